"""Re-synchronising a step with the sync pass's clock relation gives the very same step."""

from __future__ import annotations

from synthetic_rig import SynthRig, make_step, sine_step

from aatest.clocksync import freeze_pulse, synchronise
from aatest.clocksync.freeze_pulse import clock_relation


def test_relation_from_the_sync_pass_reproduces_the_step_bit_for_bit() -> None:
    """The relation carries the DAQ stamps' line fit; synchronising with it (no refit) gives
    the arrays a synchronisation from scratch gives, bit for bit."""
    data = make_step(sine_step("s", 8, 100.0), SynthRig(drift_ppm=37.0), seed=4)
    relation = clock_relation(data)
    assert relation.daq_time_fit is not None
    fresh, reused = synchronise(data), synchronise(data, relation)
    assert fresh.time_s.tobytes() == reused.time_s.tobytes()
    assert set(fresh.daq) == set(reused.daq) == set(data.daq.channels)
    for name in fresh.daq:
        assert fresh.daq[name].tobytes() == reused.daq[name].tobytes(), name
    for name in fresh.table:
        assert fresh.table[name].tobytes() == reused.table[name].tobytes(), name


def test_daq_channels_are_resampled_when_read(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Only the channels an analysis reads are splined, each once."""
    calls: list[int] = []
    original = freeze_pulse.uniform_cubic_spline

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(freeze_pulse, "uniform_cubic_spline", counting)
    synced = synchronise(make_step(sine_step("s", 8, 100.0), SynthRig(), seed=6))
    assert calls == []
    first = synced.daq["v_sz"]
    assert synced.daq["v_sz"] is first and len(calls) == 1
    assert synced.daq["sync_pulse"].size == first.size and len(calls) == 1  # digital: no spline
