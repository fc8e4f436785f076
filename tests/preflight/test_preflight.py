"""Preflight (issue 23 item 3): every mistake that would fail after the recording fails
``validate`` at its FILE:LINE:COLUMN with exit 2, and fails ``run`` before the twin's table
gets a single command (the table's methods are wrapped and counted)."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from one_sensor_twin import one_sensor_twin
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine import plan_checks
from aatest.plugins.turntable.sim import SimTurntable

GOOD = """\
procedure: pf
sensor: {model: sr207, serial: "P1"}
rig: {turntable: sim, daq: sim}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 0.5}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}
analysis: [sync, scale_factor]
report: {template: calibration-certificate}
"""

#: the table's methods that talk to a controller: none may be called before the preflight passed
COMMANDS = ("start", "move_to", "begin_motion", "record", "end_motion", "safe_stop", "close")


@pytest.fixture
def sent(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[str]]:
    """Every command the twin's table receives, counted by name."""
    counts: Counter[str] = Counter()
    for name in COMMANDS:
        original = getattr(SimTurntable, name)

        def counted(self: Any, *args: Any, _name: str = name, _original: Any = original,
                    **kwargs: Any) -> Any:
            counts[_name] += 1
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(SimTurntable, name, counted)
    yield counts


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


def _records(tmp_path: Path) -> list[str]:
    return ["--records", f"sqlite:///{tmp_path / 'records.sqlite'}"]


MISTAKES = {
    # name: (replace this, with this, the located line expected in the output)
    "unknown-turntable": ("turntable: sim", "turntable: nope",
                          "p.yaml:3:7: rig.turntable: no turntable plugin named 'nope'"),
    "unknown-daq": ("daq: sim", "daq: nidaq", "p.yaml:3:23: rig.daq: no daq plugin named 'nidaq'"),
    "unknown-sensor": ("model: sr207", "model: sr999",
                       "p.yaml:2:10: sensor.model: no sensor plugin named 'sr999'"),
    "unknown-template": ("template: calibration-certificate", "template: nope",
                         "p.yaml:8:10: report.template: no report plugin named 'nope'"),
    "unknown-analysis": ("[sync, scale_factor]", "[sync, scale_factr]",
                         "p.yaml:7:18: analysis.1: no analysis plugin named 'scale_factr'"),
    "bad-analysis-option": ("[sync, scale_factor]", "[sync, scale_factor: {orders: 3}]",
                            "p.yaml:7:33: analysis.1.scale_factor.orders:"),
    # the diagnose command's report: a run recorded every step, then ended in an internal
    # error (exit 4) handing it a run's results
    "diagnose-report": ("template: calibration-certificate", "template: diagnosis",
                        "p.yaml:8:10: report.template: report 'diagnosis' presents the "
                        "document of `aatest diagnose`, not a run's results; choose one of: "
                        "calibration-certificate, frequency-response, misalignment"),
    # a signed report asked for and no key to sign it with: the run used to give an unsigned
    # one after a warning
    "signed-without-key": ("template: calibration-certificate}",
                           "template: calibration-certificate, sign: true}",
                           "p.yaml:8:45: report.sign: the procedure asks for a signed report "
                           "and no signing key is configured"),
    # two sets of options for one analysis: the run recorded, then stopped unlocated
    "options-twice": ("[sync, scale_factor]",
                      "[sync, scale_factor: {orders: [1, 3]}, scale_factor: {orders: [1, 5]}]",
                      "p.yaml:7:50: analysis.2.scale_factor: analysis 'scale_factor' is given "
                      "two different sets of options"),
}


@pytest.mark.parametrize("mistake", sorted(MISTAKES))
def test_each_mistake_fails_validate_located_and_run_before_motion(
        mistake: str, tmp_path: Path, sent: Counter[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AATEST_SIGNING_KEY", raising=False)  # the machine's own key, if any
    old, new, located = MISTAKES[mistake]
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    checked = CliRunner().invoke(app, ["validate", str(path), *_records(tmp_path)])
    assert checked.exit_code == 2, checked.output
    assert f"{tmp_path}/{located}" in checked.output, checked.output
    ran = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "run"),
                                   "--confirm-prompts", "auto", "--no-progress",
                                   *_records(tmp_path)])
    assert ran.exit_code == 2, ran.output
    assert f"{tmp_path}/{located}" in ran.output, ran.output
    assert sum(sent.values()) == 0, sent  # nothing reached the table
    assert not (tmp_path / "run").exists()  # nothing recorded, no number burned


def test_the_good_procedure_passes_and_its_run_commands_the_table(
        tmp_path: Path, sent: Counter[str]) -> None:
    """The control: without a mistake the counter sees the run's commands, and the recording
    fits the preflight's estimate of its size (the estimate bounds one copy of it)."""
    path = _write(tmp_path, GOOD)
    checked = CliRunner().invoke(app, ["validate", str(path), *_records(tmp_path)])
    assert checked.exit_code == 0, checked.output
    ran = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "run"),
                                   "--confirm-prompts", "auto", "--no-progress",
                                   *_records(tmp_path)])
    assert ran.exit_code in (0, 1), ran.output
    assert sent["start"] == 1 and sent["begin_motion"] == 1 and sent["record"] == 1
    estimate = plan_checks.recording_bytes(_prepared(path).plan.steps, None, 7)
    one_copy = (estimate - plan_checks.REPORT_BYTES) / (plan_checks.COPIES
                                                         * (1 + plan_checks.MARGIN))
    assert (tmp_path / "run" / "recording.mcap").stat().st_size <= one_copy


def _refused_before_motion(tmp_path: Path, sent: Counter[str], arguments: list[str],
                           message: str) -> None:
    """``validate`` and ``run`` with ``arguments`` both exit 2 saying ``message``, and the
    table was sent nothing."""
    for command in (["validate"], ["run", "--out", str(tmp_path / "run"), "--no-progress",
                                   "--confirm-prompts", "auto"]):
        result = CliRunner().invoke(app, [*command, *arguments])
        assert result.exit_code == 2, result.output
        assert message in result.output
    assert sum(sent.values()) == 0, sent


def _prepared(path: Path) -> Any:
    from aatest.engine.run.session import prepare

    return prepare(path, None)


def test_validate_json_lists_every_check_with_status_and_message(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD.replace("template: calibration-certificate", "template: nope"))
    result = CliRunner().invoke(app, ["validate", str(path), "--json", *_records(tmp_path)])
    assert result.exit_code == 2, result.output
    doc = json.loads(result.output)
    status = {c["name"]: c["status"] for c in doc["checks"]}
    assert status == {"procedure": "ok", "plugins": "ok", "report template": "failed",
                      "plan": "ok", "analysable steps": "ok", "sensor channels": "ok",
                      "logger range": "ok",
                      "disk space": "ok", "run directory": "ok",
                      "lab profile": "ok", "signing key": "ok", "records store": "ok"}
    assert doc["ok"] is False and all(c["message"] for c in doc["checks"])
    (failed,) = [c for c in doc["checks"] if c["status"] == "failed"]
    assert failed["problems"][0]["line"] == 8 and failed["problems"][0]["field"] == \
        "report.template"


def test_a_key_that_does_not_open_fails_before_motion(
        tmp_path: Path, sent: Counter[str], monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.bundle.signing import generate_keypair

    key = tmp_path / "key.pem"
    generate_keypair(key, "right passphrase")
    monkeypatch.setenv("AATEST_SIGNING_PASSPHRASE", "wrong passphrase")
    path = _write(tmp_path, GOOD)
    _refused_before_motion(tmp_path, sent, [str(path), "--sign-key", str(key),
                                            *_records(tmp_path)],
                           f"{key}: not a usable private key or wrong passphrase")


def test_a_lab_profile_that_does_not_load_is_located(tmp_path: Path, sent: Counter[str]) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: Lab\ncertificate_prefx: X\n")
    path = _write(tmp_path, GOOD)
    _refused_before_motion(tmp_path, sent, [str(path), "--lab", str(lab), *_records(tmp_path)],
                           f"{lab}:2:1: certificate_prefx:")


def test_an_unreachable_records_store_fails_before_motion(tmp_path: Path,
                                                          sent: Counter[str]) -> None:
    path = _write(tmp_path, GOOD)
    unreachable = ["--records", "postgresql://nobody@127.0.0.1:9/none"]  # port 9: discard
    _refused_before_motion(tmp_path, sent, [str(path), *unreachable], "cannot be reached")


def test_a_store_of_a_newer_schema_is_refused(tmp_path: Path, sent: Counter[str]) -> None:
    import sqlite3

    from aatest.records.store import RecordStore

    store = tmp_path / "records.sqlite"
    RecordStore.open(f"sqlite:///{store}").close()
    with sqlite3.connect(store) as db:
        db.execute("UPDATE alembic_version SET version_num = 'from_the_future'")
    result = CliRunner().invoke(app, ["validate", str(_write(tmp_path, GOOD)),
                                      "--records", f"sqlite:///{store}"])
    assert result.exit_code == 2, result.output
    assert "schema revision 'from_the_future' is unknown to this aatest" in result.output


def test_too_little_disk_fails_before_motion(tmp_path: Path, sent: Counter[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    real = shutil.disk_usage

    def nearly_full(path: Any) -> Any:
        usage = real(path)
        return usage._replace(free=plan_checks.REPORT_BYTES)  # less than any recording needs

    monkeypatch.setattr(plan_checks.shutil, "disk_usage", nearly_full)
    path = _write(tmp_path, GOOD)
    _refused_before_motion(tmp_path, sent, [str(path), *_records(tmp_path)],
                           f"{path}:5:1: steps: not enough disk space: the recording needs up to")


def test_a_long_static_step_with_sync_is_analysable(tmp_path: Path) -> None:
    """An hour's static record with every static analysis validates: the table logs its
    full-rate head, on whose freeze-pulse edges the clocks are fitted (issue 26)."""
    text = GOOD.replace("  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}\n",
                        "  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}\n"
                        "  - static: {duration_s: 3600}\n")
    result = CliRunner().invoke(app, ["validate", str(_write(tmp_path, text)),
                                      *_records(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "analysable steps: ok" in result.output


def test_the_long_static_step_alone_with_drift_is_analysable(tmp_path: Path) -> None:
    """The same record analysed by 'drift' alone passes too."""
    text = GOOD.replace("  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}\n",
                        "  - static: {duration_s: 3600}\n").replace("[sync, scale_factor]",
                                                                    "[drift]")
    result = CliRunner().invoke(app, ["validate", str(_write(tmp_path, text)),
                                      *_records(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "analysable steps: ok" in result.output


def test_a_sensor_channel_the_daq_does_not_record_fails_before_motion(
        tmp_path: Path, sent: Counter[str]) -> None:
    """The three-axis sr207-aamu through that one-sensor twin: the run recorded every step,
    then its bias analysis ended in an internal error (KeyError 'v_sy', exit 4)."""
    rig = one_sensor_twin(tmp_path)
    path = _write(tmp_path, GOOD.replace("model: sr207,", "model: sr207-aamu,").replace(
        "[sync, scale_factor]", "[sync]"))  # a plan the three axes can pass
    _refused_before_motion(tmp_path, sent, [str(path), "--rig", str(rig), *_records(tmp_path)],
                           f"{path}:2:10: sensor.model: sensor 'sr207-aamu' has the channels "
                           "v_sz, v_sy, v_sx, but daq plugin 'sim' records v_sz, sync_pulse, "
                           "trigger, temperature_c: v_sy, v_sx would not be recorded")
    assert not (tmp_path / "run").exists()
    single = CliRunner().invoke(app, ["validate", str(_write(tmp_path, GOOD)), "--rig", str(rig),
                                      *_records(tmp_path)])
    assert single.exit_code == 0, single.output  # the sensor the model was written for
    assert "sensor channels: ok: sr207: v_sz, each recorded by daq plugin 'sim'" in single.output


def test_a_bad_rig_option_fails_located_before_motion(tmp_path: Path, sent: Counter[str]) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: sim}\ndaq:\n  plugin: sim\n  slip_rign: true\n")
    _refused_before_motion(tmp_path, sent, [str(_write(tmp_path, GOOD)), "--rig", str(rig),
                                            *_records(tmp_path)],
                           f"{rig}:4:3: daq.slip_rign: daq plugin 'sim' (aatest): unknown option; "
                           "did you mean 'slip_ring'?")


def test_a_run_never_writes_into_a_directory_of_other_files(tmp_path: Path,
                                                          sent: Counter[str]) -> None:
    """``--out`` holding an earlier ``analyze``'s bundle: the run replaced its signed report
    and results.json, and signed the other files as its own. Refused now, files untouched;
    an empty directory is taken."""
    bundle = tmp_path / "bundle"
    bundle.mkdir()
    kept = {"report.html": b"<html>signed</html>", "report.html.sig": b"{}",
            "results.json": b"{}"}
    for name, data in kept.items():
        (bundle / name).write_bytes(data)
    path = _write(tmp_path, GOOD)
    for command in (["validate"], ["run", "--no-progress", "--confirm-prompts", "auto"]):
        result = CliRunner().invoke(app, [*command, str(path), "--out", str(bundle),
                                          *_records(tmp_path)])
        assert result.exit_code == 2, result.output
        assert (f"{bundle} holds files that are not a run (report.html, report.html.sig, "
                "results.json)") in result.output, result.output
    assert sum(sent.values()) == 0, sent
    assert {p.name: p.read_bytes() for p in bundle.iterdir()} == kept
    empty = tmp_path / "empty"
    empty.mkdir()
    checked = CliRunner().invoke(app, ["validate", str(path), "--out", str(empty),
                                       *_records(tmp_path)])
    assert checked.exit_code == 0 and f"run directory: ok: {empty}: empty" in checked.output
