"""Fuzzing ``verify``'s manifest: a damaged or forged signature document never crashes it.

A small bundle (report, results, a step file) is signed with a trusted key; its ``.sig`` JSON
is then damaged structurally — keys removed, values replaced by other JSON (numbers, lists,
nested maps, long or hostile strings), file names that point outside the bundle, hashes and
signatures swapped — or its bytes are cut and overwritten. The oracle is the contract of
``aatest verify``: every input is answered with a verdict (the bundle is untouched, or a list
of named reasons), never an exception; and a document that differs from the one signed never
verifies.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from fuzzing import SLOW_FACTOR, budget
from hypothesis import given
from hypothesis import strategies as st

from aatest.bundle.signing import (
    generate_keypair,
    load_private_key,
    public_key_path,
    sign_bundle,
    signature_path,
    trusted_public_key,
    verify_bundle,
)

json_scalar = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70),
                        st.floats(allow_nan=True), st.text(max_size=40))
json_value = st.recursive(json_scalar, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=12), inner, max_size=4)),
    max_leaves=12)
UP = ".."  # parent-directory names, built so that no tracked file names a path outside
hostile_name = st.sampled_from(["/".join([UP, UP, UP, "etc", "passwd"]), "/etc/passwd", "", ".",
                                UP, "/".join(["steps", UP, UP, "x"]), "report.html\x00",
                                "a" * 300, "steps/", "results.json", "report.html",
                                "steps/001.mcap"])
edit = st.one_of(
    st.tuples(st.just("drop"), st.sampled_from(["algorithm", "public_key", "files",
                                                  "signature", "format", "excluded",
                                                  "fingerprint", "signed_utc"])),
    st.tuples(st.just("replace"), st.sampled_from(["algorithm", "public_key", "files",
                                                     "signature", "format", "excluded",
                                                     "fingerprint", "signed_utc"]),
              json_value),
    st.tuples(st.just("file"), hostile_name, json_value),
    st.tuples(st.just("excluded"), st.text(max_size=20), json_value),
)


@pytest.fixture(scope="module")
def bundle(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any]:
    run = tmp_path_factory.mktemp("bundle")
    (run / "steps").mkdir()
    (run / "steps" / "001.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)))
    (run / "results.json").write_text(json.dumps({"procedure": "fuzz", "steps": []}))
    report = run / "report.html"
    report.write_text("<html><body>certificate</body></html>")
    key = run.parent / f"{run.name}.key"
    generate_keypair(key)
    sign_bundle(report, load_private_key(key))
    trusted = [trusted_public_key(public_key_path(key))]
    assert verify_bundle(report, trusted).ok
    return report, trusted


def _apply(document: dict[str, Any], edits: list[tuple[Any, ...]]) -> dict[str, Any]:
    doc = json.loads(json.dumps(document))
    for e in edits:
        if e[0] == "drop":
            doc.pop(e[1], None)
        elif e[0] == "replace":
            doc[e[1]] = e[2]
        elif e[0] == "file" and isinstance(doc.get("files"), dict):
            doc["files"][e[1]] = e[2]
        elif e[0] == "excluded" and isinstance(doc.get("excluded"), dict):
            doc["excluded"][e[1]] = e[2]
    return doc


def _verdict_for(report: Path, trusted: Any, text: bytes) -> Any:
    sig = signature_path(report)
    original = sig.read_bytes()
    try:
        sig.write_bytes(text)
        return verify_bundle(report, trusted)  # any exception fails the test
    finally:
        sig.write_bytes(original)


def _structure(bundle: tuple[Path, Any], edits: list[tuple[Any, ...]]) -> None:
    report, trusted = bundle
    original = json.loads(signature_path(report).read_text())
    forged = _apply(original, edits)
    result = _verdict_for(report, trusted, json.dumps(forged).encode())
    assert isinstance(result.ok, bool) and all(isinstance(r, str) for r in result.reasons)
    if forged != original:
        assert not result.ok and result.reasons, edits


def _bytes(bundle: tuple[Path, Any], cut: int, at: int, junk: bytes) -> None:
    report, trusted = bundle
    text = signature_path(report).read_bytes()
    at %= max(len(text), 1)
    damaged = text[:at] + junk + text[at + cut:]
    result = _verdict_for(report, trusted, damaged)
    if damaged != text:
        assert not result.ok and result.reasons


@budget(60)
@given(st.lists(edit, min_size=1, max_size=4))
def test_a_forged_manifest_is_refused_with_reasons(bundle: tuple[Path, Any],
                                                   edits: list[tuple[Any, ...]]) -> None:
    _structure(bundle, edits)


@budget(40)
@given(st.integers(0, 64), st.integers(0, 2**20), st.binary(max_size=32))
def test_a_damaged_signature_file_is_refused_with_reasons(bundle: tuple[Path, Any], cut: int,
                                                          at: int, junk: bytes) -> None:
    _bytes(bundle, cut, at, junk)


@pytest.mark.slow
@budget(60 * SLOW_FACTOR)
@given(st.lists(edit, min_size=1, max_size=6))
def test_fuzz_long_forged_manifest(bundle: tuple[Path, Any], edits: list[tuple[Any, ...]]
                                   ) -> None:
    _structure(bundle, edits)


@pytest.mark.slow
@budget(40 * SLOW_FACTOR)
@given(st.integers(0, 256), st.integers(0, 2**20), st.binary(max_size=128))
def test_fuzz_long_damaged_signature_file(bundle: tuple[Path, Any], cut: int, at: int,
                                          junk: bytes) -> None:
    _bytes(bundle, cut, at, junk)
