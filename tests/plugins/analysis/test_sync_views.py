"""Views of the synchronised steps of a recording: filtered and channel-restricted."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aatest.engine.analysis.passes import run_analyses
from aatest.plugins.analysis.sync import SyncedSteps
from aatest.recording import read_dataset

RECORDING = Path(__file__).parents[2] / "recording" / "data" / "streaming" / "recording.mcap"


def test_a_view_of_some_channels_synchronises_them_identically() -> None:
    """SyncedSteps.only decodes and resamples only the channels named (plus the time stamps),
    and gives exactly the values the whole step gives for them."""
    data = read_dataset(RECORDING)
    synced = run_analyses(data, ["sync"]).outputs["sync"].steps  # type: ignore[attr-defined]
    assert isinstance(synced, SyncedSteps)
    sensor = data.sensors[0].channel
    some = synced.where(lambda p: p.kind == "sine").only(table=("inner_accel_dps2",),
                                                         daq=(sensor,))
    assert len(some) == len(synced)
    for k in (0, 5):
        whole, part = synced[k], some[k]
        assert set(part.table) == {"inner_accel_dps2"} and set(part.daq) == {sensor}
        assert part.relation == whole.relation
        np.testing.assert_array_equal(part.time_s, whole.time_s)
        np.testing.assert_array_equal(part.table["inner_accel_dps2"],
                                      whole.table["inner_accel_dps2"])
        assert part.daq[sensor].tobytes() == whole.daq[sensor].tobytes()
