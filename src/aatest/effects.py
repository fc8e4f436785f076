"""The public effect-plugin API: a lab's own effect model, found through ``aatest.effects``.

The effect vocabulary of ``aatest diagnose`` (docs/interfaces.md §4) is open. A lab adds an
effect by installing a distribution that declares an entry point in the group
``aatest.effects`` whose target is a subclass of :class:`Effect`. One class says everything
the three users of an effect need:

* **the twin** applies its forward model (:meth:`Effect.forward`) when a rig model names it
  (``plugin_effects`` of a sensor in the rig-model YAML, which ``diagnose --model-out`` writes);
* **the replay/design of diagnose** builds its linear-in-parameters design columns
  (:meth:`Effect.columns`), with an optional small bounded search over its shape parameters;
* **the selection** asks whether the data can test it (:meth:`Effect.testable`) and whether a
  fitted result matches its physical signature (:meth:`Effect.signature`); otherwise it competes
  with the built-in effects on the same held-out evidence.

Where the effect enters the sensor model (``Effect.enters``):

``"acceleration"``
    Σ pᵢ·columnᵢ is added, in °/s², to the acceleration the scale factor multiplies — after
    the sensor's dynamics, saturation and cubic term, before ``K(T)`` and the bias. The
    parameters are then relative to K, like the built-in ``nonlinearity_cubic``.
``"voltage"``
    Σ pᵢ·columnᵢ is added, in volts, to the sensor output (like ``bias_temperature``).

Plugins are found only through installed entry points (never from a path or a string in a
file), validated on load (:func:`installed_effects`): the entry-point name equals
``Effect.name``, names are unique over all installed distributions, a built-in name is used
only when the plugin declares ``shadows = True``, and every parameter states its unit. Errors
name the distribution and are :class:`~aatest.engine.errors.PluginError` (exit 2).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar, Literal

import numpy as np

from aatest.engine import registry
from aatest.engine.errors import PluginError

#: the contract's effect vocabulary (docs/interfaces.md §4): an effect plugin may reuse one of
#: these names only when it declares ``shadows = True``
BUILTIN_EFFECTS: frozenset[str] = frozenset({
    "bias_temperature", "scale_temperature", "nonlinearity_cubic", "saturation", "hysteresis",
    "sensor_dynamics", "time_delay", "clock_drift", "jerk_sensitivity", "g_sensitivity",
    "cross_axis", "misalignment", "rate_ripple", "motor_vibration", "excess_noise",
    "amplitude_damping", "rotor_stiction", "jerk_distortion"})
#: where an effect's contribution may enter the sensor model (:attr:`Effect.enters`)
EFFECT_DOMAINS = ("acceleration", "voltage")


@dataclass(frozen=True)
class EffectParameter:
    """One parameter of an effect: its name, unit and (for shape parameters) search bounds.

    ``unit`` is required; write ``"1"`` for a dimensionless parameter. Names should carry the
    unit as the contract's do (``delay_s``, ``limit_dps2``); ``lower``/``upper`` bound the
    search of a shape parameter and are checked when a rig model sets the parameter.
    """

    name: str
    unit: str
    description: str = ""
    lower: float | None = None
    upper: float | None = None


@dataclass(frozen=True)
class EffectInputs:
    """What the sensing element experiences over one record (arrays of equal length).

    Attributes
    ----------
    alpha_dps2
        Acceleration along the sensitive axis that the scale factor multiplies, after the
        sensor's dynamics and saturation (°/s²).
    sensed_dps2
        Acceleration along the sensitive axis before the sensor's dynamics (°/s²).
    temperature_delta_c
        Sensor temperature minus the model's reference temperature (°C).
    time_s
        Time since the table record started (s; negative while the logger runs ahead).
    dt_s
        Sample spacing (s).
    range_dps2
        The sensor's measuring range (°/s²), for terms normalised to it.
    """

    alpha_dps2: np.ndarray
    sensed_dps2: np.ndarray
    temperature_delta_c: np.ndarray
    time_s: np.ndarray
    dt_s: float
    range_dps2: float


@dataclass(frozen=True)
class Excitation:
    """What a dataset exercises, for :meth:`Effect.testable`.

    Attributes
    ----------
    peak_alpha_dps2
        Largest commanded |α| along the sensor axis in any sine step (°/s²).
    range_dps2
        The sensor's range (°/s²).
    temperature_span_c
        Spread of the mean step temperatures (°C).
    frequencies_hz
        Distinct sine frequencies of the dynamic steps (Hz).
    """

    peak_alpha_dps2: float
    range_dps2: float
    temperature_span_c: float
    frequencies_hz: tuple[float, ...]


class Effect(ABC):
    """Base class of an effect plugin (one instance per installed effect, built without args).

    Subclasses set the class attributes and implement :meth:`columns`; the rest has defaults.
    The effect's contribution must be linear in :attr:`parameters` for fixed
    :attr:`shape_parameters` (which are searched within their bounds).
    """

    #: effect name as it appears in findings and rig models (a Python identifier)
    name: ClassVar[str]
    #: linear parameters: contribution = Σ p·column(p)
    parameters: ClassVar[tuple[EffectParameter, ...]]
    #: nonlinear parameters, searched within [lower, upper] (bounds required)
    shape_parameters: ClassVar[tuple[EffectParameter, ...]] = ()
    #: where the contribution enters (module docstring)
    enters: ClassVar[Literal["acceleration", "voltage"]] = "acceleration"
    #: "sensor" (the default) or "table", as reported in findings
    attributed_to: ClassVar[str] = "sensor"
    #: True: deliberately replaces the built-in effect of the same name
    shadows: ClassVar[bool] = False
    #: one line saying what the effect is (shown by ``aatest plugins`` and in the docs)
    summary: ClassVar[str] = ""

    @abstractmethod
    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> Mapping[str, np.ndarray]:
        """One column per linear parameter name: its contribution per unit of the parameter.

        Units: °/s² per unit parameter when ``enters == "acceleration"``, V per unit when
        ``"voltage"``. ``shape`` holds the current shape-parameter values.
        """

    def forward(self, inputs: EffectInputs, parameters: Mapping[str, float]) -> np.ndarray:
        """The effect's contribution (°/s² or V, per :attr:`enters`) for given parameters."""
        shape = {p.name: float(parameters[p.name]) for p in self.shape_parameters}
        cols = self.columns(inputs, shape)
        out = np.zeros_like(inputs.alpha_dps2, dtype=float)
        for p in self.parameters:
            out = out + float(parameters[p.name]) * np.asarray(cols[p.name], dtype=float)
        return out

    def testable(self, excitation: Excitation) -> str | None:
        """Why the data cannot test this effect (None: testable). Default: always testable."""
        return None

    def signature(self, parameters: Mapping[str, float],
                  ci95: Mapping[str, list[float]]) -> str | None:
        """Why a fitted result does not match the effect's physics (None: it matches).

        Called with the fitted parameters and their 95 % intervals; a returned reason vetoes
        the candidate however much it lowers the residual.
        """
        return None


@dataclass(frozen=True)
class InstalledEffect:
    """An effect plugin found through an entry point, with its distribution."""

    effect: Effect
    distribution: str
    version: str

    @property
    def name(self) -> str:
        """The effect's name (its entry-point name)."""
        return self.effect.name


def validate_declaration(name: str, target: Any, dist: str) -> None:
    """An effect plugin's declaration: its name, parameters with units, bounds and domain.

    Checked on the class (nothing is constructed): the entry-point name is the effect's
    ``name``, a built-in name needs ``shadows = True``, every parameter states a unit, shape
    parameters are bounded, and ``enters`` / ``attributed_to`` take known values.
    """
    who = f"effect plugin {name!r} from distribution {dist!r}"
    declared = getattr(target, "name", None)
    if declared != name:
        raise PluginError(f"{who} calls itself {declared!r}: the entry-point name must be the "
                          "effect name")
    if name in BUILTIN_EFFECTS and getattr(target, "shadows", False) is not True:
        raise PluginError(f"{who} shadows the built-in effect of that name; set "
                          "'shadows = True' to replace it deliberately")
    linear = list(getattr(target, "parameters", ()) or ())
    shape = list(getattr(target, "shape_parameters", ()) or ())
    if not linear:
        raise PluginError(f"{who} declares no (linear) parameters")
    names = [getattr(p, "name", None) for p in linear + shape]
    if len(set(names)) != len(names):
        raise PluginError(f"{who} declares a parameter twice: {names}")
    for p in linear + shape:
        pname, unit = getattr(p, "name", None), getattr(p, "unit", None)
        if not (isinstance(pname, str) and pname.isidentifier()):
            raise PluginError(f"{who}: parameter name {pname!r} is not an identifier")
        if not (isinstance(unit, str) and unit.strip()):
            raise PluginError(f"{who}: parameter {pname!r} states no unit (use '1' when "
                              "dimensionless)")
    for p in shape:
        lo, hi = getattr(p, "lower", None), getattr(p, "upper", None)
        if lo is None or hi is None or not lo < hi:
            raise PluginError(f"{who}: shape parameter {p.name!r} needs bounds lower < upper")
    if getattr(target, "enters", None) not in EFFECT_DOMAINS:
        raise PluginError(f"{who}: 'enters' must be one of {', '.join(EFFECT_DOMAINS)}")
    if getattr(target, "attributed_to", "sensor") not in ("sensor", "table"):
        raise PluginError(f"{who}: 'attributed_to' must be 'sensor' or 'table'")


def _load(name: str) -> InstalledEffect:
    """Load one effect, check its declaration (:func:`validate_declaration`), construct it."""
    declared_by = [ep for ep in registry.entry_points("effect") if ep.name == name]
    if len(declared_by) > 1:  # an effect name is global across distributions
        dists = sorted(getattr(getattr(ep, "dist", None), "name", None) or "unknown"
                       for ep in declared_by)
        raise PluginError(f"effect {name!r} is declared by several distributions "
                          f"({', '.join(dists)}): uninstall all but one")
    info = registry.load("effect", name)
    target, dist = info.target, info.distribution
    validate_declaration(name, target, dist)
    if not (isinstance(target, type) and issubclass(target, Effect)):
        raise PluginError(f"effect plugin {name!r} from distribution {dist!r} is not a subclass "
                          "of aatest.effects.Effect")
    try:
        effect = target()
    except Exception as exc:  # a plugin that cannot be built is the plugin's fault
        raise PluginError(f"effect plugin {name!r} from distribution {dist!r} cannot be "
                          f"constructed: {exc}") from exc
    return InstalledEffect(effect, dist, info.version)


@lru_cache(maxsize=1)
def _installed() -> dict[str, InstalledEffect]:
    return {name: _load(name) for name in sorted({ep.name for ep in
                                                  registry.entry_points("effect")})}


def installed_effects() -> dict[str, InstalledEffect]:
    """Every installed effect plugin by name, each validated (a broken one raises).

    The result is cached; :func:`refresh` forgets it (after installing a distribution in the
    running process, e.g. in tests).
    """
    return dict(_installed())


def refresh() -> None:
    """Forget the cached plugin set so the next call re-reads the installed entry points."""
    _installed.cache_clear()


def load_effect(name: str, distribution: str | None = None) -> InstalledEffect:
    """The installed effect ``name``; a missing one raises naming what to install.

    Parameters
    ----------
    name
        Effect name (as in a finding or a rig model).
    distribution
        The distribution a rig model says provides it, named in the error when absent.
    """
    effects = _installed()
    if name in effects:
        return effects[name]
    hint = (f"install the distribution {distribution!r}" if distribution
            else "install the distribution that provides it")
    known = ", ".join(sorted(effects)) or "none installed"
    raise PluginError(f"effect {name!r} is not installed ({hint}; installed effect plugins: "
                      f"{known})")


#: prefix that marks a plugin effect among a diagnose spec's linear terms
SPEC_PREFIX = "plugin:"


def spec_token(effect: str) -> str:
    """How a plugin effect is switched on in a diagnose spec (``plugin:<name>``).

    The prefix keeps a plugin that shadows a built-in apart from the built-in's own columns.
    """
    return SPEC_PREFIX + effect


def column_name(effect: str, parameter: str) -> str:
    """Design-column name of one linear parameter of a plugin effect (``effect.parameter``)."""
    return f"{effect}.{parameter}"


def plugin_names(tokens: Iterable[str]) -> list[str]:
    """The plugin effects switched on among a spec's ``tokens`` (see :func:`spec_token`)."""
    return sorted(t[len(SPEC_PREFIX):] for t in tokens if t.startswith(SPEC_PREFIX))


def design_column_names(tokens: Iterable[str]) -> list[str]:
    """Design-column names of the plugin effects switched on among ``tokens``."""
    return [column_name(n, p.name) for n in plugin_names(tokens)
            for p in load_effect(n).effect.parameters]


def evaluate_columns(installed: InstalledEffect, inputs: EffectInputs,
                     shape: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Call a plugin's :meth:`Effect.columns` and check what it returns.

    One finite array of the inputs' length per linear parameter; anything else — or an
    exception inside the plugin — is a :class:`PluginError` naming the distribution (exit 2),
    not an internal error of aatest.
    """
    eff, who = installed.effect, (f"effect plugin {installed.name!r} from distribution "
                                  f"{installed.distribution!r}")
    try:
        cols = eff.columns(inputs, shape)
    except Exception as exc:  # vendor code: translated at the plugin boundary
        raise PluginError(f"{who} failed in columns(): {type(exc).__name__}: {exc}") from exc
    out: dict[str, np.ndarray] = {}
    for p in eff.parameters:
        if p.name not in cols:
            raise PluginError(f"{who}: columns() returned no column for parameter {p.name!r}")
        col = np.asarray(cols[p.name], dtype=float)
        if col.shape != inputs.alpha_dps2.shape or not np.all(np.isfinite(col)):
            raise PluginError(f"{who}: the column of {p.name!r} must be {inputs.alpha_dps2.size} "
                              "finite values, one per sample")
        out[p.name] = col
    return out


def forward(installed: InstalledEffect, inputs: EffectInputs,
            parameters: Mapping[str, float]) -> np.ndarray:
    """A plugin's :meth:`Effect.forward`, checked like :func:`evaluate_columns`."""
    who = (f"effect plugin {installed.name!r} from distribution "
           f"{installed.distribution!r}")
    try:
        term = np.asarray(installed.effect.forward(inputs, parameters), dtype=float)
    except Exception as exc:  # vendor code: translated at the plugin boundary
        raise PluginError(f"{who} failed in forward(): {type(exc).__name__}: {exc}") from exc
    if term.shape != inputs.alpha_dps2.shape or not np.all(np.isfinite(term)):
        raise PluginError(f"{who}: forward() must return {inputs.alpha_dps2.size} finite "
                          "values, one per sample")
    return term


def design_columns(tokens: Iterable[str], inputs: EffectInputs,
                   shapes: Mapping[str, Mapping[str, float]]) -> dict[str, np.ndarray]:
    """Columns (per :func:`column_name`) of the plugin effects switched on among ``tokens``.

    ``shapes`` maps an effect to its current shape-parameter values (its bounds' midpoint
    when absent). Units per :attr:`Effect.enters`, per unit of each linear parameter.
    """
    out: dict[str, np.ndarray] = {}
    for n in plugin_names(tokens):
        installed = load_effect(n)
        shape = dict(shapes.get(n, {}))
        for p in installed.effect.shape_parameters:
            shape.setdefault(p.name, 0.5 * (float(p.lower or 0.0) + float(p.upper or 0.0)))
        for name, col in evaluate_columns(installed, inputs, shape).items():
            out[column_name(n, name)] = col
    return out


__all__ = ["BUILTIN_EFFECTS", "EFFECT_DOMAINS", "Effect", "EffectInputs", "EffectParameter",
           "Excitation", "InstalledEffect", "column_name", "design_column_names", "design_columns",
           "evaluate_columns", "forward", "installed_effects", "load_effect", "plugin_names",
           "refresh", "spec_token", "validate_declaration"]
