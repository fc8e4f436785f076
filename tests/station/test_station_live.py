"""What the page is sent while a long static record streams: its chunks, before the step ends.

``aatest run`` of a 600 s rest on the twin (longer than the simulated table's log, so the DAQ
streams it) with the station's observer: every chunk is published as it arrives, plotted on
one time axis from the record's start, and the table's snapshot log follows the last chunk
without resetting the plot. The table's polled status is published while each step runs, on
the twin's lab clock. A short step before it is shown at once when its loggers deliver it.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from aatest.engine.run.events import AbortFlag, RunEvents
from aatest.engine.run.session import run
from aatest.station.live import AFTER_STEP, CHUNK_POINTS, LIVE, PLOT_POINTS, StationObserver

PROCEDURE = Path(__file__).parent / "data" / "quick-long-static.yaml"
REST_S = 600.0  # the procedure's streamed record, s


@pytest.fixture(scope="module")
def published(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    """Every message the station's observer published during one run of the procedure."""
    seen: list[dict[str, Any]] = []
    observer = StationObserver(seen.append, AbortFlag())
    run(PROCEDURE, None, tmp_path_factory.mktemp("live") / "run", False, 3, None,
        show_progress=False, events=RunEvents(observer))
    return seen


def test_streamed_chunks_are_published_before_the_step_ends(
        published: list[dict[str, Any]]) -> None:
    seen = published
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
    # the short step's logs in one message, right after its reset (no replay at page pace)
    after = seen[seen.index(warm[0]) + 1]
    assert after["type"] == "samples" and len(after["daq"]["t"]) == PLOT_POINTS
    assert len(after["table"]["t"]) == PLOT_POINTS


def test_table_status_is_published_while_the_step_runs(published: list[dict[str, Any]]) -> None:
    seen = published
    rest = next(e["id"] for e in seen if e["type"] == "step" and e["id"].startswith("s002"))
    started = seen.index({"type": "step", "id": rest, "state": "running",
                          "motion": next(e["motion"] for e in seen if e.get("id") == rest
                                         and e.get("state") == "running")})
    done = seen.index({"type": "step", "id": rest, "state": "done"})
    points = [e for e in seen[started:done] if e["type"] == "table_live"]
    # the twin's lab clock moves on by events: positioning, the settle, each generated block
    # of the 600 s record (131 072 samples ≈ 131 s at 1 kHz: 5 blocks), the return
    assert len(points) >= 3 and {p["id"] for p in points} == {rest}
    t = [p["t"] for p in points]
    assert t[0] == 0.0 and all(b > a for a, b in itertools.pairwise(t))
    assert REST_S < t[-1] < REST_S + 10.0  # record, settle and return, on the table's clock
    # the table at rest at 0° through the step: the realistic rig's motor line moves it by
    # less than 1e-3° and 0.1 °/s (four 3 °/s² tones near 35 Hz)
    assert all(abs(p["position_deg"]) < 1e-3 and abs(p["rate_dps"]) < 0.1 for p in points)
    assert {p["axis"] for p in points} == {"inner"} and points[0]["clock"] == "controller"
    assert not [e for e in seen if e["type"] == "table_live_off"]
