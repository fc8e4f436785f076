"""The study's quantitative results (docs/method.md) beside the twin's, row by row.

Runs the study's designs on the twin's realistic rig (:func:`aatest.twin.api.realistic_rig_model`)
through the shipped procedures and the analyses, and prints for every result the method brief
reports: the study's value, the twin's, their difference, the tolerance and whether it holds.

- scale factor (``scale-factor.yaml``, 1 Hz, 400 °/s²) against the table estimate and the
  sliding-mode reference at the study's orders: linear term, RMSE, R², and the (non)linearity
  L of Eq. 3.36 (the model against the record's ideal line);
- FRF (``stepped-sine-frequency-response.yaml``, the four constant-acceleration groups):
  roll-off at the highest frequency (9.99 Hz) against the flat level (the mean gain at
  ≤ 1 Hz), the frequency where the gain starts to fall (the lowest point from which every
  higher point is ≥ 0.1 dB below the flat level), and the phase delay's spread in samples;
- transfer functions (``study-transfer-function.yaml``: the study's 28 test points at
  400 °/s²): models identified on points 7, 11, 15, …, 27 of the 28 (1.007, 1.999, 3.006,
  5.005, 7.004 and 9.003 Hz — the grid's whole frequencies) by time-domain (output-error)
  estimation on those records, validated in the time domain on the other 22 records with the
  table's acceleration estimate as input (fit %, MATLAB's ``compare``); without a delay and
  with the study's 28-sample delay. "7, 11, …, 27 of 1–28" number the 28 points, not Hz: the
  study's FRF stops at 9.99 Hz (docs/method.md §1.3, §4.4);
- cross-axis ratios and misalignment (``pivoted-misalignment.yaml``, the three-sensor unit).

The TF00 row cannot hold on records aligned as the FRF's: a gain-only model's error on a sine
record is fixed by the FRF phase (noise and harmonics only add to it), and at the study's own
24–31-sample delays no reading of ``compare`` (records together, the mean or median of their own
fits, 1 − NMSE, a gain without feedthrough) gives 78.56 % (bench/study_gaps.py --only cause).
``--tf-input-lag 12`` pairs each output sample with the input estimate 12 samples earlier, noise
kept: the one number that puts TF00, the best models and the 28-sample row on the study's values
together (seed 7: 78.77 %, 98.50 % and 94.41 %; unshifted 63.66, 98.52 and 96.48) (the study's
delayed models fit 3–6 points worse than its undelayed ones: the twin's 2.0 unshifted, 6.8
shifted, as 28 samples exceed the records' own lag by 3.7 or 15.7; a causal 50 Hz low-pass
instead leaves TF00 at 77.6 % and the 28-sample row 1.1 above the study's range where the shift
leaves it 1.1 below, n ≤ 2). The study's FRF delays and its 28-sample cross- correlation delay
then come from records aligned 12 samples apart from its transfer-function records; the default
keeps the FRF's alignment (docs/method.md §4.4).

Tolerances (issue 28): FRF roll-off ± 0.15 dB, fits ± 1.5 points, L within 30 %, delays within
the study's 24–31 samples; the rest as printed. ``--only`` picks sections (the FRF groups and
the misalignment take a few minutes each on one core).

    python bench/study.py [--seed 7] [--only scale frf tf misalignment] [--model RIG.yaml]
                          [--tf-input-lag SAMPLES]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from aatest.clocksync.freeze_pulse import synchronise_all
from aatest.engine.analysis.passes import run_analysis
from aatest.engine.run.session import prepare
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis._common import input_accel_dps2
from aatest.plugins.analysis.tfest import fit_discrete_tf, time_domain_fit
from aatest.plugins.analysis.tfest_oe import fit_discrete_tf_oe
from aatest.recording.dataset import Dataset
from aatest.results.frf import FrfPoint
from aatest.twin.api import realistic_rig_model, simulate_dataset
from aatest.twin.model import RigModel

PROCEDURES = Path(__file__).resolve().parents[1] / "src" / "aatest" / "procedures"
#: reference → (order, linear term (°/s²)/V, RMSE °/s², R², L °/s²) measured by the study
SCALE = {"table_estimate": (1, 250.0, 29.8, 0.989, 0.464),
         "sliding_mode": (3, 255.1, 14.5, 0.997, 1.261)}
#: acceleration °/s² → FRF roll-off at the highest frequency, dB, measured by the study
ROLL_OFF_DB = {1.0: 1.0, 10.0: 0.5, 100.0: 0.4, 400.0: 0.2}
#: where the two lowest accelerations' gain starts to fall, Hz (study: "≈ 2 Hz")
FALL_START_HZ = {1.0: 2.0, 10.0: 2.0}
#: the study's phase delay range, samples at 2 kHz (docs/method.md §1.3)
DELAY_RANGE = (24.0, 31.0)
#: the study's transfer-function fits, %: TF00, best models (range), 28-sample delay (range)
TF00_FIT, BEST_FIT, DELAYED_FIT = 78.56, (98.36, 98.59), (92.8, 95.3)
STUDY_DELAY_SAMPLES = 28
#: the acceleration (°/s²) of the study's transfer-function records, and the numbers (1-based,
#: in frequency order) of the 28 test points that identify; the other 22 validate
TF_ACCEL_DPS2, IDENTIFICATION_POINTS = 400.0, (7, 11, 15, 19, 23, 27)
#: the gain counts as falling this far below its flat level, dB
FALL_DB = 0.1
#: cross-axis ratios measured, % (docs/method.md §4.5), and the misalignment specification, °
CROSS_RANGE_PCT, MISALIGNMENT_SPEC_DEG = (0.03, 1.1), 0.5
#: the largest ratio is one draw of the unit's mounting errors, in the study as in the twin: over
#: seeds 1–8 the twin's is 0.80–1.19 % (mean 0.97, SD 0.15; bench/study_linearity.py --only
#: cross), so two draws differ by SD ≈ 0.21 % and ± 0.4 % (2 SD) is what one record resolves
CROSS_MAX_TOL_PCT = 0.4


@dataclass(frozen=True)
class Row:
    """One compared result: the study's value, the twin's, and whether it is within tolerance."""

    name: str
    study: str
    twin: str
    difference: str
    tolerance: str
    ok: bool


def _plan(name: str) -> list[PlannedStep]:
    return list(prepare(PROCEDURES / name, None).plan.steps)


def _relative(name: str, study: float, twin: float, share: float) -> Row:
    diff = twin - study
    return Row(name, f"{study:.4g}", f"{twin:.4g}", f"{diff:+.3g} ({100 * diff / study:+.0f} %)",
               f"within {100 * share:.0f} %", abs(diff) <= share * abs(study))


def _absolute(name: str, study: float, twin: float, tol: float, unit: str) -> Row:
    diff = twin - study
    return Row(name, f"{study:.4g} {unit}", f"{twin:.4g} {unit}", f"{diff:+.3g}",
               f"± {tol:g} {unit}", abs(diff) <= tol)


def scale_rows(model: RigModel, seed: int) -> Iterator[Row]:
    """The scale-factor table and the (non)linearity L of both models (§4.3, Eq. 3.36)."""
    data = simulate_dataset(model, _plan("scale-factor.yaml"), seed)
    for reference, (order, a1, rmse, r2, lin) in SCALE.items():
        out = run_analysis("scale_factor", data, {"reference": reference,
                                                  "orders": (order, order)}).result["v_sz"]
        yield _relative(f"{reference}: linear term, (°/s²)/V", a1, out.coefficients[1], 0.01)
        yield _relative(f"{reference}: RMSE, °/s²", rmse, out.rmse_dps2, 0.2)
        yield _absolute(f"{reference}: R²", r2, out.fit.r2, 0.005, "")
        yield _relative(f"{reference}: L (Eq. 3.36), °/s²", lin,
                        float(out.linearity_l_dps2 or 0.0), 0.3)


def _accel_steps() -> list[PlannedStep]:
    """The stepped sine's constant-acceleration steps (the 0.2° group is not compared)."""
    return [s for s in _plan("stepped-sine-frequency-response.yaml")
            if s.kind == "sine" and not (s.group or "").startswith("position")]


def frf_points(model: RigModel, seed: int, steps: Sequence[PlannedStep]
               ) -> dict[float, list[FrfPoint]]:
    """The FRF points of ``steps`` on the twin, by nominal acceleration, in frequency order."""
    data = simulate_dataset(model, list(steps), seed)
    points = run_analysis("frf", data).result["v_sz"]
    accel = {s.id: float(s.accel_dps2 or 0.0) for s in steps}
    groups: dict[float, list[FrfPoint]] = {}
    for p in points:
        groups.setdefault(round(accel[p.step], 6), []).append(p)
    return {a: sorted(g, key=lambda p: p.frequency_hz) for a, g in sorted(groups.items())}


def roll_off_db(points: Sequence[FrfPoint]) -> float:
    """Gain at the highest frequency below the flat level (mean gain at ≤ 1 Hz), dB."""
    flat = float(np.mean([p.gain_db for p in points if p.frequency_hz <= 1.0 + 1e-6]))
    return flat - points[-1].gain_db


def fall_start_hz(points: Sequence[FrfPoint]) -> float:
    """The lowest frequency from which every higher point is ≥ ``FALL_DB`` below flat."""
    flat = float(np.mean([p.gain_db for p in points if p.frequency_hz <= 1.0 + 1e-6]))
    below = np.array([flat - p.gain_db >= FALL_DB for p in points])
    still = np.flatnonzero(~below)
    first = int(still[-1]) + 1 if still.size else 0
    return points[first].frequency_hz if first < len(points) else float("nan")


def frf_rows(model: RigModel, seed: int) -> Iterator[Row]:
    """Roll-off, where the fall starts, and the phase-delay spread per acceleration (§1.3)."""
    for accel, points in frf_points(model, seed, _accel_steps()).items():
        yield _absolute(f"FRF roll-off at {points[-1].frequency_hz:.2f} Hz, {accel:g} °/s²",
                        ROLL_OFF_DB[accel], roll_off_db(points), 0.15, "dB")
        if accel in FALL_START_HZ:
            yield _absolute(f"gain starts to fall (≥ {FALL_DB} dB), {accel:g} °/s²",
                            FALL_START_HZ[accel], fall_start_hz(points), 1.0, "Hz")
        delays = [p.delay_samples for p in points]
        low, high = min(delays), max(delays)
        yield Row(f"phase delay spread, {accel:g} °/s²", f"{DELAY_RANGE[0]:g}–{DELAY_RANGE[1]:g}",
                  f"{low:.1f}–{high:.1f}", f"spread {high - low:.1f}", "within the range",
                  DELAY_RANGE[0] <= low and high <= DELAY_RANGE[1])


def _records(data: Dataset, f_hz: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(table acceleration estimate °/s², sensor volts) of the records at ``f_hz``."""
    out = []
    for s in synchronise_all(data):
        if np.min(np.abs(f_hz - float(s.step.frequency_hz or 0.0))) < 1e-6:
            out.append((input_accel_dps2(s, "I"), np.asarray(s.daq["v_sz"], dtype=np.float64)))
    return out


@dataclass(frozen=True)
class TfDesign:
    """The transfer-function records of one run: FRF points, the split, and the (input,
    output) records that estimate (``ident_records``) and validate (``records``)."""

    f_hz: np.ndarray
    h: np.ndarray
    ident: np.ndarray
    valid: np.ndarray
    records: list[tuple[np.ndarray, np.ndarray]]
    dt: float
    ident_records: list[tuple[np.ndarray, np.ndarray]]


def tf_design(model: RigModel, seed: int, input_lag_samples: int = 0) -> TfDesign:
    """The study's design on the twin (``study-transfer-function.yaml``: the stepped sine's
    400 °/s² group): points 7, 11, …, 27 (1-based, frequency order) identify, the other 22
    validate. ``input_lag_samples`` > 0 pairs each output sample with the input estimate that
    many samples earlier (:func:`lag_input`)."""
    steps = [s for s in _plan("study-transfer-function.yaml") if s.kind == "sine"]
    assert len(steps) == 28 and {s.accel_dps2 for s in steps} == {TF_ACCEL_DPS2}
    data = simulate_dataset(model, steps, seed)
    points = sorted(run_analysis("frf", data).result["v_sz"], key=lambda p: p.frequency_hz)
    f = np.array([p.frequency_hz for p in points])
    h = np.array([complex(p.re, p.im) for p in points])
    ident = np.array(IDENTIFICATION_POINTS) - 1
    valid = np.setdiff1d(np.arange(f.size), ident)
    dt = 1.0 / float(data.steps[0].table.sample_rate_hz)
    design = TfDesign(f, h, ident, valid, _records(data, f[valid]), dt, _records(data, f[ident]))
    return lag_input(design, input_lag_samples)


def lag_input(design: TfDesign, lag_samples: int) -> TfDesign:
    """``design`` with its input ``lag_samples`` later against its output: record pairs
    (u[k − L], y[k]), the first L output samples dropped. The estimate keeps its noise (a pure
    shift, not a filter), and the FRF points gain the phase the shift adds, e^{+j2πf·L·dt}."""
    if lag_samples <= 0:
        return design
    lag = int(lag_samples)
    lead = np.exp(2j * np.pi * design.f_hz * lag * design.dt)
    records, ident = ([(u[:-lag], y[lag:]) for u, y in rs]
                      for rs in (design.records, design.ident_records))
    return TfDesign(design.f_hz, design.h * lead, design.ident, design.valid, records,
                    design.dt, ident)


def tf_fits(design: TfDesign, delays: Sequence[int] = (0, STUDY_DELAY_SAMPLES),
            max_poles: int = 5) -> dict[tuple[int, int, int], float]:
    """Time-domain validation fit % of every (poles, zeros, delay) model, each estimated in
    the time domain (output error, stable by construction) on the identification records as
    the study's ``tfest`` did, started from the fit to their FRF points."""
    fits = {}
    for n in range(max_poles + 1):
        for m in range(n + 1):
            for d in delays:
                start = fit_discrete_tf(design.f_hz[design.ident], design.h[design.ident], n, m,
                                        design.dt, d)
                tf = fit_discrete_tf_oe(design.ident_records, n, m, design.dt, d, start)
                fits[(n, m, d)] = time_domain_fit(tf, design.records, settle_samples=2000)
    return fits


def tf_rows(model: RigModel, seed: int, input_lag_samples: int = 0) -> Iterator[Row]:
    """TF00, the best model without a delay (n ≥ 1) and the best with 28 samples (any n,
    TF00 with the delay included) (§4.4); ``input_lag_samples`` as :func:`tf_design`."""
    fits = tf_fits(tf_design(model, seed, input_lag_samples))
    yield _absolute("TF00 (gain only) fit, %", TF00_FIT, fits.get((0, 0, 0), float("nan")),
                    1.5, "%")
    for label, d, (low, high) in (("best model fit, no delay", 0, BEST_FIT),
                                  ("best model fit, 28-sample delay", STUDY_DELAY_SAMPLES,
                                   DELAYED_FIT)):
        best = max(((v, k) for k, v in fits.items() if k[2] == d and (k[0] > 0 or d > 0)),
                   default=(float("nan"), (0, 0, d)))
        diff = 0.0 if low <= best[0] <= high else min(best[0] - low, best[0] - high, key=abs)
        yield Row(f"{label} (n={best[1][0]}, m={best[1][1]}), %", f"{low:g}–{high:g} %",
                  f"{best[0]:.2f} %", f"{diff:+.2f}", "± 1.5 of the range", abs(diff) <= 1.5)


def misalignment_rows(seed: int) -> Iterator[Row]:
    """Cross-axis ratio range and misalignments of the three-sensor unit (§4.5)."""
    from aatest.plugins.sensors.sr207 import SR207Unit

    model = realistic_rig_model(SR207Unit().datasheet())
    data = simulate_dataset(model, _plan("pivoted-misalignment.yaml"), seed)
    out = run_analysis("misalignment", data).result
    ratios = [100 * abs(r) for sensors in out.sets.values() for s in sensors.values()
              for r in (s.cross_ratio_x, s.cross_ratio_y)]
    deltas = [abs(s.delta_deg) for sensors in out.scenarios.values() for s in sensors.values()]
    low, high = CROSS_RANGE_PCT
    yield Row("cross-axis ratio range, %", f"{low:g}–{high:g}",
              f"{min(ratios):.3f}–{max(ratios):.3f}", f"max {max(ratios) - high:+.3f}",
              f"max ± {CROSS_MAX_TOL_PCT:g}", abs(max(ratios) - high) <= CROSS_MAX_TOL_PCT)
    below = float(np.mean(np.array(deltas) < MISALIGNMENT_SPEC_DEG))
    yield Row("misalignments below 0.5°", "most", f"{100 * below:.0f} % (max "
              f"{max(deltas):.2f}°)", "—", "> 50 %", below > 0.5)


SECTIONS: dict[str, Callable[[RigModel, int], Iterator[Row]]] = {
    "scale": scale_rows, "frf": frf_rows, "tf": tf_rows,
    "misalignment": lambda _model, seed: misalignment_rows(seed)}


def main() -> None:
    """Print the comparison table and how many rows hold."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--only", nargs="+", choices=list(SECTIONS), default=list(SECTIONS))
    parser.add_argument("--model", type=Path, help="a rig model YAML instead of the realistic")
    parser.add_argument("--tf-input-lag", type=int, default=0, metavar="SAMPLES",
                        help="transfer-function rows with the input estimate this many "
                             "samples late against the output (12: the study's TF rows)")
    args = parser.parse_args()
    model = realistic_rig_model()
    if args.model is not None:
        from aatest.twin.model import load_rig_model

        model = load_rig_model(args.model)
    print(f"{'result':<48} {'study':>14} {'twin':>16} {'difference':>16}  tolerance")
    held = total = 0
    sections = dict(SECTIONS, tf=partial(tf_rows, input_lag_samples=args.tf_input_lag))
    for name in args.only:
        for row in sections[name](model, args.seed):
            total, held = total + 1, held + row.ok
            print(f"{row.name:<48} {row.study:>14} {row.twin:>16} {row.difference:>16}  "
                  f"{row.tolerance} {'ok' if row.ok else 'MISS'}", flush=True)
    print(f"{held}/{total} rows within tolerance")


if __name__ == "__main__":
    main()
