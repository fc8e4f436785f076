"""PDF copies of reports, printed by headless Chromium (Debian's ``chromium`` package).

The HTML report stays the primary document (self-contained, inline SVG); the PDF is the same
page printed, for labs that file certificates as PDF. It joins the signed bundle when present.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from aatest.engine.errors import PluginError

PDF_NAME = "report.pdf"
_BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: flags for a closed network: no background connections, no first-run, no sandbox as root
_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run", "--no-pdf-header-footer",
)


def find_browser() -> str | None:
    """Path of a Chromium-family browser, if one is installed."""
    for name in _BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    return None


def render_pdf(html_path: Path, timeout_s: float = 120.0) -> Path:
    """Print ``html_path`` to ``report.pdf`` beside it; raise PluginError when that is impossible."""
    browser = find_browser()
    if browser is None:
        raise PluginError("PDF reports need Chromium: install Debian's 'chromium' package")
    pdf_path = html_path.with_name(PDF_NAME)
    with tempfile.TemporaryDirectory(prefix="aatest-chromium-") as profile:
        cmd = [browser, *_FLAGS, f"--user-data-dir={profile}", f"--print-to-pdf={pdf_path}",
               html_path.resolve().as_uri()]
        try:
            subprocess.run(cmd, capture_output=True, timeout=timeout_s, check=False,
                           stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired as exc:
            raise PluginError(f"{browser} did not print {html_path.name} within {timeout_s:g} s") from exc
    if not pdf_path.is_file() or pdf_path.read_bytes()[:5] != b"%PDF-":
        raise PluginError(f"{browser} produced no PDF for {html_path}")
    return pdf_path
