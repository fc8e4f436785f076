"""The example table's declared capabilities flow into the plan and the uncertainty budget:
its 24-bit encoder (0.0772″ per count) is budgeted instead of the default 0.01″, its serial
is the one identified at ``start``, and its missing outer axis is refused at ``validate``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app

PROCEDURE = """\
procedure: vendor-frf
sensor: {{model: sr207, serial: "C-1"}}
rig: {{turntable: acme-single-axis, daq: sim, chamber: none}}
sampling: {{rate_hz: 2000, samples: 8192, settle_s: 0.5}}
steps:
{steps}
analysis: [sync, frf]
report: {{template: frequency-response, sign: false}}
"""
SINE = "  - sine: {axis: inner, frequency_hz: 2.0, accel_dps2: 200, snap: coherent}"
COUNTS_24_BIT = 2**24


def _write(tmp_path: Path, *steps: str) -> Path:
    path = tmp_path / "procedure.yaml"
    path.write_text(PROCEDURE.format(steps="\n".join(steps)))
    return path


def _run(tmp_path: Path, *extra: str) -> dict[str, Any]:
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(_write(tmp_path, SINE)), "--out", str(out),
                                      "--no-progress", "--seed", "4", *extra])
    assert result.exit_code == 0, result.output
    return dict(json.loads((out / "results.json").read_text()))


def _row(results: dict[str, Any], name: str) -> dict[str, Any]:
    [point] = results["analysis"]["frf"]["v_sz"]
    return next(r for r in point["gain_budget"] if r["name"] == name)


@pytest.mark.usefixtures("vendor_example")
def test_the_declared_24_bit_encoder_is_budgeted_instead_of_the_default(tmp_path: Path) -> None:
    results = _run(tmp_path)
    row = _row(results, "encoder_resolution")
    q_arcsec = 360 * 3600 / COUNTS_24_BIT
    assert f"{COUNTS_24_BIT} counts/rev (q = 0.0772″)" in row["basis"]
    assert row["basis"].startswith("declared by the turntable plugin 'acme-single-axis' "
                                   "(aatest-vendor-example 0.1.0)")
    [point] = results["analysis"]["frf"]["v_sz"]
    amplitude_arcsec = point["accel_dps2"] / (2 * math.pi * point["frequency_hz"]) ** 2 * 3600
    # u = q/√12 over A: plain arithmetic on recorded numbers (float rounding only)
    assert row["standard_uncertainty"] == pytest.approx(
        q_arcsec / math.sqrt(12) / amplitude_arcsec, rel=1e-9)
    accuracy = _row(results, "encoder_accuracy")
    assert accuracy["basis"].startswith("declared by the turntable plugin 'acme-single-axis'")
    assert "encoder accuracy ±2″" in accuracy["basis"]
    meta = results["metadata"]
    assert meta["table_serial"] == "SR1-0042"  # identified by start(), not before
    declared = meta["rig"]["capabilities"]["turntable"]["declared"]
    assert (declared["model"], declared["serial"]) == ("ACME SR-1", "SR1-0042")


@pytest.mark.usefixtures("vendor_example")
def test_the_rig_description_overrides_the_declaration(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: acme-single-axis}\ndaq: {plugin: sim}\n"
                   "instruments:\n  encoder: {resolution_counts_per_rev: 1296000, "
                   "cert_id: ENC-9}\n")
    results = _run(tmp_path, "--rig", str(rig))
    row = _row(results, "encoder_resolution")
    assert row["basis"].startswith("rig description: encoder resolution 1296000 counts/rev "
                                   "(q = 1″)")
    # the accuracy the lab did not state still comes from the plugin
    assert _row(results, "encoder_accuracy")["basis"].startswith("declared by the turntable")


@pytest.mark.usefixtures("vendor_example")
@pytest.mark.parametrize(("step", "reason"), [
    ("  - sine: {axis: outer, frequency_hz: 2.0, accel_dps2: 100, snap: coherent}",
     "moves the outer axis"),
    ("  - multi_position: {positions: [[0, 90]], repetitions: 1, mountings: [original]}",
     "puts the outer axis at 90°"),
], ids=["outer-sine", "outer-position"])
def test_what_the_table_cannot_do_is_refused_at_validate(tmp_path: Path, step: str,
                                                         reason: str) -> None:
    result = CliRunner().invoke(app, ["validate", str(_write(tmp_path, step))])
    assert result.exit_code == 2, result.output
    assert f"{reason}, an axis this table does not have (declared axes: inner) " \
           "[outer.present]" in result.output
