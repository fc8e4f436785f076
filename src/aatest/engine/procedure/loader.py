"""Load procedure and rig YAML files into validated models, with located errors.

Every problem is reported as ``FILE:LINE:COLUMN: field: message``, all at once, through one
:class:`~aatest.engine.errors.ProcedureError` (exit code 2). Whatever the bytes in the file,
nothing else escapes: YAML oddities (recursive aliases, odd tags, huge nesting) become a
located problem too.

Example
-------
>>> from pathlib import Path
>>> from aatest.engine.procedure.loader import load_procedure, load_rig, rig_from_procedure
>>> import aatest
>>> shipped = Path(aatest.__file__).parent / "procedures" / "scale-factor.yaml"
>>> proc = load_procedure(shipped)
>>> rig_from_procedure(proc).turntable.plugin
'sim'
"""

from __future__ import annotations

import difflib
from dataclasses import replace
from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    StrictStr,
    ValidationError,
    model_validator,
)

from aatest.engine.errors import PluginError, Problem, ProcedureError
from aatest.engine.procedure import models as _procedure_models
from aatest.engine.procedure.models import STEP_KINDS, Procedure
from aatest.engine.rig_description import (
    EncoderSpec,
    Instruments,
    LabSpec,
    LoggerSpec,
    TableGeometry,
    ThermometerSpec,
)
from aatest.positioned_yaml import (
    locate,
    parse_yaml,
    problems_from_validation,
    read_text,
    validate_tree,
)


class PluginSpec(BaseModel):
    """One rig plugin: its entry-point name and that plugin's own options (validated later by
    the plugin's ``Config`` model)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    plugin: StrictStr = Field(min_length=1)
    options: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _flat_options(cls, data: Any) -> Any:
        """``{plugin: modbus, host: h}`` → ``{plugin: modbus, options: {host: h}}``;
        a bare string names a plugin without options."""
        if isinstance(data, str):
            return {"plugin": data}
        if isinstance(data, dict) and "plugin" in data and "options" not in data:
            options = {k: v for k, v in data.items() if k != "plugin"}
            return {"plugin": data["plugin"], "options": options}
        return data


class RigConfig(BaseModel):
    """The rig: one plugin per kind (docs/interfaces.md §2, ``--rig RIG.yaml``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    turntable: PluginSpec = PluginSpec(plugin="sim")
    daq: PluginSpec = PluginSpec(plugin="sim")
    chamber: PluginSpec = PluginSpec(plugin="none")
    instruments: Instruments | None = Field(
        None, description="stated accuracies and traceability of the instruments "
        "(docs/interfaces.md §2); None: the documented defaults, named as such in every budget")
    references: tuple[str, ...] = Field(
        (), description="identifiers of the reference standards this rig uses, registered with "
        "`aatest references add`; an overdue one refuses a calibration before motion")
    _rig_dir: Path | None = PrivateAttr(None)

    @property
    def rig_dir(self) -> Path | None:
        """The rig file's directory, where its plugins' relative file options lie (None: the
        procedure's ``rig`` block, :mod:`aatest.plugin_options`)."""
        return self._rig_dir


def _vocabulary() -> frozenset[str]:
    """Every key the procedure and rig files know (for "did you mean" hints)."""
    models = [m for m in vars(_procedure_models).values()
              if isinstance(m, type) and issubclass(m, BaseModel)] + [
        RigConfig, Instruments, EncoderSpec, LoggerSpec, ThermometerSpec, TableGeometry, LabSpec]
    return frozenset(name for m in models for name in m.model_fields)


_UNKNOWN_KEY = "Extra inputs are not permitted"


#: dotted parts of a step's own key: "steps", the step's index, the key
_STEP_KEY_DEPTH = 3


def _with_hint(problem: Problem, vocabulary: frozenset[str]) -> Problem:
    """Add a hint to an unknown-key problem: the closest known key, or the step kinds."""
    if problem.message != _UNKNOWN_KEY or not problem.field:
        return problem
    parts = problem.field.split(".")
    # "….steps.<index>.<key>": the unknown key is where a step kind belongs
    is_step_kind = len(parts) >= _STEP_KEY_DEPTH and parts[-3] == "steps" and parts[-2].isdigit()
    choices = STEP_KINDS if is_step_kind else sorted(vocabulary)
    close = difflib.get_close_matches(parts[-1], choices, n=1, cutoff=0.75)
    message = f"unknown key; did you mean {close[0]!r}?" if close else "unknown key"
    if is_step_kind:
        message += f"{' A' if close else '; a'} step is one of: {', '.join(STEP_KINDS)}"
    return replace(problem, message=message)


def _guarded(filename: str, text: str, model: type[Any]) -> tuple[Any, Any]:
    """Parse and validate, translating anything unexpected into a located problem."""
    try:
        tree, data = parse_yaml(text, filename)
        return validate_tree(model, tree, data, filename), tree
    except ProcedureError as exc:
        vocabulary = _vocabulary()
        raise ProcedureError([_with_hint(p, vocabulary) for p in exc.problems]) from exc
    except (RecursionError, ValueError, TypeError, AttributeError, KeyError, IndexError,
            OverflowError) as exc:
        # e.g. a self-referencing alias (&a [*a]) or a construct ruamel cannot represent
        message = f"cannot load YAML: {type(exc).__name__}: {exc}"[:300]
        raise ProcedureError([Problem(filename, 1, 1, "", message)]) from exc


def _option_problems(exc: ValidationError, path: tuple[Any, ...], fields: list[str], tree: Any,
                     filename: str) -> list[Problem]:
    """Located problems of one analysis' options (unknown ones with a "did you mean")."""
    problems = []
    for p in problems_from_validation(exc, tree, filename):
        where = path + tuple(int(x) if x.isdigit() else x for x in p.field.split(".") if x)
        line, col = locate(tree, where)
        message = p.message
        if message == _UNKNOWN_KEY:
            close = difflib.get_close_matches(where[-1], fields, n=1, cutoff=0.6)
            message = f"unknown option; did you mean {close[0]!r}?" if close else \
                f"unknown option; options: {', '.join(fields) or 'none'}"
        problems.append(Problem(filename, line, col, ".".join(map(str, where)), message))
    return problems


def _analysis_problems(proc: Procedure, tree: Any, filename: str) -> list[Problem]:
    """Every ``analysis:`` entry must name an installed analysis and give it valid options."""
    from aatest.engine.analysis import plugins

    problems = []
    for i, entry in enumerate(proc.analysis):
        name, options = plugins.split_entry(entry)
        path: tuple[Any, ...] = ("analysis", i) + (() if isinstance(entry, str) else (name,))
        try:
            plugin = plugins.load(name)
        except PluginError as exc:
            line, col = locate(tree, path)
            problems.append(Problem(filename, line, col, ".".join(map(str, path)), str(exc)))
            continue
        try:
            plugin.options(options)
        except ValidationError as exc:
            fields = list(plugin.cls.Options.model_fields)
            problems += _option_problems(exc, path, fields, tree, filename)
    for clash in plugins.option_clashes(proc.analysis):  # the run could not tell which
        path = ("analysis", clash.index, plugins.split_entry(proc.analysis[clash.index])[0])
        first_line, _ = locate(tree, ("analysis", clash.first))
        line, col = locate(tree, path)
        problems.append(Problem(
            filename, line, col, ".".join(map(str, path)),
            f"analysis {clash.plugin!r} is given two different sets of options (the other at "
            f"line {first_line}): list it once, with the options it is to run with"))
    return problems


def parse_procedure(text: str, filename: str = "<procedure>") -> Procedure:
    """Validate procedure YAML given as text (``filename`` labels the problems).

    Analysis options are validated by each analysis plugin's own ``Options`` model.
    """
    from aatest.engine import registry

    proc, tree = _guarded(filename, text, Procedure)
    with registry.pinned():  # each entry resolves aliases: read the installation once
        problems = _analysis_problems(proc, tree, filename)
    if problems:
        raise ProcedureError(problems)
    return proc.with_source(filename, tree)  # type: ignore[no-any-return]


def load_procedure(path: str | Path) -> Procedure:
    """Read and validate a procedure file.

    Raises
    ------
    ProcedureError
        Every problem, each as ``FILE:LINE:COLUMN: field: message``.
    """
    return parse_procedure(read_text(Path(path)), str(path))


def load_rig(path: str | Path) -> RigConfig:
    """Read a rig file: ``turntable``/``daq``/``chamber``, each ``{plugin: NAME, **options}``.

    Kinds left out keep the simulated defaults (sim, sim, none). Each plugin's options are
    checked against its own ``Config`` model now, every problem located in the file.
    """
    rig, tree = _guarded(str(path), read_text(Path(path)), RigConfig)
    rig._rig_dir = Path(path).absolute().parent
    problems = [p for kind in ("turntable", "daq", "chamber")
                for p in _plugin_option_problems(rig, kind, tree, str(path))]
    if problems:
        raise ProcedureError(problems)
    return rig  # type: ignore[no-any-return]


def _plugin_option_problems(rig: RigConfig, kind: str, tree: Any, filename: str
                            ) -> list[Problem]:
    """The ``kind`` plugin's options checked against its ``Config`` where the rig file gives
    them, located (an unknown plugin name is located at its ``plugin:``)."""
    from aatest.engine import registry

    spec: PluginSpec = getattr(rig, kind)
    try:
        info = registry.load(kind, spec.plugin)
        registry.configure(info, dict(spec.options), rig.rig_dir)
    except PluginError as exc:
        given = tree.get(kind)
        where = (kind, "options") if isinstance(given, dict) and "options" in given else (kind,)
        if not isinstance(exc.__cause__, ValidationError):
            return [Problem(filename, *locate(tree, (kind, "plugin")), f"{kind}.plugin", str(exc))]
        fields = list(info.config_model.model_fields) if info.config_model else []
        named = f"{kind} plugin {spec.plugin!r} ({info.distribution}): "
        return [replace(p, message=named + p.message)
                for p in _option_problems(exc.__cause__, where, fields, tree, filename)]
    return []


def rig_from_procedure(proc: Procedure) -> RigConfig:
    """The rig named in the procedure's ``rig`` block (plugins without options)."""
    return RigConfig(turntable=PluginSpec(plugin=proc.rig.turntable),
                     daq=PluginSpec(plugin=proc.rig.daq),
                     chamber=PluginSpec(plugin=proc.rig.chamber))
