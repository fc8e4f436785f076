"""The study's low-acceleration FRF rows: why the gain falls from ≈ 2 Hz (issue 28).

The study (docs/method.md §1.3): at 1 and 10 °/s² the gain starts to fall at ≈ 2 Hz and is 1.0
and 0.5 dB down at 10 Hz; 0.4 and 0.2 dB at 100 and 400 °/s²; the phase delay is 24–31 samples,
a pure transport delay at 100 and 400 °/s², irregular at 1 and 10 °/s². ``bench/study.py``
reads "starts to fall" as the lowest point from which every higher one is ≥ 0.1 dB below the
flat level (the mean gain at ≤ 1 Hz), ± 1 Hz.

1. ``shape`` (describing functions, seconds). A damping change (``amplitude_damping``) moves
   the gain as f² at low frequency: with 0.5 dB at 10 Hz the loss at 2.98 Hz is ≈ 0.04 dB, and
   the damping that reaches 0.1 dB there lags by more than the study's 31 samples. A gain loss
   that grows *linearly* with f and carries no phase is the describing function of a gap at
   the rate reversals (``rotor_stiction``: the rotor sticks while |rate| < r and loses the
   share ``depth`` of its response; the loss is depth·N(2πf·r/A)): it meets the 10 °/s² row.
   But any mechanism whose loss is a function of f/A (a rate threshold) makes the 1 °/s²
   loss rise ten times faster than the 10 °/s² one, while the study's roll-offs need about
   twice: the grid below finds no (r, depth) that meets both lowest accelerations' rows.
2. ``frf`` (minutes). ``bench/study.py``'s FRF rows on the realistic twin and on the realistic
   twin with the stiction gap (``realistic_rig_model(stiction=True)``, ``--variants``).

    python bench/study_lowamp.py [--seed 7] [--only shape frf] [--variants realistic stiction]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study import DELAY_RANGE, FALL_DB, frf_rows

from aatest.twin.api import realistic_rig_model
from aatest.twin.defaults import REALISTIC_STICTION

FS_HZ = 2000.0
#: the stepped sine's 28 points (cycles in 2^17 samples at 2 kHz, docs/method.md §4.4)
F_HZ = np.array([26, 31, 38, 45, 54, 65, 66, 78, 94, 112, 131, 135, 163, 195, 197, 234, 262,
                 280, 328, 337, 393, 404, 459, 485, 524, 582, 590, 655]) * FS_HZ / 2**17
#: the twin's sensor natural frequency (Hz) and the delay (samples) of everything but the
#: sensor's second-order lag: transport 2.1 ms and the 100 Hz pre-sample filter
NATURAL_HZ, OTHER_DELAY_SAMPLES = 30.0, 8.7
#: the study's roll-offs at 10 Hz (dB) of the two lowest accelerations, and the tolerance
ROLL_OFF_DB, ROLL_TOL_DB = {1.0: 1.0, 10.0: 0.5}, 0.15


def _relative(gain_db: np.ndarray) -> np.ndarray:
    """Loss below the flat level (mean gain at ≤ 1 Hz), dB."""
    return gain_db[F_HZ <= 1.0 + 1e-6].mean() - gain_db


def damping_loss_db(zeta: float) -> np.ndarray:
    """Loss of the sensor's second-order response below its flat level, dB, per point."""
    r = F_HZ / NATURAL_HZ
    return _relative(-20 * np.log10(np.hypot(1 - r * r, 2 * zeta * r)))


def gap_share(x: np.ndarray) -> np.ndarray:
    """Share of a sine's fundamental lying where |rate| < r, x = r/W (W the rate amplitude)."""
    x = np.minimum(x, 1.0)
    return 2 / np.pi * (np.arcsin(x) + x * np.sqrt(1 - x * x))


def gap_loss_db(accel_dps2: float, rate_dps: float, depth: float, zeta: float) -> np.ndarray:
    """Loss below flat of the stiction gap on top of the second-order response, dB."""
    w = accel_dps2 / (2 * np.pi * F_HZ)
    gain = 20 * np.log10(1 - depth * gap_share(rate_dps / w))
    r = F_HZ / NATURAL_HZ
    return _relative(gain - 20 * np.log10(np.hypot(1 - r * r, 2 * zeta * r)))


def _fall_margin(loss: np.ndarray, start_max_hz: float, start_min_hz: float) -> float:
    """How far (dB) a loss curve is from a fall start within [start_min, start_max] Hz:
    every point from ``start_max`` on ≥ 0.1 dB down, and some point in [start_min,
    start_max) less than 0.1 dB down; > 0 when both hold."""
    late = loss[start_max_hz - 1e-6 <= F_HZ].min() - FALL_DB
    window = (start_min_hz - 1e-6 <= F_HZ) & (start_max_hz - 1e-6 > F_HZ)
    early = FALL_DB - loss[window].min()
    return float(min(late, early))


def shape_rows() -> None:
    print("1a. damping only (sensor ωn 30 Hz): loss below flat and the low-frequency delay")
    print(f"{'ζ':>6} {'2.98 Hz':>9} {'10 Hz':>8} {'delay, samples':>15}")
    i3 = int(np.argmin(np.abs(F_HZ - 2.9755)))
    for zeta in (0.73, 0.8, 0.9, 1.0, 1.05, 1.1):
        loss = damping_loss_db(zeta)
        delay = 2 * zeta / (2 * np.pi * NATURAL_HZ) * FS_HZ + OTHER_DELAY_SAMPLES
        print(f"{zeta:>6.2f} {loss[i3]:>7.3f}dB {loss[-1]:>6.2f}dB {delay:>15.1f}")
    print(f"   study: 10 °/s² is 0.5 dB down at 10 Hz and ≥ {FALL_DB} dB from ≤ 2.98 Hz; "
          f"delays ≤ {DELAY_RANGE[1]:g} samples")
    print("1b. rotor stiction gap (any r, depth; ζ 0.73–0.85): best joint margin of the rows")
    best = (-np.inf, 0.0, 0.0, 0.0)
    for rate in np.geomspace(0.003, 0.3, 60):
        for depth in np.arange(0.02, 0.99, 0.02):
            for zeta in (0.73, 0.76, 0.79, 0.82, 0.85):
                low, ten = (gap_loss_db(a, rate, depth, zeta) for a in (1.0, 10.0))
                margin = min(_fall_margin(low, 3.0, 1.0), _fall_margin(ten, 3.0, 1.0),
                             ROLL_TOL_DB - abs(low[-1] - ROLL_OFF_DB[1.0]),
                             ROLL_TOL_DB - abs(ten[-1] - ROLL_OFF_DB[10.0]))
                best = max(best, (margin, rate, depth, zeta))
    margin, rate, depth, zeta = best
    print(f"   best margin {margin:+.3f} dB at r = {rate:.3g} °/s, depth {depth:.2f}, ζ {zeta:.2f} "
          f"({'met' if margin > 0 else 'not met'}: > 0 needs every row)")
    s = REALISTIC_STICTION
    for accel in (1.0, 10.0):
        loss = gap_loss_db(accel, s.breakaway_rate_dps, s.depth, 0.78)
        print(f"   twin's gap (r {s.breakaway_rate_dps:g} °/s, depth {s.depth:g}, ζ 0.78), "
              f"{accel:g} °/s²: " + " ".join(f"{f:.2f}:{v:.2f}" for f, v in
                                             zip(F_HZ[4:20:3], loss[4:20:3], strict=True))
              + f" … 9.99:{loss[-1]:.2f} dB")


def frf_table(seed: int, variants: list[str]) -> None:
    models = {"realistic": realistic_rig_model,
              "stiction": lambda: realistic_rig_model(stiction=True)}
    for name in variants:
        model = models[name]()
        print(f"2. {name} (seed {seed})")
        for row in frf_rows(model, seed):
            print(f"   {row.name:<44} {row.study:>10} {row.twin:>14} {row.difference:>12}  "
                  f"{row.tolerance} {'ok' if row.ok else 'MISS'}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--only", nargs="+", choices=["shape", "frf"], default=["shape", "frf"])
    parser.add_argument("--variants", nargs="+", choices=["realistic", "stiction"],
                        default=["realistic", "stiction"], help="rigs of the frf section")
    args = parser.parse_args()
    if "shape" in args.only:
        shape_rows()
    if "frf" in args.only:
        frf_table(args.seed, args.variants)


if __name__ == "__main__":
    main()
