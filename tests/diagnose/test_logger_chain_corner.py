"""The logger's pre-sample filter corner read from the residual noise (no model file stated).

Once ``fp_latch_s`` resolves the alignment, a corner error is a timing error: a 2nd-order
filter at fc lags √2/(2π·fc) at low frequency (2.25 ms at 100 Hz), so reading 90 Hz for the
rig's 100 Hz filter is a 0.25 ms lead — a spurious ``jerk_sensitivity``. Lines in the noise
(a motor, mains, harmonics of a clipped or backlashed sine) must not bend the estimate.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from aatest.diagnose.candidates.logger import WELCH_SEGMENT
from aatest.diagnose.logger_chain import DEFAULT_ANTIALIAS_HZ, estimate_corner_hz, stated_antialias
from aatest.engine.errors import ProcedureError
from aatest.recording.dataset import Dataset
from aatest.twin.daq import antialias_filter

FS_HZ = 2000.0
SAMPLES = 4096
STEPS = 2


def _noise_psd(corner_hz: float, lines_hz: tuple[float, ...], seed: int
               ) -> tuple[np.ndarray, np.ndarray, int]:
    """Welch PSD of two records of filtered sensor noise (1 mV) + ADC floor + lines."""
    rng = np.random.default_rng(seed)
    b, a, _ = antialias_filter(corner_hz, 1.0 / FS_HZ)
    t = np.arange(SAMPLES) / FS_HZ
    spectra, segments = [], 0
    for _ in range(STEPS):
        x = signal.lfilter(b, a, rng.normal(0.0, 1e-3, SAMPLES + 1000))[1000:]
        x += rng.normal(0.0, 1e-4, SAMPLES)
        for k, f in enumerate(lines_hz):  # 20 mV down to ~1 mV: far above the noise
            x += 0.02 / (k + 1) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        f_hz, p = signal.welch(x, fs=FS_HZ, nperseg=WELCH_SEGMENT,
                               detrend=lambda v: np.asarray(signal.detrend(v, type="linear")))
        spectra.append(p)
        segments += (SAMPLES - WELCH_SEGMENT) // (WELCH_SEGMENT // 2) + 1
    return f_hz, np.mean(spectra, axis=0), segments


@pytest.mark.parametrize("seed", range(6))
def test_the_rigs_filter_is_read_as_100_hz_on_two_short_records(seed: int) -> None:
    f, p, k = _noise_psd(DEFAULT_ANTIALIAS_HZ, (), seed)
    assert estimate_corner_hz(f, p, FS_HZ, k) == DEFAULT_ANTIALIAS_HZ


@pytest.mark.parametrize("seed", range(3))
def test_lines_in_the_noise_do_not_bend_the_corner(seed: int) -> None:
    """A motor band near 38 Hz, mains at 50 Hz and odd harmonics of a clipped 8 Hz sine."""
    lines = (37.2, 38.1, 38.9, 50.0, *(8.0 * k for k in range(3, 20, 2)))
    f, p, k = _noise_psd(DEFAULT_ANTIALIAS_HZ, lines, seed)
    assert estimate_corner_hz(f, p, FS_HZ, k) == DEFAULT_ANTIALIAS_HZ


def test_another_corner_is_estimated_not_snapped() -> None:
    f, p, k = _noise_psd(160.0, (42.0,), 7)
    fc = estimate_corner_hz(f, p, FS_HZ, k)
    assert fc != DEFAULT_ANTIALIAS_HZ
    assert fc == pytest.approx(160.0, rel=0.05)


def _dataset_with_model_file(folder: Path, text: str) -> Dataset:
    (folder / "model.yaml").write_text(text)
    return Dataset(procedure="imported", sample_rate_hz=FS_HZ, sensors=(), steps=(),
                   source=folder, metadata={"model_file": "model.yaml"})


def test_a_model_file_states_the_filter_only_when_it_describes_the_logger(tmp_path: Path) -> None:
    sensor_only = _dataset_with_model_file(
        tmp_path, "sensors:\n  - {channel: v_sz, axis: I, scale_v_per_dps2: 0.004}\n")
    assert stated_antialias(sensor_only) == (False, None)  # estimated from the noise instead
    with_logger = _dataset_with_model_file(tmp_path, "daq: {antialias_hz: 160.0}\n")
    assert stated_antialias(with_logger) == (True, 160.0)


def test_a_broken_model_file_is_bad_input_naming_it(tmp_path: Path) -> None:
    broken = _dataset_with_model_file(tmp_path, "daq: {antialias_hz: [1,}\n")
    with pytest.raises(ProcedureError) as raised:
        stated_antialias(broken)
    assert str(raised.value).startswith(f"{tmp_path / 'model.yaml'}:1:")
