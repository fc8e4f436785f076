"""Why two rows of ``bench/study.py`` stay open: the evidence, printed (issue 28).

1. **Phase-delay spread at 1 °/s²** (study 24–31 samples; the twin's top point exceeds 31).
   The stepped sine's 1 °/s² group on the realistic twin, per seed, beside the same rig
   without output noise and without hysteresis: if the noise-free chain sits inside the
   range and the outliers sit at the lowest frequencies (phase noise in samples grows as
   1/f), the miss is the 1 mV output noise on a 4 mV signal, not a missing low-acceleration
   effect — and a threshold/stiction term would only add lag.
2. **TF00 fit** (study 78.56 %). A gain-only model of a pure relative delay between the input
   estimate and the sensor output, on the validation frequencies of three readings of the
   design (1–10 Hz whole frequencies; 1–28 Hz whole frequencies; the study's 28 test points
   with points 7, 11, …, 27 identifying), fit over the records together and the mean of the
   records' own fits: which relative delay each fit implies.
3. **Transfer-function rows on the twin** (``bench/study.py``'s design) with the table's
   acceleration estimate as input, raw and through a causal 2nd-order Butterworth low-pass
   (the smoothing the brief says the estimate needs, which also delays it): TF00 (both fit
   readings), the best model without a delay and the best with 28 samples, and the filter's
   lag. If one filter puts TF00 and the 28-sample row on the study's numbers together, the
   study's input was a smoothed estimate, not the raw one.

    python bench/study_gaps.py [--seeds 7 8 9] [--only delay tf00 tf]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scipy import signal
from study import STUDY_DELAY_SAMPLES, TfDesign, _accel_steps, frf_points, tf_design, tf_fits

from aatest.plugins.analysis.tfest import fit_discrete_tf, time_domain_fit
from aatest.twin.api import realistic_rig_model

FS_HZ = 2000.0
#: validation frequencies (Hz): the shipped design (1–10 Hz less 1, 4, 7, 10) and the study's
#: (whole frequencies 1–28 Hz less its identification set 7, 11, …, 27)
TWIN_VALID_HZ = (2.0, 3.0, 5.0, 6.0, 8.0, 9.0)
STUDY_VALID_HZ = tuple(float(f) for f in range(1, 29) if f not in (7, 11, 15, 19, 23, 27))
#: the study's 28 test points (docs/method.md §4.4), Hz, and the ones that identify (1-based)
MATRIX_HZ = (0.396728516, 0.473022461, 0.579833984, 0.686645508, 0.823974609, 0.991821289,
             1.007080078, 1.190185547, 1.434326172, 1.708984375, 1.998901367, 2.059936523,
             2.487182617, 2.975463867, 3.005981445, 3.570556641, 3.997802734, 4.272460938,
             5.004882813, 5.142211914, 5.996704102, 6.164550781, 7.003784180, 7.400512695,
             7.995605469, 8.880615234, 9.002685547, 9.994506836)
IDENT_POINTS = (7, 11, 15, 19, 23, 27)
MATRIX_IDENT_HZ = tuple(MATRIX_HZ[i - 1] for i in IDENT_POINTS)
MATRIX_VALID_HZ = tuple(f for f in MATRIX_HZ if f not in MATRIX_IDENT_HZ)
#: the causal low-pass corners (Hz) tried on the input estimate; None = the raw estimate
INPUT_CORNERS_HZ = (None, 50.0, 30.0)
#: the model scan of the input variants stops here (n ≤ 5 in bench/study.py takes minutes each)
GAP_MAX_POLES = 3


def delay_rows(seeds: list[int]) -> None:
    """Phase-delay range (samples) of the 1 °/s² group: realistic, no noise, no hysteresis."""
    steps = [s for s in _accel_steps() if abs((s.accel_dps2 or 0.0) - 1.0) < 1e-9]
    base = realistic_rig_model()
    sensor = base.sensors[0]
    variants = {"realistic": base,
                "no output noise": base.model_copy(update={"sensors": [
                    sensor.model_copy(update={"noise_rms_v": 0.0})]}),
                "no hysteresis": base.model_copy(update={"sensors": [
                    sensor.model_copy(update={"hysteresis": None})]})}
    for seed in seeds:
        for name, model in variants.items():
            points = frf_points(model, seed, steps)[1.0]
            d = np.array([p.delay_samples for p in points])
            worst = points[int(np.argmax(np.abs(d - np.median(d))))]
            print(f"seed {seed:>2} {name:<16} {d.min():5.1f}–{d.max():5.1f} samples; farthest "
                  f"from the median: {worst.delay_samples:.1f} at {worst.frequency_hz:.2f} Hz",
                  flush=True)


def tf00_fit_pct(valid_hz: tuple[float, ...], delay_samples: float,
                 ident_hz: tuple[float, ...] | None = None, per_record: bool = False) -> float:
    """Fit % (100·(1 − ‖y − g·u‖/‖y − ȳ‖)) of a gain g for sines of equal amplitude delayed by
    ``delay_samples`` relative to the input: g best on ``ident_hz`` (on ``valid_hz`` if None);
    over the records together, or (``per_record``) the mean of each record's fit."""
    phase = 2 * np.pi * np.asarray(valid_hz) * delay_samples / FS_HZ
    ident = phase if ident_hz is None else 2 * np.pi * np.asarray(ident_hz) * delay_samples / FS_HZ
    err = np.abs(np.exp(-1j * phase) - np.mean(np.cos(ident)))
    return float(100 * (np.mean(1 - err) if per_record else 1 - np.sqrt(np.mean(err**2))))


def tf00_rows() -> None:
    print(f"{'relative delay':>16} {'1–10 Hz':>9} {'1–28 Hz':>9} {'28 points':>10} "
          f"{'28 points, mean of records':>27}")
    for samples in (0.0, 4.0, 10.0, 15.0, 20.0, 24.0, 26.5, 28.0, 31.0):
        print(f"{samples:>8.1f} samples {tf00_fit_pct(TWIN_VALID_HZ, samples):>7.1f} % "
              f"{tf00_fit_pct(STUDY_VALID_HZ, samples):>7.1f} % "
              f"{tf00_fit_pct(MATRIX_VALID_HZ, samples, MATRIX_IDENT_HZ):>8.1f} % "
              f"{tf00_fit_pct(MATRIX_VALID_HZ, samples, MATRIX_IDENT_HZ, True):>25.1f} %")


def filtered_input(design: TfDesign, corner_hz: float | None) -> TfDesign:
    """``design`` with every input record through a causal 2nd-order Butterworth low-pass at
    ``corner_hz`` (the FRF points then relate the output to the filtered input)."""
    if corner_hz is None:
        return design
    sos = signal.butter(2, corner_hz, fs=1.0 / design.dt, output="sos")
    _, hf = signal.sosfreqz(sos, worN=design.f_hz, fs=1.0 / design.dt)
    records, ident = ([(signal.sosfilt(sos, u), y) for u, y in rs]
                      for rs in (design.records, design.ident_records))
    return TfDesign(design.f_hz, design.h / hf, design.ident, design.valid, records, design.dt,
                    ident)


def tf_rows(seed: int) -> None:
    """The transfer-function rows with the raw and the low-passed table estimate as input."""
    base = tf_design(realistic_rig_model(), seed)
    print(f"seed {seed}: study TF00 78.56 %, best 98.36–98.59 %, 28-sample delay 92.8–95.3 % "
          f"(models n ≤ {GAP_MAX_POLES} here)")
    print(f"{'input':<22} {'lag, samples':>12} {'TF00':>8} {'TF00 rec.':>10} "
          f"{'best, no delay':>16} {'best, 28 samples':>18}")
    for corner in INPUT_CORNERS_HZ:
        design = filtered_input(base, corner)
        fits = tf_fits(design, max_poles=GAP_MAX_POLES)
        gain = fit_discrete_tf(design.f_hz[design.ident], design.h[design.ident], 0, 0,
                               design.dt)
        per_record = np.mean([time_domain_fit(gain, [r], 2000) for r in design.records])
        best = max((v, k) for k, v in fits.items() if k[2] == 0 and k[0] > 0)
        late = max((v, k) for k, v in fits.items() if k[2] == STUDY_DELAY_SAMPLES)
        lag = -np.angle(design.h[0]) / (2 * np.pi * design.f_hz[0] * design.dt)
        name = "raw estimate" if corner is None else f"low-pass {corner:g} Hz"
        print(f"{name:<22} {lag:>12.1f} {fits[(0, 0, 0)]:>7.2f}% {per_record:>9.2f}% "
              f"{best[0]:>8.2f}% (n={best[1][0]},m={best[1][1]}) "
              f"{late[0]:>9.2f}% (n={late[1][0]},m={late[1][1]})", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8, 9])
    parser.add_argument("--only", nargs="+", choices=["delay", "tf00", "tf"],
                        default=["delay", "tf00", "tf"])
    args = parser.parse_args()
    if "tf00" in args.only:
        tf00_rows()
    if "tf" in args.only:
        tf_rows(args.seeds[0])
    if "delay" in args.only:
        delay_rows(args.seeds)


if __name__ == "__main__":
    main()
