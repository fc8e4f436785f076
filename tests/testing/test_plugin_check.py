"""``aatest plugin-check DIST`` on real distributions: wheels built here and installed by pip
into a directory of their own (:mod:`vendor_wheel`), checked in a separate process."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from vendor_wheel import build_wheel, env_with, pip_install

DAQ = {"aatest.daqs": {"acme-logger": "acme_logger:AcmeLogger"}}
RIG = {"aatest.conformance": {"daq:acme-logger": "acme_logger:rig"}}


def plugin_check(tmp_path: Path, dist: str, defect: str | None,
                 groups: dict[str, dict[str, str]]) -> subprocess.CompletedProcess[str]:
    target = tmp_path / "site"
    pip_install(build_wheel(tmp_path, dist, defect, groups), target)
    return subprocess.run([sys.executable, "-m", "aatest.cli", "plugin-check", dist],
                          env=env_with(target), cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, check=False)


def rows(output: str) -> dict[str, str]:
    """check name → 'pass'/'FAIL' from the table of ``daq:acme-logger``."""
    found = {}
    for line in output.splitlines():
        if line.startswith("daq:acme-logger"):
            cells = [cell for cell in line.split("  ") if cell.strip()]
            found[cells[1].strip()] = cells[2].strip()
    return found


def test_a_conforming_vendor_daq_passes(tmp_path: Path) -> None:
    done = plugin_check(tmp_path, "acme-logger", None, DAQ | RIG)
    assert done.returncode == 0, done.stdout + done.stderr
    assert rows(done.stdout) == {
        "loads and validates": "pass", "daq record channels clock trigger and pulse": "pass",
        "daq life cycle": "pass", "refuses bad options": "pass", "reports simulated": "pass",
        "every fault ends safe and resumes": "pass"}, done.stdout
    assert "acme-logger 0.3.1: 6 checks of 1 plugins" in done.stdout


@pytest.mark.parametrize(("defect", "failing", "reason"), [
    ("time-goes-back", {"daq record channels clock trigger and pulse"},
     "time stamps are not strictly increasing (1 steps ≤ 0)"),
    ("swallows-faults", {"daq life cycle", "every fault ends safe and resumes"},
     "the injected fault did not raise RigFault"),
])
def test_a_broken_contract_fails_naming_the_check(tmp_path: Path, defect: str,
                                                  failing: set[str], reason: str) -> None:
    done = plugin_check(tmp_path, "acme-logger-broken", defect, DAQ | RIG)
    assert done.returncode == 1, done.stdout + done.stderr
    table = rows(done.stdout)
    assert {check for check, result in table.items() if result == "FAIL"} == failing, done.stdout
    assert reason in done.stdout
    assert f"{len(failing)} of 6 checks FAILED" in done.stderr


def test_a_rig_plugin_without_a_simulator_fails(tmp_path: Path) -> None:
    done = plugin_check(tmp_path, "acme-no-rig", None, DAQ)
    assert done.returncode == 1, done.stdout + done.stderr
    assert rows(done.stdout) == {"loads and validates": "pass", "conformance rig": "FAIL"}
    assert "no 'aatest.conformance' entry point named 'daq:acme-logger'" in done.stdout


def test_missing_distribution_or_no_plugins_is_bad_input(tmp_path: Path) -> None:
    done = plugin_check(tmp_path, "acme-nothing", None, {"console_scripts": {"acme": "x:y"}})
    assert done.returncode == 2, done.stdout + done.stderr
    assert "distribution 'acme-nothing' declares no aatest plugin" in done.stderr
    missing = subprocess.run([sys.executable, "-m", "aatest.cli", "plugin-check", "acme-absent"],
                             capture_output=True, text=True, timeout=120, check=False)
    assert missing.returncode == 2
    assert "distribution 'acme-absent' is not installed" in missing.stderr
