"""The PDF copy of a report is printed by Chromium and joins the signed bundle."""

from pathlib import Path

import pytest

from aatest.bundle import signing
from aatest.engine.run import session
from aatest.plugins.report.pdf import find_browser

QUICK = Path(__file__).parents[2] / "data" / "procedures" / "quick-sine-3-steps.yaml"


@pytest.mark.skipif(find_browser() is None,
                    reason="PDF test skipped: Debian chromium not installed")
def test_pdf_is_signed_and_tampering_it_is_detected(tmp_path: Path) -> None:
    key = tmp_path / "lab.key"
    signing.generate_keypair(key)
    run_dir, _ = session.run(QUICK, None, tmp_path / "run", False, 1, key, show_progress=False,
                             pdf=True)
    pdf = run_dir / "report.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 10_000
    trusted = [signing.trusted_public_key(signing.public_key_path(key))]
    assert signing.verify_bundle(run_dir / "report.html", trusted).ok

    data = bytearray(pdf.read_bytes())
    data[len(data) // 2] ^= 0x01
    pdf.write_bytes(bytes(data))
    result = signing.verify_bundle(run_dir / "report.html", trusted)
    assert not result.ok and any(r.startswith("report.pdf: modified") for r in result.reasons)

    # re-rendering without --pdf drops the stale PDF rather than signing around it
    session.report(run_dir, None, key)
    assert not pdf.exists() and signing.verify_bundle(run_dir / "report.html", trusted).ok
