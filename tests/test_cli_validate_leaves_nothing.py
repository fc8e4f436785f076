"""``aatest validate`` checks a run without touching anything: no file appears on disk.

Validation runs before anything moves and may be repeated at will, so it must not create the
default records store (an SQLite file under the user's data directory), the run directory it
checks the free space of, nor a library's cache: matplotlib's font cache was built in the
home directory by merely importing the analysis and report plugins.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import aatest

PROCEDURE = Path(aatest.__file__).parent / "procedures" / "scale-factor.yaml"
#: variables that would point aatest or its libraries outside the empty home
_OUTSIDE = ("AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY", "AATEST_STAGING",
            "MPLCONFIGDIR", "XDG_DATA_HOME", "XDG_CONFIG_HOME", "XDG_CACHE_HOME",
            "XDG_STATE_HOME")


@pytest.mark.slow  # ≈ 8–15 s: a fresh interpreter imports every plugin
def test_validate_in_an_empty_home_leaves_no_file(tmp_path: Path) -> None:
    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir()
    cwd.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in _OUTSIDE} | {"HOME": str(home)}
    script = "from aatest.cli import app; app()"
    done = subprocess.run([sys.executable, "-c", script, "validate", str(PROCEDURE)],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "records store: ok" in done.stdout  # the store was checked, not created
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == [
        Path("cwd"), Path("home")]
