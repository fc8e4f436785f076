"""Two ways to install the example vendor package for a test.

* ``vendor_venv`` (module scope): for real. A fresh virtual environment (no system site
  packages) sees the test environment's packages through a ``.pth`` file, gets aatest installed
  editable from this repository and the example built and installed by pip from its own
  ``pyproject.toml`` — offline when the build backends are already installed. Skipped only when
  no virtual environment can be created.
* ``install`` / ``vendor_example``: the light way (pluggy's trick) for checks of this process's
  registry: a ``.dist-info`` written from the package's ``pyproject.toml`` on ``sys.path``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import venv
from collections.abc import Callable
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples" / "vendor-plugin"
IGNORED = shutil.ignore_patterns("build", "*.egg-info", "__pycache__")


def write_distribution(site: Path, name: str, version: str,
                       entry_points: dict[str, dict[str, str]]) -> None:
    """A ``.dist-info`` with METADATA and entry_points.txt, as pip would write it."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n"
        for group, eps in entry_points.items()))


@pytest.fixture
def example_dir() -> Path:
    """The example vendor package's source tree (its ``pyproject.toml`` and ``src/``)."""
    return EXAMPLES


@pytest.fixture
def install(tmp_path_factory: pytest.TempPathFactory,
            monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    site = tmp_path_factory.mktemp("site")
    monkeypatch.syspath_prepend(str(site))

    def _install(name: str, version: str, entry_points: dict[str, dict[str, str]]) -> None:
        write_distribution(site, name, version, entry_points)

    return _install


@pytest.fixture
def vendor_example(install: Callable[..., None], monkeypatch: pytest.MonkeyPatch) -> None:
    project = tomllib.loads((EXAMPLES / "pyproject.toml").read_text())["project"]
    install(project["name"], project["version"], project["entry-points"])
    monkeypatch.syspath_prepend(str(EXAMPLES / "src"))


def _build_requirements() -> list[str]:
    """The build backends aatest and the example declare (``[build-system] requires``)."""
    return sorted({req for project in (REPO, EXAMPLES) for req in tomllib.loads(
        (project / "pyproject.toml").read_text())["build-system"]["requires"]})


def _create_venv(root: Path) -> Path:
    """A fresh venv without pip (fast) that sees this interpreter's site packages; its python."""
    try:
        venv.EnvBuilder(system_site_packages=False, with_pip=False, symlinks=os.name != "nt",
                        clear=True).create(root)
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"cannot create a virtual environment here: {exc}")
    python = root / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    purelib = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True).stdout.strip()
    host = dict.fromkeys(sysconfig.get_paths()[key] for key in ("purelib", "platlib"))
    # addsitedir also runs the host's .pth files (editable installs), unlike a plain path line
    Path(purelib, "_aatest_test_host.pth").write_text(
        "".join(f"import site; site.addsitedir({path!r})\n" for path in host))
    return python


def _pip(python: Path, *args: str) -> None:
    """Run this interpreter's pip on the venv of ``python`` (pip ≥ 22.3: ``--python``)."""
    done = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install",
                           "--disable-pip-version-check", *args],
                          check=False, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"pip install {' '.join(args)} failed:\n{done.stdout}{done.stderr}"


@pytest.fixture(scope="module")
def vendor_venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with aatest and the example installed by pip; its scripts directory."""
    python = _create_venv(tmp_path_factory.mktemp("vendor") / "venv")
    # already satisfied from the test environment (offline), else from the pip cache or index
    _pip(python, *_build_requirements())
    _pip(python, "--no-deps", "--no-build-isolation", "--no-index", "--editable", str(REPO))
    # built from a copy: setuptools leaves build/ and *.egg-info behind in the source tree
    source = shutil.copytree(EXAMPLES, python.parents[2] / "vendor-plugin", ignore=IGNORED)
    # dependencies (aatest, pydantic) must resolve from what is installed: no index at all
    _pip(python, "--no-build-isolation", "--no-index", "--no-cache-dir", str(source))
    return python.parent
