"""Every public name of the engine, the stages it orchestrates and the results is documented,
with its units (``aatest.engine``, ``aatest.recording``, ``aatest.metrology``, ``aatest.storage``,
``aatest.bundle``, ``aatest.results``: the packages mypy checks strictly).

Read statically with ``ast`` (nothing is imported), over every module of these packages:

- every public class, function and method (no ``_`` in its module path or its own name, not
  nested in a function) has a docstring;
- a public function that takes or returns a physical quantity names the unit in its docstring.
  A quantity is a parameter whose name ends in a unit suffix (``duration_s``, ``freq_hz``,
  ``accel_dps2`` …: the docstring must name *that* unit), a function whose own name ends in one
  (its return value), or, in a numeric module (one that imports numpy, scipy or math), a
  parameter or return annotated ``float`` (any unit, or "dimensionless").
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

import aatest

PACKAGES = ("engine", "recording", "metrology", "storage", "bundle", "results")
SOURCE_DIR = Path(aatest.__file__).parent

#: unit suffix of a name → the pattern its docstring must contain
UNIT_PATTERNS: dict[str, str] = {
    "s": r"(?<![\w'\u2019/°-])s(?![\w'\u2019²^])|\bseconds?\b",
    "ns": r"\bns\b|\bnanoseconds?\b",
    "ms": r"\bms\b|\bmilliseconds?\b",
    "hz": r"Hz",
    "deg": r"°(?![/C])|\bdeg(rees?)?\b(?!/)",
    "dps": r"(°|\bdeg)/s(?![²^])",
    "dps2": r"(°|\bdeg)/s(²|\^2)",
    "v": r"(?<![\w'\u2019])V(?![\w'\u2019])|\bvolts?\b",
    "c": r"°C",
    "ppm": r"\bppm\b",
    "db": r"\bdB\b",
    "rad": r"\brad\b",
}
ANY_UNIT = re.compile("|".join([*UNIT_PATTERNS.values(), r"\bdimensionless\b", r"%"]))
SUFFIX = re.compile(r"_(" + "|".join(UNIT_PATTERNS) + r")$")
NUMERIC_MODULES = ("numpy", "scipy", "math")
Definition = ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef

# Public names that fail today, as "module:qualname"; the lists can only shrink (an entry
# that passes fails `test_allow_lists_name_only_current_failures`). What is left lives in
# modules owned elsewhere this session (dataset, uncertainty); the lead empties them on merge.
ALLOWED_UNDOCUMENTED: frozenset[str] = frozenset(
    {
    }
)
ALLOWED_WITHOUT_UNITS: frozenset[str] = frozenset(
    {
        "aatest.metrology.uncertainty.gum:Input.mean",  # generic: the caller's unit
        "aatest.metrology.uncertainty.statistics:finite_values",  # generic: the caller's unit
        "aatest.metrology.uncertainty.gum:Input.standard_uncertainty",  # generic: the caller's unit
        "aatest.metrology.uncertainty.gum:evaluate",  # generic: the caller's unit
    }
)


@dataclass(frozen=True)
class PublicName:
    """One public class or function found in the source, with what the checks need."""

    key: str
    node: Definition
    numeric_module: bool

    @property
    def docstring(self) -> str:
        """Return the docstring, empty when there is none."""
        return ast.get_docstring(self.node) or ""


def _module_name(path: Path) -> str:
    parts = path.relative_to(SOURCE_DIR.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_public(name: str) -> bool:
    return not name.startswith("_")


def _imports_numeric(tree: ast.Module) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        else:
            continue
        if any(name.split(".")[0] in NUMERIC_MODULES for name in names):
            return True
    return False


def _skipped(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Overload stubs and property setters/deleters share the documented definition."""
    for decorator in node.decorator_list:
        text = ast.unparse(decorator)
        if text.endswith(("overload", ".setter", ".deleter")):
            return True
    return False


def _walk_public(body: list[ast.stmt], prefix: str) -> Iterator[tuple[str, Definition]]:
    for node in body:
        if isinstance(node, ast.ClassDef) and _is_public(node.name):
            yield (f"{prefix}{node.name}", node)
            yield from _walk_public(node.body, f"{prefix}{node.name}.")
        elif (
            isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and _is_public(node.name)
            and not _skipped(node)
        ):
            yield (f"{prefix}{node.name}", node)


def public_names(path: Path) -> Iterator[PublicName]:
    """Yield the public classes, functions and methods defined in one source file."""
    module = _module_name(path)
    if not all(_is_public(part) for part in module.split(".")):
        return
    tree = ast.parse(path.read_text(encoding="utf-8"))
    numeric = _imports_numeric(tree)
    for qualname, node in _walk_public(tree.body, ""):
        yield PublicName(f"{module}:{qualname}", node, numeric)


def _is_float(annotation: ast.expr | None) -> bool:
    return annotation is not None and re.search(r"\bfloat\b", ast.unparse(annotation)) is not None


def missing_units(name: PublicName) -> list[str]:
    """Describe each quantity of a function whose unit its docstring does not name."""
    node = name.node
    if isinstance(node, ast.ClassDef):
        return []
    args = node.args
    params = [*args.posonlyargs, *args.args, *args.kwonlyargs]
    quantities = [(p.arg, p.annotation) for p in params if p.arg not in {"self", "cls"}]
    quantities.append((f"{node.name} (return)", node.returns))
    problems = []
    for label, annotation in quantities:
        suffix = SUFFIX.search(label.removesuffix(" (return)"))
        if suffix and not re.search(UNIT_PATTERNS[suffix.group(1)], name.docstring):
            problems.append(f"{label}: unit of _{suffix.group(1)} not named")
        elif (
            not suffix
            and name.numeric_module
            and _is_float(annotation)
            and not ANY_UNIT.search(name.docstring)
        ):
            problems.append(f"{label}: float without a unit or 'dimensionless'")
    return problems


def _all_public_names() -> list[PublicName]:
    paths = sorted(p for package in PACKAGES for p in (SOURCE_DIR / package).rglob("*.py"))
    return [name for path in paths for name in public_names(path)]


def find_failures() -> tuple[dict[str, str], dict[str, str]]:
    """Map the undocumented names, and the names whose units are missing, to a reason."""
    undocumented: dict[str, str] = {}
    without_units: dict[str, str] = {}
    for name in _all_public_names():
        if not name.docstring:
            undocumented[name.key] = "no docstring"
        elif problems := missing_units(name):
            without_units[name.key] = "; ".join(problems)
    return undocumented, without_units


@pytest.fixture(scope="module")
def failures() -> tuple[dict[str, str], dict[str, str]]:
    """Return the failures of the whole of ``aatest.engine`` and ``aatest.results``."""
    return find_failures()


def _report(title: str, found: dict[str, str], allowed: frozenset[str]) -> None:
    new = [f"{key}: {reason}" for key, reason in sorted(found.items()) if key not in allowed]
    if new:
        pytest.fail(f"{title}:\n  " + "\n  ".join(new), pytrace=False)


def test_every_public_name_has_a_docstring(failures: tuple[dict[str, str], ...]) -> None:
    """Classes, functions and methods a user may call say what they are for."""
    _report("public names without a docstring", failures[0], ALLOWED_UNDOCUMENTED)


def test_quantities_name_their_units(failures: tuple[dict[str, str], ...]) -> None:
    """A physical quantity in a signature has its unit in the docstring."""
    _report("docstrings that do not name the units", failures[1], ALLOWED_WITHOUT_UNITS)


def test_allow_lists_name_only_current_failures(failures: tuple[dict[str, str], ...]) -> None:
    """A fixed (or removed) name must leave its allow-list, so the lists only shrink."""
    stale = sorted(
        (ALLOWED_UNDOCUMENTED - failures[0].keys()) | (ALLOWED_WITHOUT_UNITS - failures[1].keys())
    )
    if stale:
        pytest.fail(
            "allow-listed names that now pass or no longer exist; remove them:\n  "
            + "\n  ".join(stale),
            pytrace=False,
        )


def test_the_whole_of_both_packages_is_read() -> None:
    """Every module of both packages is parsed, including the subpackages."""
    keys = {name.key.partition(":")[0] for name in _all_public_names()}
    assert {"aatest.engine.errors", "aatest.recording.writer", "aatest.results.base"} <= keys


# The checks themselves, on small sources, so a broken checker cannot pass silently.


def _names(source: str) -> list[PublicName]:
    tree = ast.parse(source)
    numeric = _imports_numeric(tree)
    return [
        PublicName(f"aatest.engine.example:{qualname}", node, numeric)
        for qualname, node in _walk_public(tree.body, "")
    ]


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ('def f(duration_s: float) -> None:\n    """Wait ``duration_s`` (s)."""', []),
        (
            'def f(duration_s: float) -> None:\n    """Wait for the step\'s end."""',
            ["duration_s: unit of _s not named"],
        ),
        (
            'def f(rate_dps: float) -> None:\n    """Spin at ``rate_dps`` (°/s²)."""',
            ["rate_dps: unit of _dps not named"],
        ),
        ('def f(accel_dps2: float) -> None:\n    """Shake at ``accel_dps2`` (°/s²)."""', []),
        ('def f(freq_hz: float, angle_deg: float) -> None:\n    """At f (Hz), angle (°)."""', []),
        (
            'def lab_time_s() -> float:\n    """Lab time of the run."""',
            ["lab_time_s (return): unit of _s not named"],
        ),
        (
            'import numpy\ndef f(gain: float) -> float:\n    """Scale the gain."""',
            [
                "gain: float without a unit or 'dimensionless'",
                "f (return): float without a unit or 'dimensionless'",
            ],
        ),
        ('import numpy\ndef f(gain: float) -> None:\n    """Scale (dimensionless)."""', []),
        ('def f(gain: float) -> None:\n    """Not a numeric module."""', []),
    ],
    ids=[
        "seconds",
        "apostrophe-s-is-no-unit",
        "dps-not-dps2",
        "dps2",
        "two-units",
        "return",
        "numeric-float",
        "dimensionless",
        "non-numeric",
    ],
)
def test_unit_detection(source: str, expected: list[str]) -> None:
    """Units are matched per suffix; a bare ``s`` in a word does not count as seconds."""
    (name,) = _names(source)
    assert missing_units(name) == expected


def test_private_and_nested_names_are_skipped() -> None:
    """Only the public surface is required to be documented."""
    source = (
        "class A:\n    def m(self): pass\n    def _p(self): pass\n"
        "def _helper(): pass\n"
        "def outer():\n    '''Doc.'''\n    def inner(): pass\n"
    )
    found = {name.key.partition(":")[2]: name.docstring for name in _names(source)}
    assert found == {"A": "", "A.m": "", "outer": "Doc."}
