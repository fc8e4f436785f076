"""Why the (non)linearity rows of ``bench/study.py`` stay open: the evidence (issue 28).

The study's L (Eq. 3.36) is the chosen model f against the ideal line g — the straight line of
the table's own estimate on the sensor volts (g = 250.02·u − 0.319) — RMS over the record. The
study measured L = 0.464 °/s² (table estimate, 1st order) and 1.261 °/s² (sliding-mode
reference, 3rd order, linear term 255.1 (°/s²)/V). Four sections:

1. ``identity`` — the 1st-order model against the table estimate *is* g (the same least
   squares on the same samples): L = 0 to rounding whatever the rig does. The section runs
   the realistic rig with the sensor's cubic curvature off, at its default, and 7× and 22×
   larger: L stays at 1e-13. A non-zero L needs f ≠ g, i.e. a model estimated on other samples
   (printed: the line identified on the cross-validation's first quarter and on random
   quarters, the only readings of the study's design that give one) — a construction question,
   not a rig effect.
2. ``consistency`` — the study's own pair (255.1, 1.261) under Eq. 3.36 as read: over the
   record's sine u = U·sin θ, f − g = b1·u + b3·u³ (+ even terms, which only add), so
   L ≥ b1·U/√20 (the b3 minimising it). With b1 = 255.1 − 250.02 and U = 400/250.02 V that is
   1.82 °/s²; conversely L = 1.261 allows a linear term of at most 253.5. No model reproduces
   both numbers exactly; the tolerances (1 %, 30 %) leave a window.
3. ``scan`` — what the sensor's static curvature (``nonlinearity_cubic``, the vocabulary's
   effect) and its small-signal scale factor do to the rows: the cubic model's linear term is
   the small-signal inverse scale 1/K whatever c3 is (a curvature cannot move it), the table
   line's slope falls by (3/4)·c3·(A/R)², and L_sliding = c3·A³/(4√2·R²). A cubic against
   the table estimate sees the same curvature (both references are unbiased on the twin), so a
   sensor curvature cannot make the study's two L values differ 2.7×.
4. ``variant`` — the unit the study's numbers describe if the sensor's curvature is real and
   the references are clean: c3 from L_sliding and 1/K from g's slope (:func:`study_unit_model`),
   through the bench's scale rows. It meets the sliding-mode rows and keeps the table rows;
   it is outside the datasheet (small-signal scale −1.7 %, non-linearity 0.73 % FR against
   ±1 % and ±0.05 % FR), which is why it is a variant and not the realistic default.
   ``--write-model PATH`` writes it for ``bench/study.py --model PATH --only scale``.

5. ``tuning`` — the sliding-mode reference's own part: Levant's differentiator with its
   Lipschitz bound C at multiples of the record's peak jerk (the analysis uses 1×). Only a
   differentiator that loses its sliding mode (C ≲ 0.3×) moves the cubic's linear term or L,
   and there its RMSE is not the study's 14.5 °/s²; at the bound that reproduces the RMSE the
   linear term stays 1/K.

And ``cross`` (minutes per seed): the cross-axis ratios of the pivoted test over seeds — the
study's 0.03–1.1 % is one draw of the unit's mounting errors; the twin's maximum over seeds
says whether 1.1 is inside the draws' spread.

    python bench/study_linearity.py [--seeds 7] [--write-model PATH]
        [--only identity consistency scan variant tuning cross]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study import CROSS_RANGE_PCT, SCALE, _plan, scale_rows

from aatest.clocksync.freeze_pulse import SyncedStep, synchronise_all
from aatest.engine.analysis.passes import run_analysis
from aatest.plugins.analysis._common import fundamental, input_accel_dps2
from aatest.plugins.analysis.reference import (
    default_cutoff_hz,
    first_difference,
    levant_differentiator,
    zero_phase_lowpass,
)
from aatest.plugins.analysis.scale_factor import aligned_pair, fractional_delay
from aatest.recording.dataset import SensorInfo
from aatest.twin.api import realistic_rig_model, simulate_dataset
from aatest.twin.model import NonlinearityCubic, RigModel, dump_rig_model

#: the study's ideal line g = slope·u + intercept, (°/s²)/V and °/s² (Eq. 3.36)
IDEAL_SLOPE, IDEAL_INTERCEPT = 250.02, -0.319
#: the scale-factor record's acceleration amplitude, °/s² (scale-factor.yaml, §4.3)
AMPLITUDE_DPS2 = 400.0
#: the study's L with the sliding-mode reference, °/s², and its cubic's linear term
L_SLIDING, LINEAR_SLIDING = SCALE["sliding_mode"][4], SCALE["sliding_mode"][1]
#: the curvatures scanned, as multiples of none, the default, and the two readings below
SCAN_C3 = (0.0, 0.002, 0.0135, 0.044)
#: the comparison's tolerances (issue 28): linear term 1 %, L 30 %
LINEAR_TOL, L_TOL = 0.01, 0.3
#: the datasheet's scale-factor tolerance, % (docs/method.md §1.3)
SCALE_TOL_PCT = 1.0
#: share of the record the cross-validation identifies on (docs/method.md §4.3)
ID_FRACTION = 0.25
P = np.polynomial.polynomial


def min_l_dps2(linear_excess: float, u_amplitude_v: float) -> float:
    """Smallest L (°/s²) of f − g = b1·u + b3·u³ over u = U·sin θ, any b3: b1·U/√20.

    f − g = (b1·U + ¾·b3·U³)·sin θ − (b3·U³/4)·sin 3θ; the mean square is minimal at
    b3·U³/4 = −3·b1·U/10, where it is b1²U²/20."""
    return abs(linear_excess) * u_amplitude_v / np.sqrt(20.0)


def cubic_c3_from_l(l_dps2: float, amplitude_dps2: float, range_dps2: float) -> float:
    """The sensor curvature c3 (output ∝ α·(1 + c3·(α/R)²)) whose cubic model departs from
    the clean reference's line by ``l_dps2`` RMS over a sine of ``amplitude_dps2``:
    L = c3·A³/(4√2·R²) (the 3rd harmonic the curvature adds to the line)."""
    return 4.0 * np.sqrt(2.0) * range_dps2**2 * l_dps2 / amplitude_dps2**3


def study_unit_model(base: RigModel | None = None) -> RigModel:
    """The realistic rig with the unit the study's sliding-mode numbers describe, read as a
    sensor curvature seen through clean references.

    c3 from L_sliding (:func:`cubic_c3_from_l`); the small-signal scale K such that the line a
    straight-line fit draws over the 400 °/s² sine has g's slope: 1/K = slope·(1 + ¾·c3·(A/R)²)
    (the curvature steepens the output at the peaks, so the line is flatter than 1/K).
    """
    model = base or realistic_rig_model()
    sensor = model.sensors[0]
    c3 = cubic_c3_from_l(L_SLIDING, AMPLITUDE_DPS2, sensor.range_dps2)
    inverse_scale = IDEAL_SLOPE * (1 + 0.75 * c3 * (AMPLITUDE_DPS2 / sensor.range_dps2) ** 2)
    unit = sensor.model_copy(update={"nonlinearity_cubic": NonlinearityCubic(c3=float(c3)),
                                     "scale_v_per_dps2": 1.0 / inverse_scale})
    return model.model_copy(update={"sensors": [unit, *model.sensors[1:]]})


def _with_c3(model: RigModel, c3: float) -> RigModel:
    sensor = model.sensors[0].model_copy(update={"nonlinearity_cubic": NonlinearityCubic(c3=c3)})
    return model.model_copy(update={"sensors": [sensor, *model.sensors[1:]]})


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def identity_rows(seed: int) -> None:
    """L of the table estimate's line against g for several curvatures, and on quarters."""
    base = realistic_rig_model()
    print("1. table estimate, 1st order: L against the ideal line (the same fit), °/s²")
    for c3 in SCAN_C3:
        data = simulate_dataset(_with_c3(base, c3), _plan("scale-factor.yaml"), seed)
        lin = run_analysis("scale_factor", data, {"reference": "table_estimate",
                                                  "orders": (1, 1)}).result["v_sz"]
        synced = synchronise_all(data)[0]
        volts, ref, *_ = aligned_pair(synced, data.sensors[0], "table_estimate")
        u = volts - volts.mean()
        g = P.polyfit(u, ref, 1)
        quarter = int(ID_FRACTION * u.size)
        first = P.polyfit(u[:quarter], ref[:quarter], 1)
        rng = np.random.default_rng(seed)
        randoms = [P.polyfit(u[i], ref[i], 1) for i in
                   (rng.permutation(u.size)[:quarter] for _ in range(3))]
        print(f"   c3 = {c3:<7g} L = {float(lin.linearity_l_dps2 or 0.0):.1e}"
              f" (the analysis); line of the first quarter {_rms(P.polyval(u, first - g)):.3f},"
              f" of random quarters " + ", ".join(f"{_rms(P.polyval(u, r - g)):.3f}"
                                                   for r in randoms)
              + "  (study 0.464)", flush=True)


def consistency_rows() -> None:
    """The study's (255.1, 1.261) pair against Eq. 3.36 over its own sine."""
    u_amp = AMPLITUDE_DPS2 / IDEAL_SLOPE
    excess = LINEAR_SLIDING - IDEAL_SLOPE
    print("2. the study's sliding-mode pair under Eq. 3.36 (sine of "
          f"{u_amp:.3f} V against g = {IDEAL_SLOPE}u {IDEAL_INTERCEPT:+})")
    print(f"   linear term {LINEAR_SLIDING} needs L ≥ {min_l_dps2(excess, u_amp):.3f} °/s² "
          f"(study {L_SLIDING}); L = {L_SLIDING} allows a linear term ≤ "
          f"{IDEAL_SLOPE + L_SLIDING * np.sqrt(20.0) / u_amp:.2f}")
    low = LINEAR_SLIDING * (1 - LINEAR_TOL)
    print(f"   within the tolerances: linear term ≥ {low:.2f} needs L ≥ "
          f"{min_l_dps2(low - IDEAL_SLOPE, u_amp):.3f} ≤ {L_SLIDING * (1 + L_TOL):.3f}: "
          "a window exists")
    nominal = realistic_rig_model().sensors[0].scale_v_per_dps2
    print(f"   the cubic's linear term is 1/K (section 3): ≥ {low:.2f} needs K "
          f"{100 * (1 / low / nominal - 1):+.2f} % of nominal (datasheet ±{SCALE_TOL_PCT:g} %)")


def scan_rows(seed: int) -> None:
    """The bench's scale rows over the sensor's curvature and the study-unit variant."""
    base = realistic_rig_model()
    sensor = base.sensors[0]
    print("3. sensor curvature c3 (small-signal 1/K = "
          f"{1 / sensor.scale_v_per_dps2:.2f}): table line, sliding cubic's linear term, L")
    for c3 in SCAN_C3:
        model = _with_c3(base, c3)
        rows = {r.name.split(",")[0]: r.twin for r in scale_rows(model, seed)}
        data = simulate_dataset(model, _plan("scale-factor.yaml"), seed)
        cubic = run_analysis("scale_factor", data, {"reference": "table_estimate",
                                                    "orders": (3, 3)}).result["v_sz"]
        truth = c3 * AMPLITUDE_DPS2**3 / (4 * np.sqrt(2) * sensor.range_dps2**2)
        print(f"   c3 = {c3:<7g} table {rows['table_estimate: linear term']:>6}  sliding "
              f"{rows['sliding_mode: linear term']:>6}  L sliding "
              f"{rows['sliding_mode: L (Eq. 3.36)']:>7} (c3·A³/(4√2R²) = {truth:.3f})  "
              f"L table {rows['table_estimate: L (Eq. 3.36)']}, its cubic "
              f"{float(cubic.linearity_l_dps2 or 0.0):.3f}", flush=True)


def variant_rows(seed: int, write: Path | None) -> None:
    """The study-unit variant through the bench's scale rows, with its datasheet figures."""
    model = study_unit_model()
    sensor = model.sensors[0]
    c3 = sensor.nonlinearity_cubic.c3 if sensor.nonlinearity_cubic else 0.0
    nominal = realistic_rig_model().sensors[0].scale_v_per_dps2
    # y = x + c3·x³ on [−1, 1] against its best line: max |deviation| 0.4·c3 of R, FR = 2R
    print(f"4. study unit: c3 = {c3:.4f}, 1/K = {1 / sensor.scale_v_per_dps2:.2f} (°/s²)/V — "
          f"small-signal scale {100 * (sensor.scale_v_per_dps2 / nominal - 1):+.2f} % of "
          f"nominal, non-linearity {100 * 0.2 * c3:.2f} % FR (datasheet ±1 %, ±0.05 % FR)")
    for row in scale_rows(model, seed):
        print(f"   {row.name:<40} study {row.study:>7} twin {row.twin:>10} "
              f"{row.difference:>16} {'ok' if row.ok else 'MISS'}", flush=True)
    if write is not None:
        dump_rig_model(model, write)
        print(f"   written to {write}")


#: Lipschitz bounds tried, as multiples of the record's peak jerk (the analysis uses 1)
JERK_FACTORS = (0.25, 0.3, 0.5, 1.0, 3.0)


def _levant_pair(synced: SyncedStep, sensor: SensorInfo, factor: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(volts, Levant reference °/s²) aligned as the scale-factor analysis aligns them, with
    the differentiator's bound at ``factor`` × the smoothed estimate's peak jerk."""
    fs, f0 = synced.sample_rate_hz, float(synced.step.frequency_hz or 1.0)
    cutoff = default_cutoff_hz(synced)
    smooth = zero_phase_lowpass(synced.table["inner_accel_dps2"], fs, cutoff)
    jerk = float(np.max(np.abs(first_difference(smooth, fs))))
    raw = levant_differentiator(synced.table["inner_rate_dps"], fs, factor * jerk)
    ref = input_accel_dps2(synced, sensor.axis, raw)
    volts = zero_phase_lowpass(synced.daq[sensor.channel], fs, cutoff)
    ratio = fundamental(volts, f0, fs) / fundamental(ref, f0, fs)
    delay_s = float(-np.angle(ratio * np.sign(ratio.real or 1.0)) / (2 * np.pi * f0))
    trim = int(3.0 * fs / cutoff) + int(abs(delay_s) * fs) + 8
    ref = fractional_delay(ref, delay_s, fs)
    return volts[trim:-trim], ref[trim:-trim]


def tuning_rows(seed: int) -> None:
    """The sliding-mode cubic's linear term, L and RMSE over the differentiator's bound."""
    data = simulate_dataset(realistic_rig_model(), _plan("scale-factor.yaml"), seed)
    synced, sensor = synchronise_all(data)[0], data.sensors[0]
    volts, table, *_ = aligned_pair(synced, sensor, "table_estimate")
    print("5. Levant's bound C (× peak jerk): sliding cubic's linear term, L, RMSE "
          f"(study {LINEAR_SLIDING}, {L_SLIDING}, {SCALE['sliding_mode'][2]})")
    for factor in JERK_FACTORS:
        v, ref = _levant_pair(synced, sensor, factor)
        mean = float(np.mean(v))
        g = P.polyfit(volts - mean, table, 1)
        cubic = P.polyfit(v - mean, ref, 3)
        lin = _rms(P.polyval(v - mean, cubic - np.pad(g, (0, 2))))
        rmse = _rms(ref - P.polyval(v - mean, cubic))
        print(f"   C = {factor:<4g} linear {cubic[1]:7.2f}  L {lin:7.3f}  RMSE {rmse:6.2f}",
              flush=True)


def cross_ratios_pct(seed: int) -> np.ndarray:
    """|cross-axis ratio| (%) of every set, sensor and axis of the pivoted test on the
    three-sensor unit (the bench's misalignment section)."""
    from aatest.plugins.sensors.sr207 import SR207Unit

    data = simulate_dataset(realistic_rig_model(SR207Unit().datasheet()),
                            _plan("pivoted-misalignment.yaml"), seed)
    sets = run_analysis("misalignment", data).result.sets
    return np.array([100 * abs(r) for sensors in sets.values() for s in sensors.values()
                     for r in (s.cross_ratio_x, s.cross_ratio_y)])


def cross_rows(seeds: list[int]) -> None:
    """Cross-axis ratio range of the pivoted test per seed (the unit's mounting draws) and the
    spread of its maximum, the statistic the bench compares with the study's 1.1 %."""
    low, high = CROSS_RANGE_PCT
    print(f"6. cross-axis ratios (pivoted test, 8 sets × 3 sensors × 2 axes), % — study "
          f"{low:g}–{high:g}")
    maxima = []
    for seed in seeds:
        ratios = cross_ratios_pct(seed)
        maxima.append(float(ratios.max()))
        print(f"   seed {seed:>2}: {ratios.min():.3f}–{ratios.max():.3f}", flush=True)
    if len(maxima) > 1:
        m, sd = float(np.mean(maxima)), float(np.std(maxima, ddof=1))
        print(f"   maximum over {len(maxima)} seeds: {min(maxima):.3f}–{max(maxima):.3f}, mean "
              f"{m:.3f} ± {sd:.3f} (SD); the study's {high:g} is {(high - m) / sd:+.1f} SD from "
              "the mean — one draw of the same spread")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[7])
    parser.add_argument("--only", nargs="+",
                        choices=["identity", "consistency", "scan", "variant", "tuning",
                                 "cross"],
                        default=["identity", "consistency", "scan", "variant", "tuning"])
    parser.add_argument("--write-model", type=Path, help="write the study-unit model YAML here")
    args = parser.parse_args()
    seed = args.seeds[0]
    if "identity" in args.only:
        identity_rows(seed)
    if "consistency" in args.only:
        consistency_rows()
    if "scan" in args.only:
        scan_rows(seed)
    if "variant" in args.only:
        variant_rows(seed, args.write_model)
    if "tuning" in args.only:
        tuning_rows(seed)
    if "cross" in args.only:
        cross_rows(args.seeds)


if __name__ == "__main__":
    main()
