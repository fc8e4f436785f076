"""``aatest plugin-check DIST``: the conformance kit on every plugin an installed distribution
declares, as a pass/fail table.

Every entry point of the distribution in an aatest plugin group is loaded and validated as
``aatest plugins`` does (methods, ``Config``); every turntable, DAQ and chamber plugin is then
run through the conformance kit (``pytest --aatest-plugin KIND:NAME``, one pytest process for
all of them) against the simulator its package declares in ``aatest.conformance``. A rig
plugin without such a simulator fails: nothing asked is passed unchecked. Exit 0 when every
check passes, 1 when one fails, 2 when the distribution is not installed or declares no aatest
plugin. A pass is against simulators only: it says the plugin keeps the contract with its
simulator, not that the hardware behaves like it.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from xml.etree import ElementTree

import typer

from aatest.engine import registry
from aatest.engine.errors import EXIT_FINDING, AatestError, InputError
from aatest.engine.interfaces import GROUPS
from aatest.testing.conformance import GROUP as RIG_GROUP
from aatest.testing.conformance import KINDS as RIG_KINDS

KIND_OF_GROUP = {group: kind for kind, group in GROUPS.items()}


@dataclass(frozen=True)
class Row:
    """One line of the table: a check of one plugin and its outcome."""

    plugin: str
    check: str
    passed: bool
    detail: str = ""


def declared_plugins(dist: str) -> tuple[str, list[tuple[str, str]]]:
    """(version, [(kind, name)…]) of an installed distribution; InputError (exit 2) if it is
    not installed or declares no aatest plugin."""
    try:
        found = metadata.distribution(dist)
    except metadata.PackageNotFoundError as exc:
        raise InputError(f"distribution {dist!r} is not installed") from exc
    plugins = sorted({(KIND_OF_GROUP[ep.group], ep.name) for ep in found.entry_points
                      if ep.group in KIND_OF_GROUP})
    if not plugins:
        raise InputError(f"distribution {dist!r} declares no aatest plugin (entry-point "
                          f"groups {', '.join(GROUPS.values())})")
    return found.version, plugins


def load_row(kind: str, name: str) -> Row:
    """Loading and validating the plugin, as ``aatest plugins`` does."""
    try:
        registry.load(kind, name)
    except AatestError as exc:
        return Row(f"{kind}:{name}", "loads and validates", False, str(exc))
    return Row(f"{kind}:{name}", "loads and validates", True)


def _check_name(testcase: str) -> tuple[str, str]:
    """``test_daq_life_cycle[daq:can]`` → (``daq:can``, ``daq life cycle``)."""
    function, _, spec = testcase.partition("[")
    return spec.rstrip("]"), function.removeprefix("test_").replace("_", " ")


def _outcome(case: ElementTree.Element) -> tuple[bool, str]:
    for tag in ("failure", "error", "skipped"):
        found = case.find(tag)
        if found is not None:
            message = (found.get("message") or found.text or tag).strip().splitlines()
            return False, f"{tag}: {message[0] if message else tag}"
    return True, ""


def kit_rows(specs: list[str], timeout_s: float) -> list[Row]:
    """Run the kit on ``specs`` in a pytest process of its own; one row per check."""
    with tempfile.TemporaryDirectory(prefix="aatest-plugin-check-") as work:
        report = Path(work) / "report.xml"
        (Path(work) / "pytest.ini").write_text("[pytest]\n")  # no project's settings apply
        command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                   "-p", "no:xdist", "-c", str(Path(work) / "pytest.ini"), "--rootdir", work,
                   f"--junitxml={report}"] + [f"--aatest-plugin={spec}" for spec in specs]
        try:
            done = subprocess.run(command, cwd=work, capture_output=True, text=True,
                                  timeout=timeout_s, check=False)
        except subprocess.TimeoutExpired:
            return [Row(spec, "conformance kit", False, f"did not finish in {timeout_s:g} s")
                    for spec in specs]
        cases = ElementTree.parse(report).iter("testcase") if report.exists() else iter(())
        rows = [Row(*_check_name(case.get("name", "")), *_outcome(case)) for case in cases]
    rows = [row for row in rows if row.plugin]  # a check of another kind: no parameters
    tail = (done.stdout + done.stderr).strip().splitlines()[-1:] or ["no output"]
    return rows + [Row(spec, "conformance kit", False, f"no check ran (pytest exit "
                       f"{done.returncode}: {tail[0]})")
                   for spec in specs if not any(row.plugin == spec for row in rows)]


def check_distribution(dist: str, timeout_s: float = 1800.0) -> tuple[str, list[Row]]:
    """(version, rows) for every plugin ``dist`` declares (InputError, exit 2: see above)."""
    version, plugins = declared_plugins(dist)
    rows = [load_row(kind, name) for kind, name in plugins]
    rigs = {ep.name for ep in metadata.entry_points(group=RIG_GROUP)}
    specs = []
    for (kind, name), loaded in list(zip(plugins, rows, strict=True)):
        spec = f"{kind}:{name}"
        if kind not in RIG_KINDS or not loaded.passed:
            continue
        if spec in rigs:
            specs.append(spec)
        else:
            rows.append(Row(spec, "conformance rig", False, f"no '{RIG_GROUP}' entry point "
                            f"named {spec!r}: the package must declare its simulator there"))
    return version, rows + (kit_rows(specs, timeout_s) if specs else [])


def table(rows: list[Row]) -> str:
    """The rows as an aligned text table (plugin, check, result, detail)."""
    header = Row("plugin", "check", True, "detail")
    width = [max(len(r.plugin) for r in [header, *rows]),
             max(len(r.check) for r in [header, *rows])]

    def line(row: Row, result: str) -> str:
        return f"{row.plugin:<{width[0]}}  {row.check:<{width[1]}}  {result:<6}  {row.detail}"

    return "\n".join([line(header, "result").rstrip(),
                      *(line(r, "pass" if r.passed else "FAIL").rstrip() for r in rows)])


def plugin_check(
    dist: str = typer.Argument(..., help="Installed distribution (a vendor's package) to check"),
    timeout_s: float = typer.Option(1800.0, "--timeout-s", min=1.0,
                                    help="Wall seconds the conformance kit may take"),
) -> None:
    """Check every aatest plugin of an installed distribution against the plugin contract
    (its simulators); exit 1 when a check fails."""
    version, rows = check_distribution(dist, timeout_s)
    failed = sum(not row.passed for row in rows)
    typer.echo(f"{dist} {version}: {len(rows)} checks of "
               f"{len({row.plugin for row in rows})} plugins")
    typer.echo(table(rows))
    if failed:
        typer.echo(f"{failed} of {len(rows)} checks FAILED", err=True)
        raise typer.Exit(EXIT_FINDING)
    typer.echo(f"all {len(rows)} checks passed (against the plugins' simulators; a pass "
               "does not qualify the hardware)")
