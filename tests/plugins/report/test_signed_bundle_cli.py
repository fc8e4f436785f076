"""The runner's render-and-sign path and ``aatest keygen``/``verify`` exit codes (0 / 1 / 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.bundle.signing import generate_keypair, load_private_key, sign_bundle
from aatest.cli import app
from aatest.engine.run.session import render_and_sign
from aatest.results import RunResults

RUNNER = CliRunner()


@pytest.fixture(autouse=True)
def _no_records_store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """These bundles are not registered: verify them without a records store."""
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'absent.sqlite'}")
    monkeypatch.delenv("AATEST_LAB", raising=False)
    monkeypatch.delenv("AATEST_SIGNING_PASSPHRASE", raising=False)


@pytest.fixture
def key(tmp_path: Path) -> Path:
    path = tmp_path / "lab.key"
    result = RUNNER.invoke(app, ["keygen", "--no-passphrase", str(path)])
    assert result.exit_code == 0, result.output
    return path


@pytest.fixture
def signed_run(results: RunResults, run_dir: Path, key: Path) -> Path:
    results.metadata.report_template = "misalignment"  # the fastest full report
    return render_and_sign(results, run_dir, "misalignment", None, key)


def test_untouched_bundle_exits_0_naming_key(signed_run: Path, key: Path) -> None:
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{key}.pub"])
    assert result.exit_code == 0, result.output
    fingerprint = json.loads((signed_run.parent / "report.html.sig").read_text())["fingerprint"]
    assert f"key:       {fingerprint} (--public-key {key}.pub)" in result.output
    assert "no records store: bundle not checked against a record" in result.output


def test_the_bundle_directory_verifies_as_its_signed_report(signed_run: Path, key: Path) -> None:
    """Given the run directory, verify checks the report signed in it. Before, it took the
    directory for a report: 'report missing: DIR not found' and 'results.json states no
    certificate number' (the results beside the directory), exit 1 on an untouched bundle."""
    result = RUNNER.invoke(app, ["verify", str(signed_run.parent), "--public-key", f"{key}.pub"])
    assert result.exit_code == 0, result.output
    assert f"{signed_run}: signature valid" in result.output
    (signed_run.parent / "report.pdf").write_bytes(b"%PDF-1.7 printed after signing")
    result = RUNNER.invoke(app, ["verify", str(signed_run.parent), "--public-key", f"{key}.pub"])
    assert result.exit_code == 1  # still the signed report is checked: it names the new file
    assert "report.pdf: present but not covered by the signature" in result.output


@pytest.mark.parametrize("name", ["report.html", "results.json", "recording.mcap"])
def test_one_byte_changed_exits_1_naming_the_file(signed_run: Path, key: Path, name: str) -> None:
    path = signed_run.parent / name
    original = path.read_bytes()
    data = bytearray(original)
    data[len(data) // 2] ^= 0x20
    path.write_bytes(bytes(data))
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{key}.pub"])
    path.write_bytes(original)  # the suite's schema check reads every results.json it left
    assert result.exit_code == 1
    assert f"{name}: modified" in result.output


def test_untrusted_removed_signature_and_other_key_exit_1(signed_run: Path, tmp_path: Path,
                                                          key: Path) -> None:
    result = RUNNER.invoke(app, ["verify", str(signed_run)])
    assert result.exit_code == 1 and "but no key is trusted" in result.output
    other = tmp_path / "other.key"
    RUNNER.invoke(app, ["keygen", "--no-passphrase", str(other)])
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{other}.pub"])
    assert result.exit_code == 1 and "which is not trusted" in result.output
    (signed_run.parent / "report.html.sig").unlink()
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{key}.pub"])
    assert result.exit_code == 1 and "signature missing" in result.output


def _lab_profile(path: Path, fingerprint: str, valid_from: str, valid_until: str) -> Path:
    path.write_text(
        "name: Example Calibration Lab\n"
        "signatories:\n  - {name: Dr. A. Example, function: Head of the laboratory}\n"
        f"signing_keys:\n  - {{fingerprint: {fingerprint}, signatory: Dr. A. Example,\n"
        f"     valid_from: {valid_from}, valid_until: {valid_until}}}\n")
    return path


def test_lab_profile_keys_are_trusted_within_their_period(signed_run: Path, key: Path,
                                                          tmp_path: Path) -> None:
    from aatest.bundle.signing import key_fingerprint

    fingerprint = key_fingerprint(load_private_key(key))
    lab = _lab_profile(tmp_path / "lab.yaml", fingerprint, "2020-01-01", "2100-01-01")
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--lab", str(lab)])
    assert result.exit_code == 0, result.output
    assert f"key:       {fingerprint} (lab profile {lab}, valid 2020-01-01 – 2100-01-01)" \
        in result.output
    assert "signatory: Dr. A. Example (holder of the key" in result.output
    retired = _lab_profile(tmp_path / "old.yaml", fingerprint, "2020-01-01", "2021-01-01")
    result = RUNNER.invoke(app, ["verify", str(signed_run)], env={"AATEST_LAB": str(retired)})
    assert result.exit_code == 1
    assert "of Dr. A. Example is valid 2020-01-01 – 2021-01-01" in result.output


def test_lab_profile_key_held_by_an_unknown_signatory_is_bad_input(tmp_path: Path,
                                                                   signed_run: Path) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("signatories:\n  - {name: Dr. A. Example, function: Head}\n"
                   f"signing_keys:\n  - {{fingerprint: {'a' * 64}, signatory: Mr. X,"
                   " valid_from: 2026-01-01}\n")
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--lab", str(lab)])
    assert result.exit_code == 2
    assert "signatory 'Mr. X' is not one of the signatories" in result.output


def test_forged_results_resigned_with_another_key_exit_1(signed_run: Path, key: Path,
                                                         tmp_path: Path) -> None:
    """Issue 29: scale factor +5 %, re-signed with another Ed25519 key, no store — refused."""
    results_path = signed_run.parent / "results.json"
    document = json.loads(results_path.read_text())
    for row in document["analysis"]["scale_factor"].values():
        row["scale_v_per_dps2"] *= 1.05
    forger = tmp_path / "forger.key"
    generate_keypair(forger)
    results_path.write_text(json.dumps(document))
    sign_bundle(signed_run, load_private_key(forger))
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{key}.pub"])
    assert result.exit_code == 1
    assert "which is not trusted (trusted keys: --public-key" in result.output


def test_keygen_encrypts_by_default(tmp_path: Path) -> None:
    path = tmp_path / "enc.key"
    result = RUNNER.invoke(app, ["keygen", str(path)])
    assert result.exit_code == 2
    assert "give a passphrase (in AATEST_SIGNING_PASSPHRASE or at a terminal), or pass " \
           "--no-passphrase" in result.output
    assert not path.exists()
    result = RUNNER.invoke(app, ["keygen", str(path)],
                           env={"AATEST_SIGNING_PASSPHRASE": "correct horse"})
    assert result.exit_code == 0 and "encrypted" in result.output
    assert path.read_text().startswith("-----BEGIN ENCRYPTED PRIVATE KEY-----")


def test_open_key_file_refused_before_the_run_moves(key: Path, tmp_path: Path) -> None:
    key.chmod(0o644)
    procedure = Path(__file__).parents[3] / "src/aatest/procedures/scale-factor.yaml"
    out = tmp_path / "never"
    result = RUNNER.invoke(app, ["run", str(procedure), "--out", str(out), "--no-progress",
                                 "--sign-key", str(key)])
    assert result.exit_code == 2 and not out.exists()
    assert f"{key}: private key is accessible by group or others (mode 0644)" in result.output
