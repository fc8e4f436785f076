"""One step's channel spectra, shared by the FRF point and the cross-correlation term.

Inside the sync pass's scope (:func:`aatest.plugins.analysis.step_spectra.shared`) each record
is transformed once; the cross-correlation is then formed from the records' own DFTs (the
circular correlation less its wrapped products). Both must give the values computed apart.
"""

from __future__ import annotations

import gc

import numpy as np

from aatest import record_spectra
from aatest.clocksync.relation import ClockRelation, SyncedStep
from aatest.engine.datasheet import SensorInfo
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.frf import frf_point
from aatest.plugins.analysis.tf_xcorr import _padded_term, _xcorr_term
from aatest.record_spectra import BY_MEMORY, centred_rfft, shared

FS_HZ = 2000.0
N = 2**14
MAX_LAG = 100
DELAY = 7  # samples the sensor lags the table by


def _synced(seed: int) -> tuple[SyncedStep, SensorInfo]:
    """A coherent 2^14-sample sine step whose sensor follows the table ``DELAY`` samples late."""
    cycles = 41
    f_hz = cycles * FS_HZ / N
    step = PlannedStep(id="s", kind="sine", axis="inner", samples=N, duration_s=N / FS_HZ,
                       sample_rate_hz=FS_HZ, frequency_hz=f_hz, cycles=cycles,
                       amplitude_deg=1.0, accel_dps2=10.0, group="g")
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS_HZ
    accel = 10.0 * np.sin(2 * np.pi * f_hz * t) + rng.normal(0.0, 0.5, N)
    volts = 1e-3 * np.roll(accel, DELAY) + rng.normal(0.0, 1e-4, N)
    relation = ClockRelation(offset_s=0.0, drift_ppm=0.0, residual_rms_us=0.0, edges_used=10)
    synced = SyncedStep(step=step, time_s=t, sample_rate_hz=FS_HZ,
                        table={"inner_accel_dps2": accel,
                               "inner_position_deg": np.zeros(N)},
                        daq={"v": volts}, relation=relation)
    return synced, SensorInfo(channel="v", axis="I")


def test_xcorr_from_the_records_dfts_is_the_linear_correlation() -> None:
    synced, sensor = _synced(3)
    x = synced.table["inner_accel_dps2"] - np.mean(synced.table["inner_accel_dps2"])
    y = synced.daq["v"] - np.mean(synced.daq["v"])
    direct = np.array([x[:N - lag] @ y[lag:] / (N - lag) for lag in range(MAX_LAG + 1)])
    direct /= np.std(x) * np.std(y)
    term = _xcorr_term(synced, sensor, MAX_LAG)
    # each value is a sum of at most N products over (N − lag)·σx·σy; a sum in any order
    # (direct, FFT, another CPU's kernels) rounds within N·eps of Σ|x·y|/((N − lag)·σx·σy),
    # which Cauchy–Schwarz bounds by N/(N − lag) ≤ 1.01 here: that bound is the tolerance
    bound = N * np.finfo(np.float64).eps * N / (N - MAX_LAG)
    np.testing.assert_allclose(term, direct, rtol=0, atol=bound)
    np.testing.assert_allclose(term, _padded_term(x, y, MAX_LAG), rtol=0, atol=bound)
    assert int(np.argmax(term)) == DELAY


def test_shared_spectra_give_the_values_computed_apart() -> None:
    synced, sensor = _synced(4)
    apart = frf_point(synced, sensor), _xcorr_term(synced, sensor, MAX_LAG)
    with shared():
        together = frf_point(synced, sensor), _xcorr_term(synced, sensor, MAX_LAG)
    assert together[0] == apart[0]  # the same DFT, the same operations after it
    assert np.array_equal(together[1], apart[1])


def test_a_spectrum_is_kept_only_inside_the_scope() -> None:
    x = np.random.default_rng(5).normal(size=64)
    assert centred_rfft(x, "k") is not centred_rfft(x, "k")
    with shared():
        first = centred_rfft(x, "k")
        assert centred_rfft(x, "k") is first
        assert centred_rfft(x[:32], "k") is not first  # another length: another record
        assert not first.flags.writeable
    np.testing.assert_array_equal(first, np.fft.rfft(x - x.mean()))


def test_a_read_only_record_is_known_by_its_memory_while_it_lives() -> None:
    owner = np.random.default_rng(6).normal(size=256)
    owner.flags.writeable = False  # as a decoded recording's channel
    first = centred_rfft(owner, BY_MEMORY)
    assert centred_rfft(owner[:], "any key") is first  # another view of the same values
    assert centred_rfft(owner[:128], BY_MEMORY) is not first  # other values
    writeable = owner.copy()
    assert centred_rfft(writeable, BY_MEMORY) is not centred_rfft(writeable, BY_MEMORY)
    np.testing.assert_array_equal(first, np.fft.rfft(owner - owner.mean()))
    kept = len(record_spectra._KEPT)
    del owner
    gc.collect()
    assert len(record_spectra._KEPT) < kept  # gone with its record


def test_a_record_changed_under_its_memory_is_transformed_again() -> None:
    owner = np.random.default_rng(7).normal(size=256)
    owner.flags.writeable = False
    first = centred_rfft(owner, BY_MEMORY)
    owner.flags.writeable = True  # its owner takes the promise back (a reused buffer)
    owner[3] += 1.0
    owner.flags.writeable = False
    again = centred_rfft(owner, BY_MEMORY)
    assert again is not first
    np.testing.assert_array_equal(again, np.fft.rfft(owner - owner.mean()))


def test_the_centred_spectrum_through_the_scratch_buffer_is_the_plain_one() -> None:
    """Records of changing lengths (the buffer grows, then serves a shorter one) transform as
    ``rfft(x - x.mean())`` does, bit for bit, and a kept spectrum is not the buffer's."""
    rng = np.random.default_rng(5)
    spectra = []
    for n in (1000, N, 999, N + 3, 17):
        x = 3.0 + rng.normal(size=n)
        spectra.append((centred_rfft(x), np.fft.rfft(x - x.mean())))
    for got, expected in spectra:
        np.testing.assert_array_equal(got, expected)
