"""Headless Chromium screenshot: the certificate renders as a page with its plots.

Uses Debian's ``/usr/bin/chromium`` when installed; skipped with a clear message otherwise.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

from aatest.plugins.report.html import CalibrationCertificate

CHROMIUM = Path("/usr/bin/chromium")

pytestmark = pytest.mark.browser


def _chromium() -> str:
    found = str(CHROMIUM) if CHROMIUM.exists() else shutil.which("chromium")
    if not found:
        pytest.skip("headless browser test skipped: Debian chromium is not installed at "
                    "/usr/bin/chromium (apt-get install chromium to run it)")
    return found


def test_certificate_screenshot_shows_plots(results: dict[str, Any], run_dir: Path,
                                             tmp_path: Path) -> None:
    browser = _chromium()
    report = CalibrationCertificate().render(results, run_dir, None)
    shot = tmp_path / "certificate.png"
    command = [
        browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run",
        f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
        "--window-size=1200,6000", report.resolve().as_uri(),
    ]
    subprocess.run(command, check=True, capture_output=True, timeout=120)
    image = imread(shot)[..., :3]
    assert image.shape[0] >= 5900 and image.shape[1] >= 1100
    ink = np.mean(image, axis=2) < 0.9  # anything not (nearly) white
    assert ink.mean() > 0.02, "page looks blank"  # the §7.8 sections come before the plots
    # plot lines are matplotlib's C0 blue (#1f77b4); nothing else on the page uses it
    c0 = np.array([0x1F, 0x77, 0xB4]) / 255.0
    on_curve = np.all(np.abs(image.reshape(-1, 3) - c0) < 0.08, axis=1)
    assert on_curve.sum() > 500, "no plot lines (C0 blue) in the screenshot"
