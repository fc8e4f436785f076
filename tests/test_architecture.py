"""The import graph of ``src/aatest`` keeps the layering that the package map promises.

The graph is built statically with grimp (every module parsed, relative imports resolved,
imports inside functions included), so a lazy import cannot hide a dependency. The rules:

(a) no import cycle between packages (``aatest.twin``, ``aatest.clocksync``, ``aatest.recording``,
    ``aatest.metrology``, ``aatest.diagnose``, ``aatest.results``, ``aatest.cli``, each
    ``aatest.plugins.<kind>`` and each part of the engine: ``aatest.engine.run``,
    ``aatest.engine.errors`` …). The engine counts by its parts because its shared records
    (errors, steps, logs, interfaces) sit below the recording and metrology packages that its
    orchestration (procedure, run, analysis pass) sits above; and none between modules
    either: a shared piece lives in a module of its own that both import, not behind a lazy
    import in one of them;
(b) the engine and the packages it orchestrates (recording, metrology, storage, bundle) import
    no plugin, twin or diagnose module: plugins are found through entry points only;
(c) ``aatest.twin`` imports no plugin: the simulated plugins build on the twin, not the reverse;
(d) a plugin imports no private helper (``_name``) of another package.
"""

from __future__ import annotations

import ast
import importlib.util
import itertools
from collections.abc import Iterable, Iterator
from pathlib import Path

import grimp
import numpy as np
import numpy.typing as npt
import pytest
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components, shortest_path

import aatest

# Known violations, each (importer module, imported module). Empty: the layering holds. An
# entry whose import no longer exists fails `test_allow_list_names_only_existing_imports`, so a
# list that has to grow again (temporarily, with a comment why) can only shrink afterwards.
ALLOWED_IMPORTS: frozenset[tuple[str, str]] = frozenset({
    # The procedure loader checks each listed analysis' options through the analysis plugins,
    # while the analysis pass reads the procedure's models: procedure ↔ analysis, visible
    # since the engine counts by its parts. To go when the analysis-plugin lookup leaves
    # engine/analysis (the module-cycle work).
    ("aatest.engine.procedure.loader", "aatest.engine.analysis.plugins"),
})

ROOT = "aatest"
SOURCE_DIR = Path(aatest.__file__).parent


def package_of(module: str) -> str:
    """Name the package a module belongs to for the layering rules.

    ``aatest.plugins.<kind>.*`` counts per plugin kind and ``aatest.engine.<part>.*`` per part
    of the engine (``aatest.engine.run.runner`` → ``aatest.engine.run``), everything else by
    its first level below ``aatest`` (``aatest.recording.data.importer`` → ``aatest.recording``).
    """
    parts = module.split(".")
    depth = 3 if parts[1:2] in (["plugins"], ["engine"]) and len(parts) > 2 else 2
    return ".".join(parts[:depth])


def _import_lines(graph: grimp.ImportGraph, importer: str, imported: str) -> str:
    details = graph.get_import_details(importer=importer, imported=imported)
    return "; ".join(f"line {d['line_number']}: {d['line_contents']}" for d in details)


def find_package_cycles(graph: grimp.ImportGraph) -> list[str]:
    """Describe every elementary package cycle closed by some package edge, hop by hop.

    For each package edge a → b the shortest path b → … → a (scipy, unweighted) closes the
    shortest cycle through that edge; each distinct cycle is reported once, every hop with the
    module imports behind it.
    """
    edges = _package_edges(graph)
    packages = sorted({package_of(m) for m in graph.modules})
    index = {p: i for i, p in enumerate(packages)}
    matrix = csr_array(
        ([1.0] * len(edges), ([index[a] for a, _ in edges], [index[b] for _, b in edges])),
        shape=(len(packages),) * 2,
    )
    _, predecessors = shortest_path(matrix, unweighted=True, return_predecessors=True)
    cycles: dict[tuple[str, ...], str] = {}
    for a, b in sorted(edges):
        cycle = _path(predecessors, index[b], index[a], packages)
        if cycle is None:
            continue
        cycle = [a, *cycle]
        start = cycle.index(min(cycle))
        key = tuple(cycle[start:] + cycle[:start])
        cycles.setdefault(key, _describe_cycle([*key, key[0]], edges))
    return list(cycles.values())


def _path(
    predecessors: npt.NDArray[np.int32], source: int, target: int, names: list[str]
) -> list[str] | None:
    """Return the packages from source up to (not including) target, None if unreachable."""
    if predecessors[source, target] < 0 and source != target:
        return None
    hops = [target]
    while hops[-1] != source:
        hops.append(int(predecessors[source, hops[-1]]))
    return [names[i] for i in reversed(hops)][:-1]


def _describe_cycle(cycle: list[str], edges: dict[tuple[str, str], list[tuple[str, str]]]) -> str:
    lines = [f"cycle {' -> '.join(cycle)}:"]
    for a, b in itertools.pairwise(cycle):
        pairs = edges[(a, b)]
        more = f" (+{len(pairs) - 1} more)" if len(pairs) > 1 else ""
        lines.append(f"    {pairs[0][0]} -> {pairs[0][1]}{more}")
    return "\n".join(lines)


def _package_edges(graph: grimp.ImportGraph) -> dict[tuple[str, str], list[tuple[str, str]]]:
    """Map each package-to-package edge to the module imports behind it."""
    edges: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for module in sorted(graph.modules):
        for imported in sorted(graph.find_modules_directly_imported_by(module)):
            edge = (package_of(module), package_of(imported))
            if edge[0] != edge[1]:
                edges.setdefault(edge, []).append((module, imported))
    return edges


def find_module_cycles(graph: grimp.ImportGraph) -> list[str]:
    """Describe one cycle of every group of modules that import each other, hop by hop.

    The groups are the strongly connected components of the module graph (scipy); each is
    reported once, by the shortest cycle through its smallest module name, every hop with the
    import lines behind it, followed by the group's other members.
    """
    modules = sorted(graph.modules)
    index = {m: i for i, m in enumerate(modules)}
    pairs = [(index[a], index[b]) for a in modules
             for b in graph.find_modules_directly_imported_by(a)]
    matrix = csr_array(
        ([1.0] * len(pairs), ([a for a, _ in pairs], [b for _, b in pairs])),
        shape=(len(modules),) * 2,
    )
    count, labels = connected_components(matrix, directed=True, connection="strong")
    groups = [sorted(np.flatnonzero(labels == k)) for k in range(count)]
    cyclic = [g for g in groups if len(g) > 1 or matrix[g[0], g[0]]]
    if not cyclic:
        return []
    _, predecessors = shortest_path(matrix, unweighted=True, return_predecessors=True)
    found = []
    for group in sorted(cyclic, key=lambda g: modules[g[0]]):
        first = group[0]
        successors = [b for b in matrix[[first], :].indices if labels[b] == labels[first]]
        closing = [(b, _path(predecessors, b, first, modules)) for b in sorted(successors)]
        hops = min(((b, path) for b, path in closing if path is not None),
                   key=lambda item: len(item[1]))[1]
        cycle = [modules[first], *hops, modules[first]]
        lines = [f"cycle {' -> '.join(cycle)}:"]
        for a, b in itertools.pairwise(cycle):
            lines.append(f"    {a} -> {b} ({_import_lines(graph, a, b)})")
        others = sorted(set(modules[i] for i in group) - set(cycle))
        if others:
            lines.append(f"    (the same group also holds {', '.join(others)})")
        found.append("\n".join(lines))
    return found


def find_forbidden_imports(
    graph: grimp.ImportGraph, importer_package: str, forbidden: Iterable[str]
) -> list[str]:
    """List the direct imports from ``importer_package`` into any ``forbidden`` package."""
    prefixes = tuple(forbidden)
    found = []
    for module in sorted(graph.modules):
        if module != importer_package and not module.startswith(importer_package + "."):
            continue
        for imported in sorted(graph.find_modules_directly_imported_by(module)):
            if any(imported == p or imported.startswith(p + ".") for p in prefixes):
                lines = _import_lines(graph, module, imported)
                found.append(f"{module} imports {imported} ({lines})")
    return found


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_imports(module: str, source: str, is_package: bool = False) -> list[str]:
    """List the imports in ``source`` that reach a private name of another package.

    A private name is a module or attribute whose own name starts with one underscore
    (``aatest.plugins.analysis._common``, ``from aatest.twin.model import _helper``).
    """
    found = []
    own = package_of(module)
    anchor = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [(alias.name, "") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), anchor)
            targets = [(base, alias.name) for alias in node.names]
        else:
            continue
        for target, name in targets:
            path = [*target.split("."), name] if name else target.split(".")
            if path[0] != ROOT or package_of(target) == own:
                continue
            if any(_is_private(part) for part in path[1:]):
                found.append(f"{module} line {node.lineno}: imports {'.'.join(path)}")
    return found


def _module_sources() -> Iterator[tuple[str, Path]]:
    for path in sorted(SOURCE_DIR.rglob("*.py")):
        parts = path.relative_to(SOURCE_DIR.parent).with_suffix("").parts
        yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts), path


@pytest.fixture(scope="module")
def full_graph() -> grimp.ImportGraph:
    """Return the import graph of the installed ``aatest`` sources, nothing excluded."""
    return grimp.build_graph(ROOT, cache_dir=None)


@pytest.fixture(scope="module")
def graph() -> grimp.ImportGraph:
    """Return the import graph without the allow-listed, currently known violations."""
    built = grimp.build_graph(ROOT, cache_dir=None)
    for importer, imported in ALLOWED_IMPORTS:
        if built.direct_import_exists(importer=importer, imported=imported):
            built.remove_import(importer=importer, imported=imported)
    return built


def _fail_with(title: str, problems: list[str]) -> None:
    if problems:
        pytest.fail(f"{title}:\n  " + "\n  ".join(problems), pytrace=False)


def test_allow_list_names_only_existing_imports(full_graph: grimp.ImportGraph) -> None:
    """An allow-listed import that is gone must leave the list, so the list only shrinks."""
    stale = sorted(
        f"{a} -> {b}"
        for a, b in ALLOWED_IMPORTS
        if not full_graph.direct_import_exists(importer=a, imported=b)
    )
    _fail_with("ALLOWED_IMPORTS names imports that no longer exist; remove them", stale)


def test_no_import_cycle_between_packages(graph: grimp.ImportGraph) -> None:
    """(a) Packages form a directed acyclic graph."""
    _fail_with("import cycles between packages", find_package_cycles(graph))


def test_no_import_cycle_between_modules(graph: grimp.ImportGraph) -> None:
    """(a) Modules form a directed acyclic graph, lazy imports inside functions included."""
    _fail_with("import cycles between modules", find_module_cycles(graph))


#: the engine and the stages it orchestrates: none of them may reach a plugin, the twin or diagnose
ORCHESTRATED = ("aatest.engine", "aatest.recording", "aatest.metrology", "aatest.storage",
                "aatest.bundle")


@pytest.mark.parametrize("package", ORCHESTRATED)
def test_engine_imports_no_plugin_twin_or_diagnose(graph: grimp.ImportGraph, package: str) -> None:
    """(b) The engine finds plugins through entry points and never needs the twin."""
    forbidden = ["aatest.plugins", "aatest.twin", "aatest.diagnose"]
    _fail_with(
        f"{package} imports a plugin, the twin or diagnose",
        find_forbidden_imports(graph, package, forbidden),
    )


def test_reports_read_the_typed_record_not_the_recording(graph: grimp.ImportGraph) -> None:
    """A report presents the results it is handed: it never reads the recording back (the
    logged temperatures are summarised into the results when the run is analysed)."""
    _fail_with(
        "aatest.plugins.report reads the recording",
        find_forbidden_imports(graph, "aatest.plugins.report", ["aatest.recording"]),
    )


def test_twin_imports_no_plugin(graph: grimp.ImportGraph) -> None:
    """(c) The simulated plugins build on the twin, never the reverse."""
    _fail_with(
        "aatest.twin imports a plugin",
        find_forbidden_imports(graph, "aatest.twin", ["aatest.plugins"]),
    )


def test_plugins_import_no_private_helpers_of_other_packages() -> None:
    """(d) A plugin uses another package only through its public names."""
    problems = [
        problem
        for module, path in _module_sources()
        if module.startswith("aatest.plugins.")
        for problem in private_imports(module, path.read_text(), path.name == "__init__.py")
    ]
    _fail_with("plugins import private helpers of another package", problems)


# The checks themselves, on small synthetic graphs, so a broken checker cannot pass silently.


def _synthetic(edges: list[tuple[str, str]]) -> grimp.ImportGraph:
    built = grimp.ImportGraph()
    for importer, imported in edges:
        built.add_import(importer=importer, imported=imported, line_number=1, line_contents="x")
    return built


def test_package_cycle_is_reported_with_its_modules() -> None:
    """A twin ↔ plugin loop through a function-level import is named module by module."""
    built = _synthetic(
        [
            ("aatest.twin.world", "aatest.plugins.sensors.sr207"),
            ("aatest.plugins.sensors.sr207", "aatest.twin.sensor"),
            ("aatest.engine.steps", "aatest.results.base"),
        ]
    )
    (message,) = find_package_cycles(built)
    assert message.startswith("cycle aatest.plugins.sensors -> aatest.twin -> aatest.plugins")
    assert "aatest.twin.world -> aatest.plugins.sensors.sr207" in message
    assert "aatest.plugins.sensors.sr207 -> aatest.twin.sensor" in message


def test_longer_cycle_is_reported_once_in_order() -> None:
    """A three-package loop is one cycle, listed from its smallest package name."""
    built = _synthetic(
        [
            ("aatest.sync.fit", "aatest.twin.model"),
            ("aatest.twin.model", "aatest.engine.errors"),
            ("aatest.engine.errors", "aatest.sync.fit"),
        ]
    )
    (message,) = find_package_cycles(built)
    assert message.splitlines()[0] == (
        "cycle aatest.engine.errors -> aatest.sync -> aatest.twin -> aatest.engine.errors:"
    )
    assert "aatest.twin.model -> aatest.engine.errors" in message


def test_acyclic_layers_report_nothing() -> None:
    """Imports that all point down the layers are not a cycle."""
    built = _synthetic(
        [
            ("aatest.cli", "aatest.engine.run.session"),
            ("aatest.plugins.daq.sim", "aatest.twin.daq"),
            ("aatest.twin.daq", "aatest.engine.errors"),
        ]
    )
    assert find_package_cycles(built) == []


def test_module_cycle_is_reported_hop_by_hop_with_lines() -> None:
    """A three-module loop inside one package, closed by a lazy import, is one cycle."""
    built = grimp.ImportGraph()
    for importer, imported, line, text in [
        ("aatest.sync.fit", "aatest.sync.edges", 12, "from aatest.sync.edges import pair"),
        ("aatest.sync.edges", "aatest.sync.rel", 7, "from aatest.sync.rel import R"),
        ("aatest.sync.rel", "aatest.sync.fit", 40, "    from aatest.sync.fit import f"),
        ("aatest.sync.rel", "aatest.engine.errors", 3, "from aatest.engine import errors"),
        ("aatest.sync.streamed", "aatest.sync.fit", 9, "from aatest.sync.fit import f"),
    ]:
        built.add_import(importer=importer, imported=imported, line_number=line,
                         line_contents=text)
    (message,) = find_module_cycles(built)
    assert message.splitlines() == [
        "cycle aatest.sync.edges -> aatest.sync.rel -> aatest.sync.fit -> aatest.sync.edges:",
        "    aatest.sync.edges -> aatest.sync.rel (line 7: from aatest.sync.rel import R)",
        "    aatest.sync.rel -> aatest.sync.fit (line 40:     from aatest.sync.fit import f)",
        "    aatest.sync.fit -> aatest.sync.edges (line 12: from aatest.sync.edges import pair)",
    ]


def test_two_module_groups_are_two_cycles_and_a_chain_none() -> None:
    """Each strongly connected group is reported once; imports that only point down are not."""
    built = _synthetic(
        [
            ("aatest.results.quantities", "aatest.results.rounding"),
            ("aatest.results.rounding", "aatest.results.quantities"),
            ("aatest.records.audit", "aatest.records.store"),
            ("aatest.records.store", "aatest.records.audit"),
            ("aatest.records.store", "aatest.records.chain"),
            ("aatest.cli", "aatest.records.store"),
        ]
    )
    first, second = find_module_cycles(built)
    assert first.splitlines()[0] == (
        "cycle aatest.records.audit -> aatest.records.store -> aatest.records.audit:"
    )
    assert second.splitlines()[0].startswith("cycle aatest.results.quantities -> ")
    assert find_module_cycles(_synthetic([("aatest.cli", "aatest.records.store")])) == []


def test_forbidden_import_names_importer_and_line() -> None:
    """A forbidden import is reported with the importing module and its source line."""
    built = _synthetic([("aatest.engine.run.session", "aatest.plugins.report.pdf")])
    (message,) = find_forbidden_imports(built, "aatest.engine", ["aatest.plugins"])
    assert message.startswith("aatest.engine.run.session imports aatest.plugins.report.pdf")
    assert "line 1" in message


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("from aatest.twin.model import _helper", ["aatest.twin.model._helper"]),
        ("def f():\n    from aatest.clocksync import _fit", ["aatest.clocksync._fit"]),
        ("import aatest.engine._cache", ["aatest.engine._cache"]),
        ("from ..analysis._common import mean", ["aatest.plugins.analysis._common.mean"]),
        ("from ._frames import decode", []),
        ("from aatest.engine.errors import AatestError", []),
        ("from numpy import _core", []),
    ],
    ids=[
        "private-name",
        "lazy",
        "private-module",
        "relative-other-kind",
        "own-kind",
        "public",
        "third-party",
    ],
)
def test_private_import_detection(source: str, expected: list[str]) -> None:
    """Private names are found in absolute, relative and function-level imports."""
    found = private_imports("aatest.plugins.daq.can", source)
    assert [line.rpartition("imports ")[2] for line in found] == expected


#: the engine is orchestration only; the stages it calls live in their own packages (issue 22)
ENGINE_LINE_LIMIT = 6000


def test_engine_stays_orchestration_sized() -> None:
    """``aatest.engine`` holds at most :data:`ENGINE_LINE_LIMIT` lines of Python.

    Why: the engine grows by accretion — a helper the pass needs, a check the preflight runs —
    until the orchestration is hard to follow; a stage that grew here moves to its own package
    (``aatest.preflight``, ``aatest.parallel``, ``aatest.schemas`` did).
    """
    engine = SOURCE_DIR / "engine"
    counts = {p.relative_to(engine).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
              for p in engine.rglob("*.py")}
    largest = ", ".join(f"{n} {c}" for n, c in sorted(counts.items(), key=lambda i: -i[1])[:5])
    assert sum(counts.values()) <= ENGINE_LINE_LIMIT, (
        f"aatest.engine has {sum(counts.values())} lines (limit {ENGINE_LINE_LIMIT}); the "
        f"largest modules: {largest}")
