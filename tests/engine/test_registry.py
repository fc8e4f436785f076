"""Plugins come only from entry points, are validated on load, and errors name the distribution."""

from importlib import metadata
from typing import Any

import pytest
from pydantic import BaseModel, ConfigDict

from aatest.engine import registry
from aatest.engine.errors import PluginError


class _GoodSensor:
    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
        gain: float = 1.0

    def __init__(self, config: Any, context: Any) -> None:
        self.config = config

    def datasheet(self) -> None:
        return None


class _NoConfigSensor:
    def datasheet(self) -> None:
        return None


class _MissingMethodTable:
    class Config(BaseModel):
        pass

    def envelope(self) -> None:
        return None


class _FakeDist:
    def __init__(self, name: str) -> None:
        self.metadata = {"Name": name}
        self.version = "9.9"


class _FakeEntryPoint:
    def __init__(self, name: str, group: str, target: Any, dist: str) -> None:
        self.name, self.group, self._target = name, group, target
        self.dist = _FakeDist(dist)

    def load(self) -> Any:
        if isinstance(self._target, Exception):
            raise self._target
        return self._target


@pytest.fixture
def fake_plugins(monkeypatch: pytest.MonkeyPatch) -> None:
    eps = [
        _FakeEntryPoint("good", "aatest.sensors", _GoodSensor, "vendor-good"),
        _FakeEntryPoint("noconfig", "aatest.sensors", _NoConfigSensor, "vendor-sloppy"),
        _FakeEntryPoint("broken", "aatest.sensors", ImportError("no module x"), "vendor-broken"),
        _FakeEntryPoint("half", "aatest.turntables", _MissingMethodTable, "vendor-half"),
    ]

    def fake_entry_points(group: str) -> list[_FakeEntryPoint]:
        return [ep for ep in eps if ep.group == group]

    monkeypatch.setattr(metadata, "entry_points", fake_entry_points)


@pytest.mark.usefixtures("fake_plugins")
def test_good_plugin_loads_with_its_distribution() -> None:
    info = registry.load("sensor", "good")
    assert (info.distribution, info.version) == ("vendor-good", "9.9")
    config = registry.configure(info, {"gain": 2})
    assert config is not None and config.gain == 2  # type: ignore[attr-defined]


@pytest.mark.usefixtures("fake_plugins")
@pytest.mark.parametrize(
    ("kind", "name", "match"),
    [
        ("sensor", "noconfig", "vendor-sloppy.*'Config'"),
        ("sensor", "broken", "vendor-broken.*failed to import"),
        ("turntable", "half", "vendor-half.*lacks required method.*start"),
        ("sensor", "absent", "no sensor plugin named 'absent'.*good"),
    ],
    ids=["no-config", "import-error", "missing-methods", "not-installed"],
)
def test_bad_plugins_are_refused_naming_the_distribution(kind: str, name: str, match: str) -> None:
    with pytest.raises(PluginError, match=match):
        registry.load(kind, name)


@pytest.mark.usefixtures("fake_plugins")
def test_unknown_options_are_refused() -> None:
    info = registry.load("sensor", "good")
    with pytest.raises(PluginError, match="bad options: colour"):
        registry.configure(info, {"colour": "red"})


def _write_dist(site: Any, name: str, sensors: dict[str, str]) -> Any:
    """A ``.dist-info`` declaring ``aatest.sensors`` entry points, as pip would write it."""
    info = site / f"{name}-1.0.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    points = info / "entry_points.txt"
    points.write_text("[aatest.sensors]\n" + "".join(f"{k} = {v}\n" for k, v in sensors.items()))
    return points


def test_entry_points_are_read_once_while_nothing_is_installed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    real = metadata.entry_points

    def counting(group: str) -> Any:
        calls.append(group)
        return real(group=group)

    monkeypatch.setattr(metadata, "entry_points", counting)
    first = registry.entry_points("sensor")
    first.clear()  # the caller's own list: the cache is not changed through it
    assert [ep.name for ep in registry.entry_points("sensor")] == \
        [ep.name for ep in sorted(real(group="aatest.sensors"), key=lambda ep: ep.name)]
    assert calls == ["aatest.sensors"]


def test_entry_points_follow_installs_and_edits(tmp_path: Any,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    before = {ep.name for ep in registry.entry_points("sensor")}
    points = _write_dist(site, "lab_sensors", {"lab_one": "lab_sensors:One"})
    assert {ep.name for ep in registry.entry_points("sensor")} == before | {"lab_one"}
    points.write_text("[aatest.sensors]\nlab_two = lab_sensors:Two\nlab_three = x:Y\n")
    assert {ep.name for ep in registry.entry_points("sensor")} == \
        before | {"lab_two", "lab_three"}
    points.write_text("")
    assert {ep.name for ep in registry.entry_points("sensor")} == before


def test_a_pinned_block_reads_the_installation_once_and_loads_each_plugin_once(
        tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """Inside ``pinned()`` the installation is read on entry only (an install during the
    block is not seen) and a plugin is loaded once; after it, installs are seen again."""
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    reads: list[int] = []
    real = registry._installed_signature

    def counting() -> Any:
        reads.append(1)
        return real()

    monkeypatch.setattr(registry, "_installed_signature", counting)
    before = {ep.name for ep in registry.entry_points("sensor")}
    with registry.pinned():
        reads.clear()
        first = registry.load("analysis", "sync")
        assert registry.load("analysis", "sync") is first  # loaded and validated once
        _write_dist(site, "lab_sensors", {"lab_one": "lab_sensors:One"})
        assert {ep.name for ep in registry.entry_points("sensor")} == before
        with registry.pinned():  # nested: the outer block's reading
            assert registry.load("analysis", "sync") is first
        assert reads == []
    assert {ep.name for ep in registry.entry_points("sensor")} == before | {"lab_one"}
    with registry.pinned():  # a new block loads afresh
        assert registry.load("analysis", "sync") is not first
