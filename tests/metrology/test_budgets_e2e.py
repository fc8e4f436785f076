"""The certified uncertainties of shipped and quick procedures on the default simulated rig.

Issue 11: the old budgets certified K at 1 Hz to 0.0038 % and the bias to 4 µV; a complete
budget (reference, measuring chain, temperature, …) gives tenths of a percent and a bias U no
smaller than the logger's offset accuracy.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from aatest.engine.procedure.loader import load_rig
from aatest.engine.run.session import run
from aatest.results import BudgetRow, RunResults

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "src" / "aatest" / "procedures"
QUICK = ROOT / "tests" / "data" / "procedures"

RIG_YAML = """\
turntable: {plugin: sim}
instruments:
  encoder: {accuracy_arcsec: 1.5, cert_id: ENC-77, cert_date: 2026-01-12, lab: PTB}
  logger: {offset_accuracy_v: 0.0015, gain_accuracy_pct: 0.05, cert_id: LOG-123,
           cert_date: 2026-03-01}
"""


def _run(procedure: Path, out: Path, rig: Path | None = None) -> RunResults:
    _, results = run(procedure, rig, out, False, 3, None, show_progress=False,
                     confirm_prompts="auto")
    return results


def _rows(budget: list[BudgetRow]) -> dict[str, BudgetRow]:
    return {r.name: r for r in budget}


def test_shipped_scale_factor_u_is_tenths_of_a_percent(tmp_path: Path) -> None:
    """Default sim rig, 1 Hz, 400 °/s²: U/K ≈ 0.12 % (logger gain 0.1 % dominates)."""
    results = _run(SHIPPED / "scale-factor.yaml", tmp_path / "run")
    assert results.analysis.scale_factor is not None
    entry = results.analysis.scale_factor["v_sz"]
    assert entry.expanded_uncertainty is not None
    relative = entry.expanded_uncertainty / entry.scale_v_per_dps2
    assert 0.001 < relative < 0.005, relative
    rows = _rows(entry.budget)
    assert {"encoder_accuracy", "reference_method", "logger_gain"} <= set(rows)
    assert rows["reference_method"].basis.startswith("measured:")
    assert rows["temperature"].basis.startswith("measured: logged temperature")
    assert not rows["repeatability"].evaluated
    assert all(r.type in ("A", "B") and r.basis for r in rows.values())
    assert "fundamental-bin ratio" in entry.measurand and "1 Hz" in entry.measurand
    assert entry.coverage_factor == pytest.approx(2.0)
    trace = results.metadata.traceability
    assert trace is not None and trace.stated is False
    assert trace.instruments["logger"].cert_id == "not stated"


def test_bias_u_holds_the_logger_offset_and_the_rig_description(tmp_path: Path) -> None:
    """--rig instruments reach the budget (basis names the certificate) and the results."""
    rig = tmp_path / "rig.yaml"
    rig.write_text(RIG_YAML, encoding="utf-8")
    assert load_rig(rig).instruments is not None
    results = _run(QUICK / "quick-static-2-steps.yaml", tmp_path / "run", rig)
    assert results.analysis.bias is not None
    entry = results.analysis.bias["v_sz"]
    offset = _rows(entry.budget)["logger_offset"]
    assert offset.contribution == pytest.approx(0.0015 / math.sqrt(3))
    assert "cert LOG-123, 2026-03-01" in offset.basis
    assert entry.expanded_uncertainty is not None
    assert entry.expanded_uncertainty >= 2 * offset.contribution
    assert entry.expanded_uncertainty > 1e-3  # not the 4 µV of the old budget
    assert "g-sensitivity cancels" in entry.measurand
    assert results.metadata.traceability is not None
    trace = results.metadata.traceability.instruments
    assert trace["encoder"].cert_id == "ENC-77" and trace["encoder"].lab == "PTB"


def test_frf_phase_u_is_realistic(tmp_path: Path) -> None:
    """Quick stepped sine (8192 samples at 100 °/s²): U(phase) grows with f through the logger
    timing accuracy (±10 µs → 0.0036° per Hz half-width) and never drops to zero."""
    results = _run(QUICK / "quick-sine-3-steps.yaml", tmp_path / "run")
    assert results.analysis.frf is not None
    points = results.analysis.frf["v_sz"]
    u = [p.phase_expanded_uncertainty_deg or 0.0 for p in points]
    assert all(0.005 < value < 0.5 for value in u), u
    assert u[-1] > u[0]
    for p in points:
        assert {"noise", "sync", "timing"} <= set(_rows(p.phase_budget))
        assert {"encoder_accuracy", "logger_gain"} <= set(_rows(p.gain_budget))
        assert p.phase_measurand.startswith("FRF phase")
        # the phase states its own k: Welch–Satterthwaite over its rows, ≥ 2
        noise = _rows(p.phase_budget)["noise"]
        assert noise.type == "A" and "larger of two" in noise.basis
        assert p.phase_coverage_factor is not None and p.phase_coverage_factor >= 2.0
