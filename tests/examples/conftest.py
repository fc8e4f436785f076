"""Install the example vendor package the light way: its metadata (built from its own
pyproject.toml) and its source directory on sys.path, so importlib.metadata discovers it."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "vendor-plugin"


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
