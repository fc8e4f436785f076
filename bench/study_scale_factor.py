"""The study's scale-factor results (docs/method.md §4.3) against the twin, as a table.

Simulates the study's record (1 Hz, 400 °/s², 2 kHz, 140000 samples) on the realistic rig and
fits it against each reference the study used — cross-validated order, and the study's own order
set through the analysis option ``orders`` — with the twin's position-periodic ripple at its
default amplitude (0.1″ at 1 and 2 cycles/°, :data:`aatest.twin.defaults.RIPPLE_AMPLITUDE_DEG`)
times each ``--ripple`` scale. Prints, per case, the order, the linear coefficient, RMSE and R²
beside the study's values and the ratio to them.

    python bench/study_scale_factor.py [--ripple 1.0 10.0 0.0] [--seed 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from aatest.engine.analysis.passes import run_analysis
from aatest.engine.run.session import prepare
from aatest.twin.api import realistic_rig_model, simulate_dataset
from aatest.twin.defaults import RIPPLE_AMPLITUDE_DEG
from aatest.twin.model import RigModel

PROCEDURE = Path(__file__).resolve().parents[1] / "src" / "aatest" / "procedures" / \
    "scale-factor.yaml"
#: reference → (order, linear coefficient (°/s²)/V, RMSE °/s², R²) measured by the study
STUDY = {"table_estimate": (1, 250.0, 29.8, 0.989), "sliding_mode": (3, 255.1, 14.5, 0.997)}


def _with_ripple(model: RigModel, scale: float) -> RigModel:
    """``model`` with the inner axis' position-periodic ripple amplitudes times ``scale``."""
    axis = model.table.inner
    ripple = [r.model_copy(update={"amplitude_deg": r.amplitude_deg * scale})
              for r in axis.rate_ripple]
    inner = axis.model_copy(update={"rate_ripple": ripple})
    return model.model_copy(update={"table": model.table.model_copy(update={"inner": inner})})


def main() -> None:
    """Print the comparison table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ripple", type=float, nargs="+", default=[1.0, 10.0])
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    steps = list(prepare(PROCEDURE, None).plan.steps)
    print(f"{'ripple':>6} {'reference':<15} {'order':>5} {'a1':>8} {'RMSE':>7} {'R²':>7}"
          f" | study: {'order':>5} {'a1':>6} {'RMSE':>5} {'R²':>6} | a1, RMSE, 1−R² ratio")
    for scale in args.ripple:
        data = simulate_dataset(_with_ripple(realistic_rig_model(), scale), steps, args.seed)
        cases = [(reference, row, options) for reference, row in STUDY.items()
                 for options in ({}, {"orders": (row[0], row[0])})]
        for reference, (order, slope, rmse, r2), options in cases:
            out = run_analysis("scale_factor", data,
                               {"reference": reference, **options}).result["v_sz"]
            a1, fit_r2 = out.coefficients[1], out.fit.r2
            amplitude = scale * RIPPLE_AMPLITUDE_DEG * 3600.0
            print(f"{amplitude:>5.2f}″ {reference:<15} {out.order:>5} {a1:>8.2f} "
                  f"{out.rmse_dps2:>7.2f} {fit_r2:>7.4f} | {order:>12} {slope:>6.1f} {rmse:>5.1f}"
                  f" {r2:>6.3f} | {a1 / slope:.3f}, {out.rmse_dps2 / rmse:.3f}, "
                  f"{(1 - fit_r2) / (1 - r2):.3f}")


if __name__ == "__main__":
    main()
