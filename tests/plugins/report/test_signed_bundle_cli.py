"""The runner's render-and-sign path and ``aatest keygen``/``verify`` exit codes (0 / 1)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.run.session import render_and_sign
from aatest.results import RunResults

RUNNER = CliRunner()


@pytest.fixture
def signed_run(results: RunResults, run_dir: Path, tmp_path: Path) -> Path:
    key = tmp_path / "lab.key"
    assert RUNNER.invoke(app, ["keygen", str(key)]).exit_code == 0
    results.metadata.report_template = "misalignment"  # the fastest full report
    return render_and_sign(results, run_dir, "misalignment", None, key)


def test_untouched_bundle_exits_0(signed_run: Path) -> None:
    result = RUNNER.invoke(app, ["verify", str(signed_run)])
    assert result.exit_code == 0, result.output
    assert (signed_run.parent / "report.html.sig").is_file()


@pytest.mark.parametrize("name", ["report.html", "results.json", "recording.mcap"])
def test_one_byte_changed_exits_1_naming_the_file(signed_run: Path, name: str) -> None:
    path = signed_run.parent / name
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x20
    path.write_bytes(bytes(data))
    result = RUNNER.invoke(app, ["verify", str(signed_run)])
    assert result.exit_code == 1
    assert f"{name}: modified" in result.output


def test_removed_signature_and_other_key_exit_1(signed_run: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.key"
    RUNNER.invoke(app, ["keygen", str(other)])
    result = RUNNER.invoke(app, ["verify", str(signed_run), "--public-key", f"{other}.pub"])
    assert result.exit_code == 1 and "key mismatch" in result.output
    (signed_run.parent / "report.html.sig").unlink()
    result = RUNNER.invoke(app, ["verify", str(signed_run)])
    assert result.exit_code == 1 and "signature missing" in result.output
