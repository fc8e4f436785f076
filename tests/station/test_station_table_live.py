"""The table's live position and rate on the station's page, in a real Chromium.

On the twin, the table's status is polled while each step runs and plotted as it arrives: during
the ten-minute streamed rest of ``quick-long-static`` the page counts table readings rising
before the step is marked done (the twin's lab clock moves on by the blocks it generates).
A vendor's table whose plugin has no ``status()`` (the example package's single-axis table)
keeps working, and the page says that this table reports no live status. Screenshots go to
``test-artifacts/station/`` (``table-live-rest-done.png``, the page as the rest's step ends, is the
one ``docs/station.png`` is taken from).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest
from station_process import Station, running_station, shot

pytestmark = [pytest.mark.browser, pytest.mark.slow]  # a station and a browser: ≈ 1 min each

EXAMPLE_SRC = Path(__file__).parents[2] / "examples" / "vendor-plugin" / "src"
NO_STATUS = "this table reports no live status"


def _start(page: Any, station: Station, title: str) -> None:
    page.goto(station.url)
    page.wait_for_function("document.getElementById('role').textContent.includes('control')")
    page.wait_for_selector("#procedure option", state="attached")
    page.select_option("#procedure", label=title)
    page.click("#start")
    # the twin may pass through "running" within one frame: any state after the start will do
    page.wait_for_function("['running', 'analysing', 'finished'].includes(state.runState)",
                           timeout=120_000)


def test_table_readings_arrive_while_the_long_rest_runs(station: Station, page: Any) -> None:
    _start(page, station, "quick-long-static")
    # the rest is running and its table readings are on the page: keep that state
    page.wait_for_function(
        "(() => { const s = state.steps.get(state.tableLive && state.tableLive.id);"
        " return s && s.id.startsWith('s002') && s.state === 'running'"
        " && state.tableLive.data[0].length >= 2; })()", timeout=180_000)
    shot(page, "table-live-rest")
    page.wait_for_selector("#steps li[data-id^='s002'][data-state='done']", timeout=300_000)
    shot(page, "table-live-rest-done")  # the whole rest: table readings and sensor chunks
    page.wait_for_selector("#verdict", state="visible", timeout=300_000)
    log = page.evaluate("state.log")
    rest = next(e["id"] for e in log if e["type"] == "step" and e["id"].startswith("s002"))
    began = next(i for i, e in enumerate(log)
                 if e["type"] == "step" and e["id"] == rest and e["state"] == "running")
    ended = next(i for i, e in enumerate(log)
                 if e["type"] == "step" and e["id"] == rest and e["state"] == "done")
    counts = [e["points"] for e in log[began:ended] if e["type"] == "table_live"]
    # readings of this step, the count rising before the step is done (at least the one
    # before the motion and one per generated block of the 600 s record)
    assert len(counts) >= 3 and counts == sorted(counts) and counts[-1] > counts[0]
    assert all(e["id"] == rest for e in log[began:ended] if e["type"] == "table_live")
    assert page.locator("#table-live-note").get_attribute("data-live") == "yes"
    assert int(page.locator("#table-live-count").inner_text()) >= counts[-1]
    assert page.locator("#plot-table-live canvas").count() == 1
    title = page.locator("#plot-table-live .u-title").inner_text()
    assert title == "table now (inner axis, polled status)"


def _vendor_site(tmp_path: Path) -> Path:
    """The example vendor package declared as an installed distribution (its entry point in a
    ``.dist-info``), as pip would install it; its source is put on the path beside it."""
    site = tmp_path / "site"
    info = site / "aatest_vendor_example-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: aatest-vendor-example\n"
                                   "Version: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "[aatest.turntables]\n"
        "acme-single-axis = aatest_vendor_example.turntable:SingleAxisTable\n")
    return site


def test_a_table_without_status_is_named_on_the_page(tmp_path: Path, page: Any) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: acme-single-axis}\ndaq: {plugin: sim}\n"
                   "chamber: {plugin: none}\n")
    path = os.pathsep.join(p for p in (str(_vendor_site(tmp_path)), str(EXAMPLE_SRC),
                                       os.environ.get("PYTHONPATH", "")) if p)
    with running_station(tmp_path, "--rig", str(rig), env={"PYTHONPATH": path}) as station:
        _start(page, station, "quick-sine-3-steps")
        note = page.locator("#table-live-note[data-live='no']")
        note.wait_for(timeout=120_000)
        assert note.inner_text() == f"Live table: {NO_STATUS}."
        page.wait_for_selector("#steps li[data-id^='s001-sine'][data-state='done']",
                               timeout=120_000)
        shot(page, "table-live-none")
        # the vendor's table moved the step all the same, and no reading was invented
        assert page.locator("#table-live-count").inner_text() == "0"
        assert page.locator("#plot-table-live canvas").count() == 0
        page.wait_for_selector("#verdict", state="visible", timeout=300_000)
        assert page.locator("#table-live-count").inner_text() == "0"
