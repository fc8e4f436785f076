"""The method hash: the same for the same mode, code and correction; different otherwise."""

from __future__ import annotations

import aatest
from aatest.batch import method
from aatest.batch.correction import ReferenceCorrection


def test_the_hash_follows_mode_code_version_and_correction(monkeypatch) -> None:
    fix = ReferenceCorrection(reference="LOG-7", found_on="2026-11-20", reason="r",
                              logger_gain_error_ppm=6000)
    plain = method.method_of("analyze", None)
    assert plain["code_sha256"] == method.code_sha256() and len(plain["code_sha256"]) == 64
    assert "scale_factor" in plain["analysis_plugins"]
    base = method.method_hash(plain)
    assert method.method_hash(method.method_of("analyze", None)) == base
    assert method.method_hash(method.method_of("diagnose", None)) != base
    assert method.method_hash(method.method_of("analyze", fix)) != base
    monkeypatch.setattr(aatest, "__version__", "99.0")
    assert method.method_hash(method.method_of("analyze", None)) != base
    method.code_sha256.cache_clear()
    monkeypatch.setattr(method, "_RESULT_CODE", ("batch/method.py",))  # other code, other hash
    try:
        assert method.code_sha256() != plain["code_sha256"]
    finally:
        method.code_sha256.cache_clear()
