"""What the page is sent while a long static record streams: its chunks, before the step ends.

``aatest run`` of a 600 s rest on the twin (longer than the simulated table's log, so the DAQ
streams it) with the station's observer: every chunk is published as it arrives, plotted on
one time axis from the record's start, and the table's snapshot log follows the last chunk
without resetting the plot. A short step before it is shown when its loggers deliver it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aatest.engine.run.events import AbortFlag, RunEvents
from aatest.engine.run.session import run
from aatest.station.live import AFTER_STEP, CHUNK_POINTS, LIVE, StationObserver

PROCEDURE = Path(__file__).parent / "data" / "quick-long-static.yaml"
REST_S = 600.0  # the procedure's streamed record, s


def test_streamed_chunks_are_published_before_the_step_ends(tmp_path: Path) -> None:
    seen: list[dict[str, Any]] = []
    observer = StationObserver(seen.append, AbortFlag(), replay_s=0.0)
    run(PROCEDURE, None, tmp_path / "run", False, 3, None, show_progress=False,
        events=RunEvents(observer))
    rest = next(e["id"] for e in seen if e["type"] == "step" and e["id"].startswith("s002"))
    done = seen.index({"type": "step", "id": rest, "state": "done"})
    started = seen.index(next(e for e in seen if e.get("id") == rest and e["type"] == "step"))
    during = seen[started:done]
    resets = [e for e in during if e["type"] == "plot_reset"]
    assert [r["label"] for r in resets] == [LIVE] and resets[0]["live"] is True
    chunks = [e for e in during if e["type"] == "samples" and e.get("live")]
    assert len(chunks) >= 2  # 600 s in chunks of at least 60 s of whole generation blocks
    assert all(len(c["daq"]["t"]) <= CHUNK_POINTS for c in chunks)
    t = np.concatenate([c["daq"]["t"] for c in chunks])
    assert np.all(np.diff(t) > 0)  # one time axis from the record's start, chunk after chunk
    assert t[0] == 0.0 and abs(t[-1] - REST_S) < 2.0  # to the last chunk's last point, ±2 s
    # the twin's sensor at rest, I up: its 2.5 V bias within 50 mV
    volts = np.concatenate([c["daq"]["v_sz"] for c in chunks])
    assert abs(float(np.median(volts)) - 2.5) < 0.05
    table = during[-1]
    assert table["type"] == "samples" and "daq" not in table and table["table"]["t"]
    warm = [e for e in seen if e["type"] == "plot_reset" and e["id"].startswith("s001")]
    assert [w["label"] for w in warm] == [AFTER_STEP] and warm[0]["live"] is False
