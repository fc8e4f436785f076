"""``records impact``: a seeded archive where logger LOG-7 read 0.6 % high on rig A.

The truth is stated here: U1–U3 ran on rig A (LOG-7), U4 on rig B (LOG-8). U2's true scale
factor is 0.8 % above nominal (issued +1.4 %: fail; truly a pass), U3's 1.3 % below (issued
−0.7 %: pass; truly a fail), U1's nominal (pass either way). The impact report must name
exactly U1–U3 and exactly the verdicts of U2 and U3 as changing, and recover the true values.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.batch import ledger
from aatest.batch.archive import TwinUnit, record_run, register_references
from aatest.cli import app
from aatest.records.store import RecordStore

RIG_A, RIG_B = ("ENC-1", "LOG-7"), ("ENC-1", "LOG-8")
GAIN_ERROR_PPM = 6000.0
UNITS = (TwinUnit("U1", 0.0, "rig-a", RIG_A, GAIN_ERROR_PPM, seed=1),
         TwinUnit("U2", 0.8, "rig-a", RIG_A, GAIN_ERROR_PPM, seed=2),
         TwinUnit("U3", -1.3, "rig-a", RIG_A, GAIN_ERROR_PPM, seed=3),
         TwinUnit("U4", 0.8, "rig-b", RIG_B, 0.0, seed=4))
#: the verdict changes the truth implies: serial → (issued, corrected)
CHANGES = {"U2": ("fail", "pass"), "U3": ("pass", "fail")}
CORRECTION = f"""\
reference: LOG-7
found_on: 2026-11-20
reason: recalibration found the logger's gain 0.6 % high
logger_gain_error_ppm: {GAIN_ERROR_PPM}
"""


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict[str, str], Path]:
    """(records URL, serial → certificate number, folder) of the seeded archive."""
    root = tmp_path_factory.mktemp("impact-archive")
    url = f"sqlite:///{root / 'records.sqlite'}"
    register_references(url, ["ENC-1"], ["LOG-7", "LOG-8"])
    for unit in UNITS:
        record_run(unit, root, url)
    with RecordStore.open(url) as store:
        numbers = {u.serial: store.history(u.serial, include_simulations=True)[-1]
                   .certificate_number or "" for u in UNITS}
    correction = root / "log7.yaml"
    correction.write_text(CORRECTION, encoding="utf-8")
    return url, numbers, correction


def aatest(*args: object) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def test_lists_exactly_the_certificates_that_used_the_reference(archive) -> None:
    url, numbers, _ = archive
    code, out, err = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                            "--include-simulations", "--json")
    assert code == 0, out + err
    listed = {c["certificate_number"] for c in json.loads(out)["certificates"]}
    assert listed == {numbers["U1"], numbers["U2"], numbers["U3"]}
    code, out, _ = aatest("records", "impact", "--reference", "ENC-1", "--records", url,
                          "--include-simulations", "--json")
    assert {c["certificate_number"] for c in json.loads(out)["certificates"]} == \
        set(numbers.values())
    tomorrow = (datetime.now(UTC) + timedelta(days=1)).date().isoformat()
    code, out, _ = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                          "--include-simulations", "--since", tomorrow)
    assert code == 0 and out.startswith("reference LOG-7: 0 certificate(s)")


def test_correction_names_the_verdicts_that_change_and_recovers_the_truth(archive) -> None:
    url, _, correction = archive
    with RecordStore.open(url) as store:
        issued = {u.serial: store.history(u.serial, True)[-1] for u in UNITS}
    code, out, err = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                            "--include-simulations", "--correction", correction,
                            "--workers", "1", "--json")
    assert code == 1, out + err  # verdicts change: a finding for the quality manager
    report = {c["serial"]: c for c in json.loads(out)["certificates"]}
    assert set(report) == {"U1", "U2", "U3"}
    changed = {s: (c["overall_verdict"], c["corrected_overall_verdict"])
               for s, c in report.items() if c["verdict_changes"]}
    assert changed == CHANGES
    by_serial = {u.serial: u for u in UNITS}
    for serial, cert in report.items():
        (scale,) = [j for j in cert["judged"] if j["quantity"] == "scale_factor_deviation_pct"]
        # the corrected deviation is the unit's true one within its stated U (k = 2)
        assert scale["new_value"] == pytest.approx(by_serial[serial].scale_deviation_pct,
                                                   abs=scale["new_u"])
        assert scale["changes"] == (serial in CHANGES)
    with RecordStore.open(url) as store:
        redone = {r.record_id: r for r in ledger.stored(store)}
        for serial, record in issued.items():
            if serial == "U4":
                assert record.id not in redone  # rig B never used LOG-7
                continue
            old = record.quantities["scale_factor.v_sz"].value
            new = redone[record.id].quantities["scale_factor.v_sz"]["value"]
            # the fit is linear in the volts: undoing a gain g divides S by (1 + g); 1e-6
            # leaves room for the low-pass and least squares rounding (~1e-12 relative)
            assert new == pytest.approx(old / (1 + GAIN_ERROR_PPM * 1e-6), rel=1e-6)
            now = store.get(record.certificate_number or "")
            assert (now.id, now.overall_verdict) == (record.id, record.overall_verdict)
        assert store.check_chain().broken is None and ledger.check(store) is None


def test_text_report_marks_the_changes(archive) -> None:
    url, numbers, correction = archive
    code, out, err = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                            "--include-simulations", "--correction", correction,
                            "--workers", "1")
    assert code == 1
    lines = out.splitlines()
    for serial, number in numbers.items():
        head = [line for line in lines if line.startswith(number)]
        if serial == "U4":
            assert not head
            continue
        assert len(head) == 1
        assert head[0].endswith("VERDICT CHANGES" if serial in CHANGES else "verdict unchanged")
    assert lines[-1] == "2 of 3 certificate(s) change verdict"
    assert "0 to run" in err  # the re-analyses of the test before are reused (same method)


def test_a_correction_that_does_not_fit_the_reference_is_refused(archive, tmp_path) -> None:
    url, _, _ = archive
    wrong_kind = tmp_path / "enc.yaml"
    wrong_kind.write_text("reference: LOG-7\nfound_on: 2026-11-20\nreason: r\n"
                          "encoder_scale_error_ppm: 50\n", encoding="utf-8")
    code, _, err = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                          "--correction", wrong_kind)
    assert code == 2 and "encoder scale error is stated, but LOG-7 is of kind data-logger" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("reference: LOG-7\nfound_on: 2026-11-20\nreason: r\n"
                   "logger_gain_error_ppm: lots\n", encoding="utf-8")
    code, _, err = aatest("records", "impact", "--reference", "LOG-7", "--records", url,
                          "--correction", bad)
    assert code == 2 and f"{bad}:4" in err and "logger_gain_error_ppm" in err
    code, _, err = aatest("records", "impact", "--reference", "NOPE", "--records", url)
    assert code == 2 and "'NOPE' is not registered" in err
