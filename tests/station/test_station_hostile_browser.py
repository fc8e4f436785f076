"""Hostile pages in a real Chromium: framing the station and DNS rebinding are refused.

The attacker's site is a second web server on this machine (another origin; a site on the
internet would in addition meet Chromium's local-network restrictions, which would hide whether
the station's own headers refuse the frame); DNS rebinding is reproduced with Chromium's host
resolver rules, which make ``rebind.evil.example`` resolve to 127.0.0.1 exactly as a rebinding
DNS server would.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest
from station_process import CHROMIUM, Station

pytestmark = pytest.mark.browser

REBOUND = "rebind.evil.example"


@pytest.fixture
def attacker(station: Station) -> Iterator[str]:
    """Another origin on this machine: ``/`` frames the station and ``/framable``, a plain page."""
    pages = {
        "/": (f'<title>attacker</title><iframe name="station" src="{station.url}/"></iframe>'
              '<iframe name="control" src="/framable"></iframe>'),
        "/framable": "<title>framable</title>framable page",
    }

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = pages.get(self.path, "").encode()
            self.send_response(200 if self.path in pages else 404)
            self.send_header("content-type", "text/html")
            self.send_header("content-length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://localhost:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def chromium() -> Iterator[Any]:
    """Headless Chromium resolving the rebinding name to this machine."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    if not Path(CHROMIUM).exists():
        pytest.skip("no Chromium installed (apt-get install chromium); browser test skipped")
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=CHROMIUM, headless=True,
            args=[f"--host-resolver-rules=MAP {REBOUND} 127.0.0.1"],
        )
        yield browser
        browser.close()


def test_a_page_framing_the_station_is_refused(
    station: Station, chromium: Any, attacker: str
) -> None:
    page = chromium.new_page()
    page.goto(attacker)  # waits for the load event, which waits for both frames
    control = page.locator("iframe[name=control]").element_handle().content_frame()
    framed = page.locator("iframe[name=station]").element_handle().content_frame()
    assert control is not None and "framable" in control.content()  # framing works here
    assert framed is not None and not framed.url.startswith(station.url)
    assert "aatest station" not in framed.content()
    own = chromium.new_page()
    own.goto(station.url)  # the station itself still opens in its own tab, under its policy:
    assert own.title() == "aatest station"
    own.wait_for_selector("#role:has-text('control')")  # its websocket is connected


def test_dns_rebinding_page_cannot_reach_the_station(station: Station, chromium: Any) -> None:
    port = station.url.rsplit(":", 1)[1]
    page = chromium.new_page()
    response = page.goto(f"http://{REBOUND}:{port}/")
    assert response is not None and response.status == 403
    outcome = page.evaluate("""async () => {
        const runs = (await fetch("/api/runs")).status;
        const upload = (await fetch("/api/upload?name=x.yaml",
                                    {method: "POST", body: "procedure: x"})).status;
        const socket = await new Promise((resolve) => {
            const ws = new WebSocket(`ws://${location.host}/ws`);
            const seen = [];
            ws.onmessage = (event) => seen.push(JSON.parse(event.data).type);
            ws.onclose = () => resolve(seen);
            ws.onerror = () => {};
            setTimeout(() => resolve(["timeout", ...seen]), 10000);
        });
        return {runs, upload, socket};
    }""")
    assert outcome == {"runs": 403, "upload": 403, "socket": []}
    assert not (station.runs / ".station" / "uploads").exists()
