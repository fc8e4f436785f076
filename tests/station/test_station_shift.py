"""A whole shift at the station in a real Chromium, by keyboard where an operator would.

The unit's serial is typed (as a barcode scanner does: characters, then Enter), the procedure
picked by its title, run on the twin; the verdict table names every quantity as the quantity
registry does, the signed report verifies with ``aatest verify`` and its PDF link resolves. A
long streamed record shows points arriving before its step ends; a third run is aborted with
Escape and Enter, and the controls follow the run's state. The unit page lists the runs.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from station_process import Station, running_station, shot

from aatest.bundle import signing

pytestmark = pytest.mark.browser

SERIAL = "SN-SHIFT-0042"
PASSPHRASE = "correct horse battery staple"  # test key only; the station reads it from env


@pytest.fixture
def signed(tmp_path: Path) -> Iterator[tuple[Station, Path, str]]:
    """A station signing with a passphrase-protected key, its own records store."""
    key = tmp_path / "keys" / "lab.key"
    key.parent.mkdir()
    signing.generate_keypair(key, PASSPHRASE)
    records = f"sqlite:///{tmp_path / 'records.db'}"
    env = {"AATEST_SIGNING_PASSPHRASE": PASSPHRASE, "AATEST_RECORDS": records}
    with running_station(tmp_path, "--sign-key", str(key), env=env) as station:
        yield station, key, records


def _focused(page: Any) -> str:
    return str(page.evaluate("document.activeElement && document.activeElement.id"))


def _run_named(station: Station, procedure: str) -> Path:
    (run,) = [d for d in station.runs.iterdir() if procedure in d.name
              and (d / "run_state.json").is_file()]
    return run


def _controls(page: Any) -> dict[str, bool]:
    return {"start_enabled": page.locator("#start").is_enabled(),
            "abort_visible": page.locator("#abort").is_visible()}


def test_a_shift_serial_title_live_verdict_signed_report_abort_unit_page(
    signed: tuple[Station, Path, str], page: Any
) -> None:
    station, key, records = signed
    _serial_by_keyboard(station, page)
    _signed_scale_factor_with_pdf(station, page, key, records)
    _live_long_rest(page)
    _abort_by_keyboard(page)
    _unit_page(station, page)


def _serial_by_keyboard(station: Station, page: Any) -> None:
    page.goto(station.url)
    page.wait_for_function("document.getElementById('role').textContent.includes('control')")
    page.wait_for_selector("#procedure option", state="attached")
    assert _focused(page) == "serial"  # ready for the scanner on load
    assert "reports signed" in page.locator("#signing").inner_text()
    page.keyboard.type(SERIAL)
    page.keyboard.press("Enter")  # the scanner's Enter moves on to the procedure
    assert _focused(page) == "procedure"
    titles = page.locator("#procedure option").all_inner_texts()
    assert "scale-factor" in titles and not any(".yaml" in t for t in titles)
    groups = page.locator("#procedure optgroup").evaluate_all("gs => gs.map(g => g.label)")
    assert groups[:2] == ["Shipped with aatest", "The lab's procedures"]


def _signed_scale_factor_with_pdf(station: Station, page: Any, key: Path, records: str) -> None:
    # 1. the scale factor, picked by title, with its PDF; keyboard only from here
    page.select_option("#procedure", label="quick-scale-factor")
    page.locator("#pdf").check()
    page.focus("#procedure")
    page.keyboard.press("Enter")  # validates and moves to Start
    page.wait_for_selector("#plan[data-procedure='lab/quick-scale-factor.yaml'] tbody tr")
    # the plan may already be there from the validation the selection started (a fast
    # validate answers before Enter is pressed): Enter's own validation then moves the focus
    page.wait_for_function("document.activeElement && document.activeElement.id === 'start'")
    assert _focused(page) == "start"
    # the focus reached by keyboard is visible: the station's 3 px outline
    outline = page.evaluate("getComputedStyle(document.activeElement).outlineWidth")
    assert outline == "3px"
    page.keyboard.press("Enter")
    # the twin may pass through "running" within one frame: any state after the start will do
    page.wait_for_function("['running', 'analysing', 'finished'].includes(state.runState)")
    _controls_follow_the_state(page)  # the twin may be analysing already: read both at once
    page.wait_for_selector("#verdict:has-text('Verdict')", timeout=180_000)
    assert _controls(page) == {"start_enabled": True, "abort_visible": False}
    shot(page, "shift-1-verdict")
    verdicts = page.locator("#verdicts").inner_text()
    assert "Scale-factor deviation from nominal" in verdicts  # the registry's name
    assert "scale_factor" not in verdicts and "±" in verdicts and " %" in verdicts
    assert page.locator("#run-unit").inner_text() == f"sr207 {SERIAL}"
    run = _run_named(station, "quick-scale-factor")
    results = json.loads((run / "results.json").read_text())
    assert results["metadata"]["sensor"]["serial"] == SERIAL  # as run --serial names it
    links = page.locator("#links a").all_inner_texts()
    assert sorted(links) == ["report.html", "report.pdf", "results.json"]
    pdf = page.request.get(station.url + page.locator("#links a[href$='report.pdf']")
                           .get_attribute("href"))
    assert pdf.ok and pdf.headers["content-type"] == "application/pdf"
    assert pdf.body()[:5] == b"%PDF-"
    verified = subprocess.run(
        [sys.executable, "-m", "aatest.cli", "verify", str(run / "report.html"),
         "--public-key", f"{key}.pub", "--records", records],
        capture_output=True, text=True, env={**os.environ, "AATEST_RECORDS": records},
        timeout=120, check=False)
    assert verified.returncode == 0, verified.stderr
    assert "signature valid" in verified.stdout


def _live_long_rest(page: Any) -> None:
    # 2. a long streamed rest: points arrive while its step runs; no PDF this time
    page.select_option("#procedure", label="quick-long-static")
    page.locator("#pdf").uncheck()
    page.click("#start")
    page.wait_for_selector("#plot-label[data-live='yes']", timeout=120_000)
    shot(page, "shift-2-live")
    page.wait_for_selector("#verdict", state="visible", timeout=180_000)
    log = page.evaluate("state.log")
    rest = next(e["id"] for e in log if e["type"] == "step" and e["id"].startswith("s002"))
    done_at = next(i for i, e in enumerate(log) if e == {**e, "type": "step", "id": rest,
                                                          "state": "done"})
    live = [e["received"] for e in log[:done_at] if e["type"] == "samples" and e["live"]]
    # 600 s streamed in chunks of at least 60 s (whole generation blocks): between two and
    # ten deliveries, each adding points, all before the step ends
    assert 2 <= len(live) <= 10
    assert all(b > a for a, b in itertools.pairwise(live))
    assert page.locator("#links a").all_inner_texts() == ["report.html", "results.json"]


def _abort_by_keyboard(page: Any) -> None:
    # 3. a run aborted by keyboard: Escape brings the focus to Abort, Enter presses it; the run
    # is held at the operator's check before its second step (the twin would finish first)
    page.select_option("#procedure", label="quick-sine-hold")
    page.click("#start")
    page.wait_for_selector("#steps li[data-id^='s001-sine'][data-state='done']", timeout=120_000)
    page.wait_for_selector("#prompt-step:has-text('s002-sine')")
    shot(page, "shift-3-running")
    assert _controls(page) == {"start_enabled": False, "abort_visible": True}, (
        page.locator("#run-state").inner_text(), page.locator("#notice").inner_text())
    page.keyboard.press("Escape")
    assert _focused(page) == "abort"
    page.keyboard.press("Enter")
    page.wait_for_selector("#stopped", state="visible")
    shot(page, "shift-3-aborted")
    assert "aborted" in page.locator("#stopped-text").inner_text()
    assert _controls(page) == {"start_enabled": True, "abort_visible": False}
    assert page.locator("#resume").is_enabled()


def _controls_follow_the_state(page: Any) -> None:
    """Start is disabled while a run holds the rig, Abort offered until it analyses."""
    seen = page.evaluate("({state: state.runState, start: !document.getElementById('start')"
                         ".disabled, abort: !document.getElementById('abort').hidden})")
    busy = seen["state"] in ("starting", "running", "waiting for the operator", "analysing")
    assert seen["start"] is not busy, seen
    assert seen["abort"] is (busy and seen["state"] != "analysing"), seen


def _unit_page(station: Station, page: Any) -> None:
    page.wait_for_selector("#history a.unit-link")
    assert page.locator("#history a.unit-link").first.get_attribute("href") == f"/units/{SERIAL}"
    # the unit's page: both finished runs, newest last, with their files
    page.click("#unit-link")
    page.wait_for_selector("#records tbody tr")
    assert page.url == f"{station.url}/units/{SERIAL}"
    rows = page.locator("#records tbody tr")
    assert rows.count() == 2
    assert [r.split("\t")[2] for r in rows.all_inner_texts()] == [
        "quick-scale-factor", "quick-long-static"]
    assert "Scale factor" in rows.nth(0).inner_text()
    assert page.locator("#trend canvas").count() == 1
    report = rows.nth(0).locator("a[href$='report.html']").get_attribute("href")
    assert page.request.get(station.url + report).ok
    shot(page, "shift-unit-page")


def test_unnamed_unit_page_and_bad_serial_are_refused(station: Station, page: Any) -> None:
    response = page.request.get(station.url + "/api/units/%20")
    assert response.status == 404 and "serial" in response.json()["problems"][0]
