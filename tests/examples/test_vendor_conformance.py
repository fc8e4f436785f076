"""The example vendor package passes aatest's conformance kit, run as a vendor would: pytest
with ``--aatest-plugin turntable:acme-single-axis`` in a fresh venv where the package is
installed by pip (the ``vendor_venv`` fixture)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path


def test_example_passes_the_conformance_kit(vendor_venv: Path, tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    result = subprocess.run(
        [vendor_venv / "python", "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0",
         "--aatest-plugin", "turntable:acme-single-axis"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    # life cycle, envelope, options, simulated flag, the declared fault: five checks passed
    assert "5 passed" in result.stdout, result.stdout


def test_plugin_check_passes_the_installed_example(vendor_venv: Path, tmp_path: Path) -> None:
    """``aatest plugin-check`` on the pip-installed distribution: its four plugins load, and
    the table (the one rig plugin) passes the kit against its twin simulator."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    result = subprocess.run(
        [vendor_venv / "aatest", "plugin-check", "aatest-vendor-example"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "aatest-vendor-example 0.1.0: 9 checks of 4 plugins" in result.stdout, result.stdout
    for plugin in ("turntable:acme-single-axis", "sensor:acme-mems-aa",
                   "effect:asymmetric_scale", "report:acme-summary"):
        assert f"{plugin}" in result.stdout
    assert "FAIL" not in result.stdout
