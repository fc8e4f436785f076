"""The records chain: an edit made directly in SQL is caught by ``records check`` and ``verify``.

On SQLite and on a real PostgreSQL (``store_url``): the verdict, a value and its expanded
uncertainty are changed with plain UPDATE statements, as someone with database access would.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import text
from typer.testing import CliRunner

from aatest.cli import app
from aatest.records.chain import GENESIS, digest_of
from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import RecordStore

RUNNER = CliRunner()
PROCEDURE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / "scale-factor.yaml"
T0 = datetime(2026, 3, 1, 9, 30, tzinfo=UTC)


def _registration(serial: str, day: int, scale: float) -> Registration:
    return Registration(
        model="sr207", serial=serial, command="run", procedure="scale-factor", lab="Test Lab",
        calibrated_utc=T0 + timedelta(days=day), bundle=f"/runs/{serial}-{day}/report.html",
        overall_verdict="pass", verdicts=[{"quantity": "scale_factor", "verdict": "pass"}],
        results={"analysis": {"scale_factor": {"v_sz": {"scale_v_per_dps2": scale}}},
                 "note": "µ-unicode ° survives"},
        files={"report.html": "a" * 64},
        quantities={"scale_factor.v_sz": QuantityRecord(
            value=scale, expanded_uncertainty=2.0e-7, unit="V/(°/s²)")})


@pytest.fixture
def three(store_url: str) -> tuple[str, list[int]]:
    with RecordStore.open(store_url) as store:
        ids = [store.register(_registration("A1", day, 0.004011 + day * 1e-6))
               for day in range(3)]
    return store_url, ids


def _check(url: str) -> tuple[int, str]:
    result = RUNNER.invoke(app, ["records", "check", "--records", url])
    return result.exit_code, result.output


def _sql(url: str, statement: str, **params: object) -> None:
    with RecordStore.open(url) as store, store.engine.begin() as connection:
        connection.execute(text(statement), params)


def test_intact_chain_links_every_row(three: tuple[str, list[int]]) -> None:
    url, ids = three
    code, output = _check(url)
    assert code == 0, output
    assert "records chain intact: 3 record(s), head " in output
    with RecordStore.open(url) as store, store.engine.connect() as connection:
        rows = connection.execute(text(
            "SELECT id, previous_hash, row_hash FROM calibrations ORDER BY id")).all()
    assert [r.id for r in rows] == ids
    assert rows[0].previous_hash == GENESIS
    assert [r.previous_hash for r in rows[1:]] == [r.row_hash for r in rows[:-1]]
    assert len({r.row_hash for r in rows}) == 3


@pytest.mark.parametrize(("statement", "what"), [
    ("UPDATE calibrations SET overall_verdict = 'fail' WHERE id = :id", "verdict"),
    ("UPDATE quantities SET value = value * 1.05 WHERE calibration_id = :id", "value"),
    ("UPDATE quantities SET expanded_uncertainty = expanded_uncertainty / 2"
     " WHERE calibration_id = :id", "uncertainty"),
])
def test_sql_edit_is_named_by_records_check(three: tuple[str, list[int]], statement: str,
                                            what: str) -> None:
    url, ids = three
    _sql(url, statement, id=ids[1])
    code, output = _check(url)
    assert code == 1, what
    assert f"records chain broken at record {ids[1]}: its content differs" in output
    assert "(1 record(s) before it hold)" in output


def test_rehashing_an_edited_row_breaks_the_next_link(three: tuple[str, list[int]]) -> None:
    """An editor who also recomputes the edited row's hash is caught at the row after it."""
    url, ids = three
    _sql(url, "UPDATE calibrations SET overall_verdict = 'fail' WHERE id = :id", id=ids[0])
    with RecordStore.open(url) as store, store.engine.begin() as connection:
        forged = digest_of(connection, ids[0], GENESIS)
        connection.execute(text("UPDATE calibrations SET row_hash = :h WHERE id = :id"),
                           {"h": forged, "id": ids[0]})
    code, output = _check(url)
    assert code == 1 and f"broken at record {ids[1]}: its link to the record before" in output


def test_deleted_row_breaks_its_successor(three: tuple[str, list[int]]) -> None:
    url, ids = three
    _sql(url, "DELETE FROM quantities WHERE calibration_id = :id", id=ids[1])
    _sql(url, "DELETE FROM signed_files WHERE calibration_id = :id", id=ids[1])
    _sql(url, "DELETE FROM calibrations WHERE id = :id", id=ids[1])
    code, output = _check(url)
    assert code == 1 and f"broken at record {ids[2]}: its link to the record before" in output


@pytest.mark.parametrize("what", ["verdict", "value", "uncertainty"])
def test_verify_catches_a_sql_edit_of_its_record(store_url: str, tmp_path: Path,
                                                 what: str) -> None:
    """End to end on both engines: a signed, registered run; its record edited in SQL."""
    key = tmp_path / "lab.key"
    assert RUNNER.invoke(app, ["keygen", "--no-passphrase", str(key)]).exit_code == 0
    out = tmp_path / "run"
    result = RUNNER.invoke(app, ["run", str(PROCEDURE), "--out", str(out), "--no-progress",
                                 "--sign-key", str(key), "--records", store_url])
    assert result.exit_code == 0, result.output
    verify = ["verify", str(out / "report.html"), "--public-key", f"{key}.pub",
              "--records", store_url]
    assert RUNNER.invoke(app, verify).exit_code == 0
    edits = {"verdict": "UPDATE calibrations SET overall_verdict = 'pass (edited)'",
             "value": "UPDATE quantities SET value = value * 1.05",
             "uncertainty": "UPDATE quantities SET expanded_uncertainty = 1e-12"}
    _sql(store_url, edits[what])
    result = RUNNER.invoke(app, verify)
    assert result.exit_code == 1
    assert "records chain broken at record 1 (SIM-" in result.output
    assert "its content differs from what was hashed" in result.output
    assert _check(store_url)[0] == 1


def _station(url: str, serial: str, count: int, barrier: object, done: object) -> None:
    """One station: open the store, wait for the others, register ``count`` records."""
    with RecordStore.open(url) as store:
        barrier.wait()  # type: ignore[attr-defined]
        for day in range(count):
            store.register(_registration(serial, day, 0.004))
    done.put(serial)  # type: ignore[attr-defined]


def test_stations_registering_at_once_keep_one_chain(store_url: str) -> None:
    """Three processes append 20 records each at once: one unbroken chain of 60 links."""
    import multiprocessing

    RecordStore.open(store_url).close()  # migrated before the race (numbering tests race that)
    context = multiprocessing.get_context("spawn")
    barrier, done = context.Barrier(3), context.Queue()
    workers = [context.Process(target=_station, args=(store_url, f"S{i}", 20, barrier, done))
               for i in range(3)]
    for worker in workers:
        worker.start()
    assert sorted(done.get(timeout=300) for _ in workers) == ["S0", "S1", "S2"]
    for worker in workers:
        worker.join(timeout=60)
        assert worker.exitcode == 0
    code, output = _check(store_url)
    assert code == 0 and "records chain intact: 60 record(s)" in output, output
