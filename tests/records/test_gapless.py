"""Numbers only for complete certificates (issue 23 §4), on SQLite and PostgreSQL.

The certificate number is allocated in the transaction that registers the finished bundle
(:class:`aatest.records.store.Issue`). Each test fails one stage after the number was taken —
analysis, report, PDF, signing, registration — or kills the process between signing and
registration, then proves over ``certificates`` and ``calibrations``: the sequence is 1..n with
no gap and no duplicate, every issued number has exactly one record, and nothing of the failed
bundles is in the register. Registration re-run after the crash is idempotent. Then 8 processes
register 10 bundles each at once (registration only) with the same result.
"""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import select

from aatest.bundle import signing
from aatest.engine.errors import PluginError
from aatest.engine.run import session
from aatest.plugins.report import html
from aatest.records import store as store_module
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore
from aatest.records.tables import calibrations, certificates
from aatest.results import RunResults

QUICK = Path(__file__).parents[1] / "station" / "data" / "quick-scale-factor.yaml"
LAB = LabProfile(name="Gap Lab", certificate_prefix="GAP")
TEMPLATE = "calibration-certificate"
STATIONS, PER_STATION = 8, 10


class InjectedError(RuntimeError):
    """The failure a test injects into one stage."""


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RunResults, Path]:
    """One twin run recorded and analysed once (no records scope: no number), its results and
    a signing key; every stage test renders from copies of these."""
    base = tmp_path_factory.mktemp("gapless")
    key = base / "lab.key"
    signing.generate_keypair(key)
    run_dir, _ = session.run(QUICK, None, base / "run", False, 3, None, show_progress=False,
                             confirm_prompts="auto")
    return run_dir, session.read_results(run_dir), key


def _register_complete(url: str, results: RunResults, out: Path, key: Path) -> str:
    out.mkdir()
    with registering(url, LAB, "run"):
        session.render_and_sign(copy.deepcopy(results), out, TEMPLATE, None, key)
    return str(json.loads((out / "results.json").read_text())["certificate_number"])


def _register_state(url: str) -> tuple[list[int], list[str | None]]:
    """(issued sequence numbers in order, certificate numbers of all records)."""
    with RecordStore.open(url) as store, store.engine.connect() as connection:
        issued = [int(s) for s in connection.execute(
            select(certificates.c.sequence).order_by(certificates.c.sequence)).scalars()]
        held = list(connection.execute(select(calibrations.c.certificate_number)).scalars())
    return issued, held


def _assert_gapless(url: str, expected: int) -> None:
    issued, held = _register_state(url)
    assert issued == list(range(1, expected + 1)), f"gap or duplicate in {issued}"
    assert sorted(held) == sorted(set(held)) and len(held) == expected  # one record per number
    with RecordStore.open(url) as store:
        assert store.check_chain().broken is None


def _fail(monkeypatch: pytest.MonkeyPatch, target: Any, name: str,
          error: type[Exception] = InjectedError) -> None:
    def failing(*_args: Any, **_kwargs: Any) -> None:
        raise error(f"injected failure in {name}")

    monkeypatch.setattr(target, name, failing)


STAGES: dict[str, Callable[[pytest.MonkeyPatch], None]] = {
    "report": lambda m: _fail(m, html._HtmlReport, "render"),
    "pdf": lambda m: _fail(m, html._HtmlReport, "render_pdf", PluginError),
    "signing": lambda m: _fail(m, signing, "sign_bundle"),
    "registration": lambda m: _fail(m, store_module, "append_record"),
}


def test_a_failure_at_any_stage_leaves_no_trace(
        store_url: str, recorded: tuple[Path, RunResults, Path], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    run_dir, results, key = recorded
    first = _register_complete(store_url, results, tmp_path / "ok-1", key)
    with pytest.raises(InjectedError), monkeypatch.context() as patch:  # analysis: no number yet
        _fail(patch, session, "run_analyses")
        with registering(store_url, LAB, "analyze"):
            session.analyse_and_report(run_dir, tmp_path / "analysis", key_path=key)
    for stage, inject in STAGES.items():
        out = tmp_path / stage
        out.mkdir()
        with pytest.raises((InjectedError, PluginError)), monkeypatch.context() as patch:
            inject(patch)
            with registering(store_url, LAB, "run"):
                session.render_and_sign(copy.deepcopy(results), out, TEMPLATE, None, key,
                                        pdf=stage == "pdf")
        stated = json.loads((out / "results.json").read_text())["certificate_number"]
        assert stated.endswith("-000002"), stage  # it held the next number ...
        _assert_gapless(store_url, 1)  # ... and gave it back
    second = _register_complete(store_url, results, tmp_path / "ok-2", key)
    assert (first[-6:], second[-6:]) == ("000001", "000002")
    _assert_gapless(store_url, 2)


KILLED = """
import copy, os, signal, sys
from pathlib import Path
from aatest.bundle import signing
from aatest.engine.run import session
from aatest.records.hook import registering
from aatest.records.lab import LabProfile

url, run_dir, out, key = sys.argv[1:5]
sign = signing.sign_bundle

def sign_then_die(*args, **kwargs):
    sign(*args, **kwargs)
    os.kill(os.getpid(), signal.SIGKILL)  # signed, not yet registered

signing.sign_bundle = sign_then_die
results = session.read_results(Path(run_dir))
with registering(url, LabProfile(name="Gap Lab", certificate_prefix="GAP"), "run"):
    session.render_and_sign(results, Path(out), "calibration-certificate", None, Path(key))
"""


def test_kill_between_signing_and_registration(
        store_url: str, recorded: tuple[Path, RunResults, Path], tmp_path: Path) -> None:
    run_dir, results, key = recorded
    _register_complete(store_url, results, tmp_path / "ok-1", key)
    out = tmp_path / "killed"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(KILLED), store_url,
                           str(run_dir), str(out), str(key)], capture_output=True, text=True,
                          timeout=300, check=False, env={**os.environ, "AATEST_WORKERS": "1"})
    assert proc.returncode == -9, proc.stderr
    assert signing.signature_path(out / "report.html").is_file()  # the bundle was complete
    stated = json.loads((out / "results.json").read_text())["certificate_number"]
    assert stated.endswith("-000002")
    _assert_gapless(store_url, 1)  # the killed transaction took its number with it

    # registering again after the crash: re-signing numbers the bundle (the same number, as
    # nobody took it since), then repeated registration changes nothing
    with registering(store_url, LAB, "report") as registrar:
        session.report(out, None, key)
        again = session.read_results(out)
        first_id = registrar.register(again, out / "report.html")
        assert registrar.register(again, out / "report.html") == first_id
    assert again.certificate_number == stated
    _assert_gapless(store_url, 2)
    with RecordStore.open(store_url) as store:
        assert [r.id for r in store.query(RecordFilter(include_simulations=True))
                if r.certificate_number == stated] == [first_id]


STATION = """
import sys
from pathlib import Path
from aatest.bundle import observers as bundle_observers
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.results import RunResults

url, folder, station, count = sys.argv[1], Path(sys.argv[2]), sys.argv[3], int(sys.argv[4])
lab = LabProfile(name="Gap Lab", certificate_prefix="GAP")
for i in range(count):
    results = RunResults.model_validate({"procedure": "concurrent", "metadata": {
        "sensor": {"model": "sr207", "serial": f"S{station}-{i}"}}})
    bundle = folder / f"s{station}-{i}" / "report.html"
    with registering(url, lab, "run"):
        bundle_observers.before_signing(results)
        bundle.parent.mkdir(parents=True)
        bundle.write_text(f"<html>{results.certificate_number}</html>")
        bundle_observers.after_signing(results, bundle)
"""


def test_concurrent_stations_register_without_gaps(store_url: str, tmp_path: Path) -> None:
    with RecordStore.open(store_url):
        pass  # migrate once, before the stations race
    procs = [subprocess.Popen([sys.executable, "-c", textwrap.dedent(STATION), store_url,
                               str(tmp_path), str(n), str(PER_STATION)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for n in range(STATIONS)]
    for proc in procs:
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err
    _assert_gapless(store_url, STATIONS * PER_STATION)
    printed = sorted((tmp_path / f"s{n}-{i}" / "report.html").read_text()
                     for n in range(STATIONS) for i in range(PER_STATION))
    assert len(set(printed)) == STATIONS * PER_STATION  # every bundle its own number
