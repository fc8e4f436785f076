"""PDF copies of reports, printed by headless Chromium (Debian's ``chromium`` package).

The HTML report stays the primary document (self-contained, inline SVG); the PDF is the same
page printed, for labs that file certificates as PDF. It joins the signed bundle when present.

Every printed page carries the certificate's identification and "page x of y" (ISO/IEC 17025
§7.8.2.1 c). Chromium's CSS paged media has no ``counter(pages)``, so the footer is Chromium's
own print header/footer template (``pageNumber``/``totalPages``), driven through Playwright on
the installed browser (no browser download) when Playwright is importable. Without it, or when
it cannot run here (e.g. inside an asyncio loop), the browser's command line prints the page
with its built-in footer, which also numbers the pages (``x/y``, with the file's URL).
"""

from __future__ import annotations

import html
import logging
import shutil
import subprocess
import tempfile
from pathlib import Path

from aatest.engine.errors import PluginError

log = logging.getLogger("aatest.report.pdf")

PDF_NAME = "report.pdf"
_BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: flags for a closed network: no background connections, no first-run, no sandbox as root
_LAUNCH_FLAGS = (
    "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
)
_FLAGS = ("--headless", *_LAUNCH_FLAGS)
#: how a page names the document it belongs to (the certificate template sets it)
_IDENT_SCRIPT = ("() => (document.querySelector('meta[name=\"aatest-certificate\"]') || {})"
                 ".content || document.title")


def find_browser() -> str | None:
    """Path of a Chromium-family browser, if one is installed."""
    for name in _BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    return None


def footer_template(identification: str) -> str:
    """Chromium's print footer: the document's identification and "page x of y"."""
    return ('<div style="font-family: \'DejaVu Sans\', Arial, sans-serif; font-size: 8px; '
            'color: #333; width: 100%; margin: 0 12mm; display: flex; '
            'justify-content: space-between;">'
            f'<span>{html.escape(identification)}</span>'
            '<span>page <span class="pageNumber"></span> of <span class="totalPages"></span>'
            '</span></div>')


def _print_with_playwright(browser: str, html_path: Path, pdf_path: Path, timeout_s: float
                           ) -> bool:
    """Print through Playwright with the footer template; False when Playwright cannot run."""
    try:
        from playwright.sync_api import Error, sync_playwright
    except ImportError:
        return False
    try:
        with sync_playwright() as driver:
            chromium = driver.chromium.launch(executable_path=browser, args=list(_LAUNCH_FLAGS),
                                              timeout=timeout_s * 1000)
            try:
                page = chromium.new_page()
                page.goto(html_path.resolve().as_uri(), timeout=timeout_s * 1000)
                identification = str(page.evaluate(_IDENT_SCRIPT))
                page.pdf(path=str(pdf_path), format="A4", print_background=True,
                         display_header_footer=True, header_template="<span></span>",
                         footer_template=footer_template(identification),
                         # A4 margins leaving room for the footer (printed inside the margin)
                         margin={"top": "14mm", "bottom": "16mm", "left": "12mm",
                                 "right": "12mm"})
            finally:
                chromium.close()
    except Error as exc:
        log.warning("Playwright could not print %s (%s); using the browser's command line",
                    html_path.name, exc)
        return False
    return True


def _print_with_command_line(browser: str, html_path: Path, pdf_path: Path, timeout_s: float
                             ) -> None:
    with tempfile.TemporaryDirectory(prefix="aatest-chromium-") as profile:
        cmd = [browser, *_FLAGS, f"--user-data-dir={profile}", f"--print-to-pdf={pdf_path}",
               html_path.resolve().as_uri()]
        try:
            subprocess.run(cmd, capture_output=True, timeout=timeout_s, check=False,
                           stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired as exc:
            raise PluginError(
                f"{browser} did not print {html_path.name} within {timeout_s:g} s") from exc


def render_pdf(html_path: Path, timeout_s: float = 120.0) -> Path:
    """Print ``html_path`` to ``report.pdf`` beside it.

    Raises
    ------
    PluginError
        When no browser is installed or it produced no PDF.
    """
    browser = find_browser()
    if browser is None:
        raise PluginError("PDF reports need Chromium: install Debian's 'chromium' package")
    pdf_path = html_path.with_name(PDF_NAME)
    if not _print_with_playwright(browser, html_path, pdf_path, timeout_s):
        _print_with_command_line(browser, html_path, pdf_path, timeout_s)
    if not pdf_path.is_file() or pdf_path.read_bytes()[:5] != b"%PDF-":
        raise PluginError(f"{browser} produced no PDF for {html_path}")
    return pdf_path
