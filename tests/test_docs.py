"""The documents agree with the repository and with the code.

The code cites ``docs/method.md`` and ``docs/interfaces.md`` by section number, the README and the
guides link to each other, and the documents name modules, files, CLI options, procedure keys
and physical numbers. These tests keep all of that true:

- no tracked file refers to the retired shared folder or to a path above the repository root;
- every ``docs/<name>.md §N`` citation names an existing document and a numbered heading in it;
- every relative Markdown link, every repository path and every ``aatest.…`` name in the
  documents exists;
- the interfaces document names every CLI command and option, every procedure key and step kind
  and every diagnose effect;
- the method's numbers are the ones the shipped procedure, the sensor plugin and the twin use.
"""

from __future__ import annotations

import functools
import importlib
import re
import subprocess
from pathlib import Path

import pytest
from numpy.testing import assert_allclose
from pydantic import BaseModel
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
METHOD = DOCS / "method.md"
INTERFACES = DOCS / "interfaces.md"

# Built by concatenation so that this file does not match its own patterns.
RETIRED_FOLDER = "shared" + "/"
PARENT_PATH = ".." + "/"
#: (file, exact text) occurrences that are allowed, with the reason
ALLOWED = {
    ("tests/plugins/report/test_sandbox.py", "'" + PARENT_PATH + "secret.txt'"):
        "the path-traversal include the report sandbox must refuse",
    ("tests/station/test_station_security.py", "shipped/" + PARENT_PATH + PARENT_PATH + "x.yaml"):
        "the path-traversal procedure id the station must refuse",
    ("tests/station/test_station_upload.py",
     '"' + PARENT_PATH + PARENT_PATH + "etc/cron.d/evil.yaml"):
        "an uploaded file name with a path the station must reduce to a plain name",
    ("tests/station/test_station_upload.py", '"' + PARENT_PATH + '"'):
        "an uploaded file name that is only a path, which the station must refuse",
    ("tests/station/test_station_upload.py", '"' + PARENT_PATH + PARENT_PATH + 'outside.yaml"'):
        "an uploaded file name that must never be written outside the upload directory",
}
#: repository paths the documents promise before the code lands (docs/interfaces.md, marked †)
PROMISED_PATHS = frozenset({"src/aatest/schemas/results.schema.json"})
#: entry-point group names look like module names but are not modules
ENTRY_POINT_GROUPS = frozenset({"aatest.turntables", "aatest.daqs", "aatest.chambers",
                                "aatest.sensors", "aatest.analyses", "aatest.reports",
                                "aatest.effects", "aatest.conformance"})

SECTION = r"(?:§|\\u00a7)\s*(\d+(?:\.\d+)*)(?:\s*[–-]\s*(\d+(?:\.\d+)*))?"
_SECTION_NC = r"(?:§|\\u00a7)\s*\d+(?:\.\d+)*(?:\s*[–-]\s*\d+(?:\.\d+)*)?"
CITATION = re.compile(
    rf"docs/([\w-]+\.md)`{{0,2}}[\s#]*({_SECTION_NC}(?:\s*(?:,|and)\s*{_SECTION_NC})*)")
DOC_NAME = re.compile(r"docs/([\w-]+\.md)")
HEADING = re.compile(r"^#{1,6}\s+(\d+(?:\.\d+)*)\.?\s", re.MULTILINE)
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"`([^`\n]+)`")
REPO_PATH = re.compile(r"^(?:src|tests|examples|docs|bench)/[\w./-]*$")
DOTTED = re.compile(r"^aatest(?:\.\w+)+$")


def _markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def _read(path: Path) -> str | None:
    """The text of a file, or None for binary or missing files."""
    try:
        return path.read_text(encoding="utf-8")
    except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
        return None


@functools.cache
def _tracked_texts() -> dict[str, str]:
    """Repository-relative path → text of every tracked text file (git ls-files; read once)."""
    try:
        listing = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                                 check=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the tracked-file checks need git")
    texts = {name: _read(ROOT / name) for name in listing.split("\0") if name}
    return {name: text for name, text in texts.items() if text is not None}


def _prose(markdown: str) -> str:
    """Markdown without fenced code blocks (their '#' lines are comments, not headings)."""
    return FENCE.sub("", markdown)


def _sections(doc: Path) -> set[str]:
    return set(HEADING.findall(_prose(doc.read_text(encoding="utf-8"))))


def test_no_tracked_file_refers_outside_the_repository() -> None:
    this = Path(__file__).resolve().relative_to(ROOT).as_posix()
    offenders: list[str] = []
    for name, text in _tracked_texts().items():
        if name == this:
            continue
        checked = text
        for allowed_file, allowed_text in ALLOWED:
            if name == allowed_file:
                checked = checked.replace(allowed_text, "")
        for number, line in enumerate(checked.splitlines(), start=1):
            if RETIRED_FOLDER in line or PARENT_PATH in line:
                offenders.append(f"{name}:{number}: {line.strip()}")
    assert offenders == []


def test_every_cited_section_exists() -> None:
    sections: dict[str, set[str]] = {}
    problems: list[str] = []
    cited = 0
    for name, text in _tracked_texts().items():
        for doc_name, refs in CITATION.findall(text):
            doc = DOCS / doc_name
            if not doc.is_file():
                problems.append(f"{name}: docs/{doc_name} does not exist")
                continue
            known = sections.setdefault(doc_name, _sections(doc))
            for first, last in re.findall(SECTION, refs):
                cited += 1
                problems += [f"{name}: docs/{doc_name} has no section §{number}"
                             for number in (first, last) if number and number not in known]
    assert problems == []
    assert cited > 50, "the citation pattern no longer finds the code's citations"


def test_every_named_document_exists() -> None:
    missing = sorted({f"{name}: docs/{doc}" for name, text in _tracked_texts().items()
                      for doc in DOC_NAME.findall(text) if not (DOCS / doc).is_file()})
    assert missing == []


@pytest.mark.parametrize("markdown", _markdown_files(), ids=lambda p: p.name)
def test_relative_links_resolve(markdown: Path) -> None:
    prose = CODE_SPAN.sub("", _prose(markdown.read_text(encoding="utf-8")))
    broken: list[str] = []
    for target in LINK.findall(prose):
        if target.startswith("#") or re.match(r"[a-z][a-z0-9+.-]*:", target):
            continue
        path = (markdown.parent / target.split("#", 1)[0]).resolve()
        if not path.exists() or not path.is_relative_to(ROOT):
            broken.append(target)
    assert broken == []


def _resolves(dotted: str) -> bool:
    """Whether ``aatest.a.b.c`` names a module, or an attribute of the longest module prefix."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


@pytest.mark.parametrize("markdown", _markdown_files(), ids=lambda p: p.name)
def test_named_paths_and_modules_exist(markdown: Path) -> None:
    spans = CODE_SPAN.findall(_prose(markdown.read_text(encoding="utf-8")))
    paths = [s for s in spans if REPO_PATH.match(s) and s not in PROMISED_PATHS]
    names = [s for s in spans if DOTTED.match(s) and s not in ENTRY_POINT_GROUPS]
    assert [p for p in paths if not (ROOT / p.rstrip("/")).exists()] == []
    assert [n for n in names if not _resolves(n)] == []


# --- the interfaces document names what the code offers ------------------------------------


def _cli_commands() -> list[tuple[str, ...]]:
    from aatest.cli import app

    commands: list[tuple[str, ...]] = [()]
    for info in app.registered_commands:
        commands.append((info.name or info.callback.__name__.replace("_", "-"),))
    for group in app.registered_groups:
        for info in group.typer_instance.registered_commands:
            commands.append((group.name, info.name or info.callback.__name__.replace("_", "-")))
    return commands


@pytest.mark.parametrize("command", _cli_commands(), ids=lambda c: " ".join(c) or "aatest")
def test_every_cli_command_and_option_is_documented(command: tuple[str, ...]) -> None:
    from aatest.cli import app

    text = INTERFACES.read_text(encoding="utf-8")
    shown = CliRunner().invoke(app, [*command, "--help"],
                               env={"COLUMNS": "200", "NO_COLOR": "1", "TERM": "dumb"})
    assert shown.exit_code == 0, shown.output
    options = set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", shown.output))
    assert "--help" in options, "the options are no longer parsed from the help text"
    options.discard("--help")
    assert " ".join(("aatest", *command)) in text
    assert sorted(o for o in options if o not in text) == []


def test_every_procedure_key_and_step_kind_is_documented() -> None:
    from aatest.engine.procedure import models

    text = INTERFACES.read_text(encoding="utf-8")
    keys = {field for model in vars(models).values()
            if isinstance(model, type) and issubclass(model, BaseModel)
            for field in model.model_fields}
    assert "frequency_hz" in keys and "setpoints_c" in keys
    missing = sorted(k for k in keys | set(models.STEP_KINDS)
                     if not re.search(rf"(?<![\w-]){re.escape(k)}(?![\w-])", text))
    assert missing == []


def test_every_diagnose_effect_is_in_the_vocabulary() -> None:
    from aatest.diagnose.candidates import CANDIDATES

    vocabulary = set(re.findall(r"^\| `(\w+)` \|", INTERFACES.read_text(encoding="utf-8"),
                                flags=re.MULTILINE))
    assert {c.effect for c in CANDIDATES} | {"clock_drift", "excess_noise"} <= vocabulary


# --- the method's numbers are the code's numbers --------------------------------------------


def _method_number(pattern: str) -> float:
    found = re.search(pattern, METHOD.read_text(encoding="utf-8"))
    assert found is not None, f"docs/method.md no longer says {pattern!r}"
    return float(found.group(1))


def test_published_frequency_matrix_is_the_shipped_procedure() -> None:
    from aatest.engine.procedure.loader import load_procedure
    from aatest.engine.procedure.planner import expand

    text = METHOD.read_text(encoding="utf-8")
    listed = text.split("The 28 points are:", 1)[1].split("Hz.", 1)[0]
    documented = [float(f) for f in re.findall(r"\d+\.\d+", listed)]
    shipped_file = ROOT / "src/aatest/procedures/stepped-sine-frequency-response.yaml"
    plan = expand(load_procedure(shipped_file))
    shipped = sorted({s.frequency_hz for s in plan.steps if s.kind == "sine"})
    assert len(documented) == 28
    # the document rounds to 9 decimals: at most 5e-10 Hz off
    assert_allclose(documented, shipped, rtol=0, atol=5.1e-10)


@pytest.mark.parametrize(("axis", "row", "field"), [
    ("inner", r"\| rate limit \| (\d+) °/s \|", "rate_limit_dps"),
    ("outer", r"\| rate limit \| \d+ °/s \| (\d+) °/s \|", "rate_limit_dps"),
    ("inner", r"\| acceleration limit \| (\d+) °/s² \|", "accel_limit_dps2"),
    ("outer", r"\| acceleration limit \| \d+ °/s² \| (\d+) °/s² \|", "accel_limit_dps2"),
], ids=["inner-rate", "outer-rate", "inner-accel", "outer-accel"])
def test_turntable_limits_are_the_twins(axis: str, row: str, field: str) -> None:
    from aatest.twin.api import realistic_rig_model

    limits = getattr(realistic_rig_model().table, axis)
    assert getattr(limits, field) == _method_number(row)


#: (what docs/method.md says, with the number as group 1; datasheet field; factor to its unit)
DATASHEET_ROWS = [
    (r"\(±(\d+\.\d+) °/s²\)", "range_dps2", 1.0),
    (r"zero bias (\d+\.\d+) ±", "nominal_bias_v", 1.0),
    (r"zero bias \d+\.\d+ ± (\d+\.\d+) V", "bias_tolerance_v", 1.0),
    (r"\(= (\d+\.\d+) mV/\(°/s²\)\)", "scale_v_per_dps2", 1e-3),
    (r"V/\(rad/s²\) ± (\d+) %", "scale_tolerance_pct", 1.0),
    (r"< (\d+) mV RMS", "noise_rms_v", 1e-3),
    (r"cross-axis sensitivity \| ≤ (\d+) %", "cross_axis_limit", 1e-2),
    (r"sensitive-axis alignment \| ≤ (\d+\.\d+)°", "misalignment_limit_deg", 1.0),
    (r"null \(bias\) temperature sensitivity \| ±(\d+\.\d+) mV/°C",
     "bias_temperature_limit_v_per_c", 1e-3),
    (r"scale-factor temperature coefficient \| ≤ (\d+\.\d+) %/°C",
     "scale_temperature_limit_per_c", 1e-2),
    (r"non-linearity \| ±(\d+\.\d+) % FR", "nonlinearity_limit_pct_fr", 1.0),
    (r"sensor test ceiling\s+(\d+) % of range", "test_ceiling_fraction", 1e-2),
    (r"use (\d+\.\d+) °/s²\)", "floor_dps2", 1.0),
]


@pytest.mark.parametrize(("pattern", "field", "to_datasheet_unit"), DATASHEET_ROWS,
                         ids=[row[1] for row in DATASHEET_ROWS])
def test_sensor_datasheet_is_the_plugins(pattern: str, field: str,
                                        to_datasheet_unit: float) -> None:
    from aatest.plugins.sensors.sr207 import SR207

    sheet = SR207().datasheet()
    assert_allclose(getattr(sheet, field), _method_number(pattern) * to_datasheet_unit, rtol=1e-12)
