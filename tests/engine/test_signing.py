"""Ed25519 bundle signatures: every byte of the bundle and the signing key are checked."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest

from aatest.engine.errors import InputError
from aatest.engine.run.signing import (
    file_sha256,
    generate_keypair,
    key_fingerprint,
    load_private_key,
    public_key_path,
    sign_bundle,
    signature_path,
    verify_bundle,
)


@pytest.fixture
def key_path(tmp_path: Path) -> Path:
    path = tmp_path / "keys" / "lab.key"
    path.parent.mkdir()
    generate_keypair(path)
    return path


@pytest.fixture
def bundle(tmp_path: Path, key_path: Path) -> Path:
    """A signed run directory whose report prints the signing key's fingerprint."""
    run = tmp_path / "run"
    run.mkdir()
    fingerprint = key_fingerprint(load_private_key(key_path))
    report = run / "report.html"
    report.write_text(
        f'<html><head><meta name="aatest-key-fingerprint" content="{fingerprint}"></head>'
        "<body>scale factor 0.004014 V/(°/s²)</body></html>"
    )
    (run / "results.json").write_text(json.dumps({"signature": {"fingerprint": fingerprint}}))
    (run / "recording.mcap").write_bytes(bytes(range(256)) * 64)
    sign_bundle(report, load_private_key(key_path))
    return report


def _flip_byte(path: Path, index: int) -> None:
    data = bytearray(path.read_bytes())
    data[index] ^= 0x01
    path.write_bytes(bytes(data))


def test_keygen_writes_private_0600_and_public(key_path: Path) -> None:
    assert stat.S_IMODE(key_path.stat().st_mode) == 0o600
    assert public_key_path(key_path).read_text().startswith("-----BEGIN PUBLIC KEY-----")
    with pytest.raises(InputError, match="refusing to overwrite"):
        generate_keypair(key_path)


def test_passphrase_protects_key(tmp_path: Path) -> None:
    path = tmp_path / "p.key"
    fingerprint = generate_keypair(path, passphrase="correct horse")
    assert b"ENCRYPTED" in path.read_bytes()
    assert key_fingerprint(load_private_key(path, "correct horse")) == fingerprint
    assert len(fingerprint) == 64
    with pytest.raises(InputError, match="passphrase"):
        load_private_key(path, "wrong")
    with pytest.raises(InputError, match="passphrase"):
        load_private_key(path)


def test_untouched_bundle_verifies(bundle: Path, key_path: Path) -> None:
    result = verify_bundle(bundle)
    assert result.ok, result.reasons
    assert verify_bundle(bundle, public_key_path(key_path)).ok
    signed = json.loads(signature_path(bundle).read_text())["files"]
    assert set(signed) == {"report.html", "results.json", "recording.mcap"}


@pytest.mark.parametrize(
    ("name", "index"),
    [("report.html", 10), ("results.json", 3), ("recording.mcap", 0), ("recording.mcap", -1)],
    ids=["report", "results", "recording-first", "recording-last"],
)
def test_one_changed_byte_is_named(bundle: Path, name: str, index: int) -> None:
    _flip_byte(bundle.with_name(name), index)
    result = verify_bundle(bundle)
    assert not result.ok
    assert any(r.startswith(f"{name}: modified") for r in result.reasons), result.reasons


def test_missing_signature_and_missing_member(bundle: Path) -> None:
    bundle.with_name("recording.mcap").unlink()
    assert verify_bundle(bundle).reasons == ["recording.mcap: missing (it was signed)"]
    signature_path(bundle).unlink()
    result = verify_bundle(bundle)
    assert not result.ok and result.reasons[0].startswith("signature missing")


def test_resigned_with_another_key_is_refused(bundle: Path, key_path: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.key"
    generate_keypair(other)
    sign_bundle(bundle, load_private_key(other))
    result = verify_bundle(bundle)
    assert not result.ok
    assert any("key mismatch: report.html names key" in r for r in result.reasons), result.reasons
    trusted = verify_bundle(bundle, public_key_path(key_path))
    assert any("trusted key lab.key.pub" in r for r in trusted.reasons), trusted.reasons


def test_edited_signature_hashes_break_the_signature(bundle: Path) -> None:
    """An attacker who edits a file and rewrites its hash in the .sig is still caught."""
    _flip_byte(bundle.with_name("results.json"), 3)
    sig = signature_path(bundle)
    document = json.loads(sig.read_text())
    document["files"]["results.json"] = file_sha256(bundle.with_name("results.json"))
    sig.write_text(json.dumps(document))
    result = verify_bundle(bundle)
    assert not result.ok
    assert any(r.startswith("signature invalid") for r in result.reasons), result.reasons
