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

4. **What caps the study's linear fits** (best models 98.36–98.59 %, the twin 99.86 % without
   a distortion). The 400 °/s² design with and without the rotor's ``jerk_distortion``: the
   sensor's and the table estimate's THD per frequency (the study: THD rises above ≈ 4 Hz and
   with amplitude, higher in the sensor than in the table signal) and the transfer-function
   rows (n ≤ 3). A residual no linear model removes lowers the best fit and, in quadrature,
   the 28-sample row; it cannot raise TF00.
5. **Is the logged estimate band-limited?** The noise of the table's acceleration estimate
   (the records less their fitted harmonics) raw and through the 50 Hz low-pass of item 3:
   the study's scale-factor RMSE against that estimate (29.8 °/s², §4.3) needs the raw
   estimate's noise, so a controller filter lagging it ≈ 9 samples is not what it logged.

6. **What puts TF00 on 78.56 %** (``cause``). The design's TF00 read as MATLAB's ``compare``
   might report it (the validation records together, the mean and the median of their own fits,
   1 − NMSE, a gain with a one-sample lag: a discrete ``tfest`` without feedthrough, or a
   backward second difference in the estimate), beside the FRF delay and the cross-correlation
   delay, with the input paired 0–14 samples late against the output (a shift that keeps the
   estimate's noise: ``bench/study.py``'s ``lag_input``); then the delayed and undelayed models
   (n ≤ 2) unshifted, 12 samples late and through a causal 50 Hz low-pass (item 3's smoothing,
   which lags without the noise). Only a lag reaches 78.56 %, at ≈ 12 samples; there the
   28-sample row comes within the bench's ± 1.5 of the study's range too (n ≤ 5 in
   ``bench/study.py --tf-input-lag 12``: inside it, 94.41 %), while the FRF and cross-
   correlation delays fall to 12–13 samples: the study's TF records and its FRF records cannot
   share one alignment.

    python bench/study_gaps.py [--seeds 7 8 9] [--only delay tf00 tf thd estimate cause]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scipy import signal
from study import (
    STUDY_DELAY_SAMPLES,
    TfDesign,
    _accel_steps,
    frf_points,
    lag_input,
    tf_design,
    tf_fits,
)

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


def thd_pct(x: np.ndarray, f_hz: float, harmonics: int = 6) -> float:
    """THD (harmonics 2..6 over the fundamental, %) of a coherent record's DFT bins."""
    spectrum = np.abs(np.fft.rfft(x - np.mean(x)))
    k = round(f_hz * x.size / FS_HZ)
    amps = spectrum[[k * h for h in range(1, harmonics + 1)]]
    return float(100 * np.sqrt(np.sum(amps[1:] ** 2)) / amps[0])


def without_distortion(seed: int) -> TfDesign:
    """The design on the realistic rig with the rotor's jerk distortion switched off."""
    model = realistic_rig_model()
    sensors = [s.model_copy(update={"jerk_distortion": None}) for s in model.sensors]
    return tf_design(model.model_copy(update={"sensors": sensors}), seed)


def thd_rows(seeds: list[int]) -> None:
    """THD and transfer-function rows without and with the rotor's jerk distortion."""
    variants = {"without jerk_distortion": without_distortion(seeds[0]),
                "realistic (with it)": tf_design(realistic_rig_model(), seeds[0])}
    shown = (0, 5, 10, 13, 15, 17, 19, 21)  # validation records 0.40 … 9.99 Hz
    for name, design in variants.items():
        f_valid = design.f_hz[design.valid]
        print(f"{name}: THD %, table estimate / sensor, at "
              + ", ".join(f"{f_valid[i]:.1f} Hz {thd_pct(design.records[i][0], f_valid[i]):.2f}"
                          f"/{thd_pct(design.records[i][1], f_valid[i]):.2f}" for i in shown))
        fits = tf_fits(design, max_poles=GAP_MAX_POLES)
        best = max((v, k) for k, v in fits.items() if k[2] == 0 and k[0] > 0)
        late = max((v, k) for k, v in fits.items() if k[2] == STUDY_DELAY_SAMPLES)
        print(f"{'':4}TF00 {fits[(0, 0, 0)]:.2f} %, best no delay {best[0]:.2f} % "
              f"(n={best[1][0]},m={best[1][1]}), 28-sample delay {late[0]:.2f} % "
              f"(n={late[1][0]},m={late[1][1]}); study 78.56, 98.36–98.59, 92.8–95.3",
              flush=True)


def estimate_rows(seeds: list[int]) -> None:
    """Noise of the table's acceleration estimate, raw and through a 50 Hz low-pass."""
    design = tf_design(realistic_rig_model(), seeds[0])
    sos = signal.butter(2, 50.0, fs=FS_HZ, output="sos")
    for name, filt in (("raw (what the twin logs)", None), ("50 Hz low-pass", sos)):
        rms = []
        for (u, _), f in zip(design.records, design.f_hz[design.valid], strict=True):
            x = u if filt is None else signal.sosfilt(filt, u)[2000:]
            t = np.arange(x.size) / FS_HZ
            cols = [np.ones_like(t)] + [g(2 * np.pi * h * f * t) for h in range(1, 7)
                                        for g in (np.sin, np.cos)]
            basis = np.column_stack(cols)
            coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
            rms.append(float(np.std(x - basis @ coef)))
        print(f"estimate noise, {name:<26} {np.mean(rms):6.2f} °/s² RMS (study's scale-factor "
              "RMSE against the estimate: 29.8)")


#: input lags (samples) the cause scan pairs the output with
CAUSE_LAGS = (0, 1, 10, 11, 12, 13, 14)
#: the input lags whose delayed models the scan fits (n ≤ ``CAUSE_MAX_POLES``: minutes each)
CAUSE_FIT_LAGS, CAUSE_MAX_POLES = (0, 12), 2
#: the smoothing the scan compares with the shift: a causal 2nd-order Butterworth, Hz
CAUSE_CORNER_HZ = 50.0


def xcorr_delay_samples(records: list[tuple[np.ndarray, np.ndarray]], max_lag: int = 80) -> int:
    """The lag (samples) maximising the records' summed normalised input–output correlation
    (the study's "delay from the input–output cross-correlation", §4.4)."""
    total = np.zeros(max_lag + 1)
    for u_in, y_out in records:
        u, y = u_in - np.mean(u_in), y_out - np.mean(y_out)
        nfft = 1 << int(np.ceil(np.log2(u.size + max_lag)))
        c = np.fft.irfft(np.fft.rfft(y, nfft) * np.conj(np.fft.rfft(u, nfft)), nfft)
        total += c[:max_lag + 1] / np.sqrt(np.dot(u, u) * np.dot(y, y))
    return int(np.argmax(total))


def tf00_readings(design: TfDesign) -> dict[str, float]:
    """TF00 (the gain fitted to the identification points) on the validation records, read
    as MATLAB's ``compare`` might report it: over the records together, the mean and the
    median of the records' own fits, 1 − NMSE instead of 1 − NRMSE, and the gain with a
    one-sample lag (a discrete ``tfest`` without feedthrough)."""
    gain = fit_discrete_tf(design.f_hz[design.ident], design.h[design.ident], 0, 0, design.dt)
    own = np.array([time_domain_fit(gain, [r], 2000) for r in design.records])
    together = time_domain_fit(gain, design.records, 2000)
    late = fit_discrete_tf(design.f_hz[design.ident], design.h[design.ident], 0, 0,
                           design.dt, 1)
    return {"together": together, "mean": float(np.mean(own)), "median": float(np.median(own)),
            "1-NMSE": 100 * (1 - (1 - together / 100) ** 2),
            "z^-1 gain": time_domain_fit(late, design.records, 2000)}


def cause_rows(seed: int, fits: bool = True) -> None:
    """What puts TF00 on 78.56 %: the fit's readings, and the input paired L samples late."""
    base = tf_design(realistic_rig_model(), seed)
    print(f"seed {seed}: study TF00 78.56 %, 28-sample delay 92.8–95.3 %, FRF delay 24–31, "
          f"cross-correlation delay {STUDY_DELAY_SAMPLES} samples")
    print(f"{'input lag':>9} {'FRF delay':>10} {'xcorr':>6} "
          + " ".join(f"{k:>10}" for k in tf00_readings(base)))
    for lag in CAUSE_LAGS:
        design = lag_input(base, lag)
        delay = -np.angle(design.h) / (2 * np.pi * design.f_hz * design.dt)
        readings = tf00_readings(design)
        print(f"{lag:>9} {np.median(delay):>10.1f} "
              f"{xcorr_delay_samples(design.ident_records):>6} "
              + " ".join(f"{v:>9.2f}%" for v in readings.values()), flush=True)
    smooth = filtered_input(base, CAUSE_CORNER_HZ)
    print(f"{'low-pass':>9} {'':>10} {xcorr_delay_samples(smooth.ident_records):>6} "
          + " ".join(f"{v:>9.2f}%" for v in tf00_readings(smooth).values())
          + f"  (causal {CAUSE_CORNER_HZ:g} Hz, no shift)", flush=True)
    variants = {f"input {lag} samples late": lag_input(base, lag) for lag in CAUSE_FIT_LAGS}
    variants[f"input through {CAUSE_CORNER_HZ:g} Hz"] = smooth
    for name, design in variants.items() if fits else ():
        out = tf_fits(design, max_poles=CAUSE_MAX_POLES)
        best = max((v, k) for k, v in out.items() if k[2] == 0 and k[0] > 0)
        late = max((v, k) for k, v in out.items() if k[2] == STUDY_DELAY_SAMPLES)
        print(f"{name}: TF00 {out[(0, 0, 0)]:.2f} %, best no delay {best[0]:.2f} % "
              f"(n={best[1][0]},m={best[1][1]}), 28-sample delay {late[0]:.2f} % "
              f"(n={late[1][0]},m={late[1][1]}), n ≤ {CAUSE_MAX_POLES}", flush=True)


SECTIONS = {"tf00": lambda _seeds: tf00_rows(), "tf": lambda seeds: tf_rows(seeds[0]),
            "delay": delay_rows, "thd": thd_rows, "estimate": estimate_rows,
            "cause": lambda seeds: cause_rows(seeds[0])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8, 9])
    parser.add_argument("--only", nargs="+", choices=list(SECTIONS), default=list(SECTIONS))
    args = parser.parse_args()
    for name in args.only:
        SECTIONS[name](args.seeds)


if __name__ == "__main__":
    main()
