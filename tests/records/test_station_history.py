"""``aatest station --records URL``: the history list from the records store (both engines).

The station's own run is registered in the store (certificate number, files) and listed with
links to its files; records of runs made elsewhere are listed without links (no path from the
database is served); superseded records and diagnoses are left out; newest first.
"""

from __future__ import annotations

import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from aatest.engine.errors import InputError
from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import RecordStore
from aatest.station import StationOptions, build

#: the station as a browser on this machine names it (its default port)
STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"

QUICK = Path(__file__).parents[1] / "station" / "data" / "quick-scale-factor.yaml"
LONG_AGO = datetime(2025, 1, 10, 8, 0, tzinfo=UTC)


def _elsewhere(store: RecordStore, serial: str, bundle: str, days: int,
               command: str = "run") -> Registration:
    """A record registered by another station or command, its bundle outside our runs."""
    when = LONG_AGO + timedelta(days=days)
    return Registration(
        model="sr207", serial=serial, command=command, procedure="scale-factor", lab="Test Lab",
        calibrated_utc=when, bundle=bundle, overall_verdict="pass",
        certificate_number=store.issue_certificate("OTHER", when),
        quantities={"scale_factor.v_sz": QuantityRecord(value=0.004013, unit="V/(°/s²)")})


def _run_from_the_page(client: TestClient) -> dict[str, Any]:
    with client.websocket_connect(STATION_WS) as ws:
        assert [ws.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        ws.send_json({"type": "start", "procedure": "lab/quick-scale-factor.yaml",
                      "operator": "Rec Operator"})
        while (event := ws.receive_json())["type"] not in ("finished", "stopped"):
            pass
    assert event["type"] == "finished", event
    return event


def test_history_lists_the_stores_newest_calibrations(store_url: str, tmp_path: Path) -> None:
    with RecordStore.open(store_url) as store:
        store.register(_elsewhere(store, "B7", "/elsewhere/old/report.html", 0))
        newer = _elsewhere(store, "B7", "/elsewhere/old/report.html", 1)  # supersedes it
        store.register(newer)
        store.register(_elsewhere(store, "C9", "/elsewhere/c9/report.html", 2, "diagnose"))
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "quick-scale-factor.yaml").write_text(QUICK.read_text())
    runs = tmp_path / "runs"
    client = TestClient(build(StationOptions(runs_dir=runs, lab_dir=lab, records=store_url)),
                        base_url=STATION_URL)
    finished = _run_from_the_page(client)

    doc = client.get("/api/runs").json()
    assert doc["source"] == "records" and "password" not in doc["store"]
    rows = doc["runs"]
    assert [r["unit"] for r in rows] == ["sr207/A1234", "sr207/B7"]  # newest first
    ours, other = rows
    assert ours["name"] == finished["name"] and ours["overall"] == finished["overall"] == "pass"
    assert ours["operator"] == "Rec Operator" and ours["command"] == "run"
    assert ours["certificate_number"]  # issued into results.json before signing, as by `run`
    assert {"report.html", "results.json"} <= set(ours["files"])
    page = client.get(f"/runs/{ours['name']}/report.html")
    assert page.status_code == 200 and ours["certificate_number"] in page.text
    assert other["name"] is None and other["files"] == []  # listed, never served
    assert other["certificate_number"] == newer.certificate_number  # the newest record only

    with RecordStore.open(store_url) as store:
        (record,) = [r for r in store.recent(10) if r.serial == "A1234"]
    assert Path(record.bundle).parent == runs / finished["name"]
    assert "results.json" in record.files and "report.html" in record.files


def test_without_records_the_runs_directory_is_listed(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    doc = client.get("/api/runs").json()
    assert doc == {"runs": [], "source": "runs", "where": "runs"}


def test_unreachable_store_refuses_to_start(tmp_path: Path) -> None:
    url = "postgresql://station:secret@127.0.0.1:9/records"  # discard port: nothing listens
    with pytest.raises(InputError, match="cannot be reached") as refused:
        build(StationOptions(runs_dir=tmp_path / "runs", records=url))
    assert "secret" not in str(refused.value)
    done = subprocess.run(
        [sys.executable, "-m", "aatest.cli", "station", "--port", "0", "--runs",
         str(tmp_path / "runs"), "--records", url],
        capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2, done.stderr
    assert "127.0.0.1:9" in done.stderr and "secret" not in done.stderr
