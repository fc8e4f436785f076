"""The certificates looked over in Chromium: no number broken across lines, no cell overflowing.

Every shipped procedure (its short variant in ``tests/results/data``: the same analyses and
report template) is run on the twin with its PDF, and its ``report.html`` opened in headless
Chromium twice: on screen (1100 px) and as printed (print media, 703 px: A4's 210 mm less the
PDF's 12 mm margins at 96 px/in). The page itself is measured in the browser: a table cell
whose content is wider than the cell (``scrollWidth > clientWidth``), a table wider than the
page, and a number whose glyphs lie on more than one line (a ``Range`` over the number with
client rectangles at two heights: ``9.62e-``/``06``). Screenshots of each go to
``test-artifacts/certificates/`` for a person to look over.
"""

from __future__ import annotations

import logging
import logging.handlers
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from station_process import CHROMIUM

from aatest.engine.run.session import run

pytestmark = pytest.mark.browser

DATA = Path(__file__).resolve().parents[1] / "results" / "data"
ARTIFACTS = Path(__file__).parents[2] / "test-artifacts" / "certificates"
PROCEDURES = ("long-static-drift", "pivoted-misalignment", "scale-factor",
              "static-multi-position", "stepped-sine-frequency-response", "temperature-steps")
#: (media, viewport width in px): the screen, and A4 less the PDF's 2 × 12 mm side margins
LAYOUTS = (("screen", 1100), ("print", 703))

#: measured in the page: overflowing cells and tables, numbers broken across lines
MEASURE = (Path(__file__).parent / "measure_layout.js").read_text(encoding="utf-8")


def _chromium_or_skip() -> Any:
    """Playwright's sync API, where it and Debian's Chromium are installed; else skip."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    if not Path(CHROMIUM).exists():
        pytest.skip("no Chromium installed (apt-get install chromium); browser test skipped")
    return sync_api


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Path]]:
    """Every shipped procedure's short variant run on the twin with its PDF printed as
    ``aatest run --pdf`` prints it: through Playwright, with the identification footer.

    Why before :func:`browser`: a Playwright session open in this thread makes the run's own
    Playwright print refuse ("Sync API inside the asyncio loop"), and the PDF would come from
    the browser's command line instead (no footer), the fallback rather than the product.
    """
    _chromium_or_skip()  # skipped before the runs, which need the same Chromium
    root = tmp_path_factory.mktemp("certificates")
    # the PDF printer's warnings (a print that fell back to the command line), every one kept
    fallbacks = logging.handlers.BufferingHandler(capacity=sys.maxsize)
    fallbacks.setLevel(logging.WARNING)
    pdf_log = logging.getLogger("aatest.report.pdf")
    pdf_log.addHandler(fallbacks)
    try:
        done = {}
        for name in PROCEDURES:
            run_dir, _results = run(DATA / f"{name}.yaml", None, root / name, False, 7, None,
                                    show_progress=False, confirm_prompts="auto", pdf=True)
            done[name] = run_dir
    finally:
        pdf_log.removeHandler(fallbacks)
    assert [r.getMessage() for r in fallbacks.buffer] == [], \
        "a PDF was not printed through Playwright"
    yield done


@pytest.fixture(scope="module")
def browser(reports: dict[str, Path]) -> Iterator[Any]:
    """Headless Debian Chromium through Playwright (skipped where neither is installed),
    opened once the module's runs have printed their PDFs (:func:`reports`)."""
    with _chromium_or_skip().sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=CHROMIUM, headless=True)
        yield chromium
        chromium.close()


def measure(browser: Any, url: str, media: str, width: int, shot: Path | None) -> dict[str, Any]:
    """The page at ``url`` laid out for ``media`` at ``width`` px, measured (and kept)."""
    page = browser.new_page(viewport={"width": width, "height": 1000})
    try:
        page.emulate_media(media=media)
        page.goto(url)
        found: dict[str, Any] = page.evaluate(MEASURE)
        if shot is not None:
            shot.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(shot), full_page=True)
            print(f"screenshot: {shot}")
        return found
    finally:
        page.close()


def test_the_measure_finds_a_broken_number_and_an_overflowing_cell(
    browser: Any, tmp_path: Path
) -> None:
    """The check can fail: a narrow cell wraps ``9.62e-06`` after ``e-``; a clipped one
    overflows; the same number kept on one line (``nowrap``) in a wide cell is neither."""
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<table><tr><td style='width:3em;max-width:3em'>u 9.62e-06</td>"
        "<td style='width:2em;max-width:2em;overflow:hidden;white-space:nowrap'>"
        "1234567.891</td><td style='white-space:nowrap'>SHA-256 4.01e-03</td></tr></table>",
        encoding="utf-8")
    found = measure(browser, bad.as_uri(), "screen", 400, None)
    assert [b.split(" in ")[0] for b in found["broken"]] == ["9.62e-06"]
    assert found["overflow"] == ["cell: 1234567.891"]


@pytest.mark.parametrize("name", PROCEDURES, ids=PROCEDURES)
def test_certificate_in_chromium_keeps_numbers_whole_and_cells_inside(
    name: str, reports: dict[str, Path], browser: Any
) -> None:
    run_dir = reports[name]
    assert (run_dir / "report.pdf").read_bytes()[:5] == b"%PDF-"
    for media, width in LAYOUTS:
        found = measure(browser, (run_dir / "report.html").as_uri(), media, width,
                        ARTIFACTS / f"{name}-{media}.png")
        assert found["broken"] == [], f"{name} ({media}): numbers broken across lines"
        assert found["overflow"] == [], f"{name} ({media}): content wider than its box"
