"""A real station (``aatest station`` in a subprocess) and a headless Chromium driving it.

The browser is Debian's Chromium driven by Playwright (no browser download); where neither is
installed the browser tests skip with a message. Screenshots of every state go to
``test-artifacts/station/`` (ignored by git) and their paths are printed. The helpers behind
these fixtures live in :mod:`station_process`.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from station_process import CHROMIUM, Station, running_station


@pytest.fixture
def station(tmp_path: Path) -> Iterator[Station]:
    """``aatest station`` on a free loopback port with the reduced test procedures as lab."""
    with running_station(tmp_path) as running:
        yield running


@pytest.fixture
def page(request: pytest.FixtureRequest) -> Iterator[Any]:
    """A headless Chromium page (Playwright on the system Chromium)."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    if not Path(CHROMIUM).exists():
        pytest.skip("no Chromium installed (apt-get install chromium); browser test skipped")
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True)
        # the page's Content-Security-Policy forbids eval, which Playwright's string
        # predicates (wait_for_function) use; the test bypasses it, the page keeps it
        tab = browser.new_page(viewport={"width": 1100, "height": 1400}, bypass_csp=True)
        tab.set_default_timeout(60_000)
        yield tab
        browser.close()
