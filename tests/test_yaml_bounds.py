"""Every YAML the tool reads is bounded: aliases and deep nesting are refused, located.

A 1 kB "billion laughs" file expands to 9⁹ ≈ 387 million strings when aliases are followed;
before this check ``aatest validate`` on it ran for minutes and grew past 2.7 GB. It now fails
at its first alias with exit 2 and ``FILE:LINE:COLUMN``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from aatest.engine.errors import ProblemsError
from aatest.engine.procedure.loader import load_procedure, load_rig
from aatest.positioned_yaml import MAX_DEPTH, parse_yaml
from aatest.recording.data.importer import import_dataset
from aatest.records.lab import load_lab
from aatest.station import StationOptions, build
from aatest.twin.model import load_rig_model


def alias_bomb() -> str:
    """Nine levels of nine aliases each, padded with comments to 1 052 bytes."""
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    text = "\n".join(lines) + "\n"
    return text + "#" * (1051 - len(text)) + "\n"


BOMB = alias_bomb()


def test_the_bomb_is_the_reported_size() -> None:
    assert len(BOMB.encode()) == 1052


def test_parse_refuses_the_first_alias_with_its_position() -> None:
    with pytest.raises(ProblemsError) as info:
        parse_yaml(BOMB, "bomb.yaml")
    (problem,) = info.value.problems
    assert str(problem).startswith("bomb.yaml:2:8:")  # "b: &b [*a" — the first *a
    assert "alias *a is not accepted" in str(problem)


def test_merge_keys_need_aliases_and_are_refused() -> None:
    with pytest.raises(ProblemsError, match="alias"):
        parse_yaml("base: &b {x: 1}\nother:\n  <<: *b\n", "m.yaml")


def test_anchors_without_aliases_and_normal_nesting_still_load() -> None:
    _, data = parse_yaml("a: &x [1, {b: [2, [3]]}]\n", "ok.yaml")
    assert data == {"a": [1, {"b": [2, [3]]}]}


def test_deep_nesting_is_refused_before_the_recursion_limit() -> None:
    text = "a: " + "[" * 100_000 + "]" * 100_000 + "\n"
    with pytest.raises(ProblemsError, match=f"deeper than {MAX_DEPTH}"):
        parse_yaml(text, "deep.yaml")


@pytest.mark.parametrize("reader", [load_procedure, load_rig, load_lab, load_rig_model],
                         ids=["procedure", "rig", "lab-profile", "model"])
def test_every_model_file_reader_refuses_the_bomb(tmp_path: Path, reader: object) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB)
    with pytest.raises(ProblemsError) as info:
        reader(path)  # type: ignore[operator]
    assert str(info.value.problems[0]).startswith(f"{path}:2:8:")


def test_dataset_yaml_refuses_the_bomb(tmp_path: Path) -> None:
    (tmp_path / "dataset.yaml").write_text(BOMB)
    with pytest.raises(ProblemsError) as info:
        import_dataset(tmp_path)
    assert str(info.value.problems[0]).startswith(f"{tmp_path / 'dataset.yaml'}:2:8:")


def test_station_upload_refuses_the_bomb(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")),
                        base_url="http://127.0.0.1:8671")
    done = client.post("/api/upload", params={"name": "bomb.yaml"}, content=BOMB.encode())
    assert done.status_code == 200
    doc = done.json()
    assert not doc["ok"] and doc["problems"][0].startswith("bomb.yaml:2:8:")


def test_validate_exits_2_within_memory_and_cpu_bounds(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB)
    done = subprocess.run([sys.executable, "-m", "aatest.cli", "validate", str(path)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2
    assert f"{path}:2:8:" in done.stderr and "Traceback" not in done.stderr
    # a bound, not a timing: the loader under 2 s of CPU and 200 MB of address space (the CLI
    # itself imports numpy, whose address space alone is larger); following the aliases would
    # need ≈ 30 GB and minutes, so it could not exit 2 here if it did
    check = subprocess.run(
        [sys.executable, "-c",
         "import resource, sys\n"
         "from pathlib import Path\n"
         "from aatest.positioned_yaml import parse_yaml\n"
         "from aatest.engine.errors import ProblemsError\n"
         "resource.setrlimit(resource.RLIMIT_CPU, (2, 3))\n"
         "resource.setrlimit(resource.RLIMIT_AS, (200 * 2**20,) * 2)\n"
         "try:\n"
         "    parse_yaml(Path(sys.argv[1]).read_text(), sys.argv[1])\n"
         "except ProblemsError as exc:\n"
         "    print(exc.problems[0]); sys.exit(2)\n",
         str(path)],
        capture_output=True, text=True, timeout=120, check=False)
    assert check.returncode == 2, check.stderr  # not killed at 2 s CPU nor out of 200 MB
    assert check.stdout.startswith(f"{path}:2:8:")
