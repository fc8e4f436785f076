"""``aatest station --archive URL``: each finished run also goes to object storage."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from starlette.testclient import TestClient
from typer.testing import CliRunner

from aatest.cli import app
from aatest.station import StationOptions, build
from aatest.storage import RemotePath, StorageError, locate

STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"
QUICK = Path(__file__).parents[1] / "station" / "data" / "quick-scale-factor.yaml"


def test_a_station_run_is_uploaded_and_registered_at_the_archive(bucket: str, tmp_path: Path
                                                                  ) -> None:
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "quick-scale-factor.yaml").write_text(QUICK.read_text())
    records = f"sqlite:///{tmp_path / 'records.sqlite'}"
    options = StationOptions(runs_dir=tmp_path / "runs", lab_dir=lab, records=records,
                             archive=f"s3://{bucket}/station")
    client = TestClient(build(options), base_url=STATION_URL)
    with client.websocket_connect(STATION_WS) as ws:
        assert [ws.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        ws.send_json({"type": "start", "procedure": "lab/quick-scale-factor.yaml",
                      "operator": "Archive Operator"})
        while (event := ws.receive_json())["type"] not in ("finished", "stopped"):
            pass
    assert event["type"] == "finished", event
    remote = locate(f"s3://{bucket}/station/{event['name']}")
    assert isinstance(remote, RemotePath)
    local = tmp_path / "runs" / event["name"]
    assert remote.members() == sorted(p.relative_to(local).as_posix() for p in local.rglob("*")
                                      if p.is_file() and p.name != "run.lock")
    shown = CliRunner().invoke(app, ["records", "show", "1", "--records", records])
    assert shown.exit_code == 0, shown.stderr
    record = json.loads(shown.stdout)
    assert record["bundle"] == f"{remote}/report.html" and record["bundle_problems"] == []


def test_an_archive_in_a_missing_bucket_stops_the_station_starting(s3_env: str,
                                                                   tmp_path: Path) -> None:
    options = StationOptions(runs_dir=tmp_path / "runs", archive="s3://no-such-bucket-z/runs")
    with pytest.raises(StorageError, match="s3://no-such-bucket-z/runs: bucket"):
        build(options)
