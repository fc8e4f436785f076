"""The sandboxed Jinja2 environment every report template — ours or a lab's — renders in.

A lab may ship its own templates (``aatest report --template DIR``); they are untrusted code.
They run in an :class:`~jinja2.sandbox.ImmutableSandboxedEnvironment` with autoescape, so they
cannot reach Python internals (``__class__``, ``__globals__``…), mutate the results, or call
anything but the filters below; the loader only serves regular files inside the template
directory (no absolute paths, no ``..``, no symlinks leading out), and arithmetic that would
build huge strings or numbers is refused: repetitions over 100 000 items, integer powers over
16 384 bits, and widths over 10 000 characters in filters (``center``, ``indent``,
``wordwrap``, ``batch``, ``slice``, ``truncate``), string methods (``ljust``, ``zfill``…) and
format strings (``'%2000000000d'|format``, ``'{:9999999}'.format``). Whatever else a template
does runs under CPU and memory limits: :func:`render_loaded` renders in a child process
(:mod:`.confined`). The only way HTML enters unescaped is :func:`vet_svg`, for SVG figures,
which are parsed and checked element by element.
"""

from __future__ import annotations

import functools
import math
import re
import string
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from jinja2 import (
    ChoiceLoader,
    FileSystemLoader,
    Template,
    TemplateNotFound,
    TemplateSyntaxError,
    Undefined,
    UndefinedError,
    meta,
)
from jinja2.exceptions import SecurityError
from jinja2.exceptions import TemplateError as JinjaTemplateError
from jinja2.sandbox import ImmutableSandboxedEnvironment
from markupsafe import Markup

from aatest.plugins.report.confined import render_confined
from aatest.plugins.report.template_errors import TemplateError, TemplateSecurityError
from aatest.results.quantities import significant
from aatest.results.rounding import measurement_text

#: the shipped templates and static assets (no logic lives there)
BUILTIN_TEMPLATES = Path(__file__).resolve().parents[2] / "reports"
_MAX_REPEAT = 100_000
_MAX_EXPONENT = 1_000
#: largest integer a power may produce (Python prints integers up to 4 300 digits ≈ 14 300 bits)
_MAX_POWER_BITS = 16_384
#: widest padding, wrapping or formatting a template may ask for (a report line is < 1 000)
_MAX_WIDTH = 10_000
#: filters whose numeric arguments are widths or counts (checked against _MAX_WIDTH)
_WIDTH_FILTERS = ("center", "indent", "wordwrap", "batch", "slice", "truncate")
#: string methods whose numeric arguments are widths
_WIDTH_METHODS = frozenset({"center", "ljust", "rjust", "zfill", "expandtabs"})
_PERCENT_FIELD = re.compile(r"%(?:\([^)]*\))?[#0\- +]*(\*|\d+)?(?:\.(\*|\d+))?")
#: |values| at or above / below these print in scientific notation


class _ConfinedLoader(FileSystemLoader):
    """A :class:`FileSystemLoader` that only serves regular files inside its root."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root).resolve()
        super().__init__(str(self.root), followlinks=False)

    def get_source(self, environment: Any, template: str) -> Any:
        source, filename, uptodate = super().get_source(environment, template)
        resolved = Path(filename).resolve()
        if not resolved.is_relative_to(self.root) or not resolved.is_file():
            raise SecurityError(f"template {template!r} resolves outside {self.root}")
        return source, filename, uptodate


def _check_width(value: Any, what: str) -> None:
    """Refuse a numeric width or count over :data:`_MAX_WIDTH` (bools are not numbers here)."""
    if isinstance(value, int | float) and not isinstance(value, bool) and (
        not math.isfinite(value) or abs(value) > _MAX_WIDTH
    ):
        raise SecurityError(f"{what} of {value} exceeds {_MAX_WIDTH}")


def _check_percent_format(text: str) -> None:
    """Refuse ``%`` conversions with huge or ``*`` widths/precisions."""
    for width, precision in _PERCENT_FIELD.findall(text):
        for part in (width, precision):
            if part == "*":
                raise SecurityError("'*' widths in % formats are refused")
            if part:
                _check_width(int(part), "format width")


def _check_brace_format(text: str) -> None:
    """Refuse ``str.format`` specs with nested fields or huge widths/precisions."""
    try:
        fields = list(string.Formatter().parse(text))
    except ValueError:
        return  # str.format raises the same error when called
    for _literal, _field, spec, _conversion in fields:
        if spec and "{" in spec:
            raise SecurityError("nested fields in format specs are refused")
        for number in re.findall(r"\d+", spec or ""):
            _check_width(int(number), "format width")


def _capped_filter(name: str, function: Callable[..., Any]) -> Callable[..., Any]:
    """``function`` (a Jinja filter) refusing numeric arguments over :data:`_MAX_WIDTH`."""

    skip = 2 if getattr(function, "jinja_pass_arg", None) is not None else 1  # (env,) value

    @functools.wraps(function)  # keeps jinja_pass_arg (environment/context filters)
    def capped(*args: Any, **kwargs: Any) -> Any:
        for value in (*args[skip:], *kwargs.values()):
            _check_width(value, f"{name} argument")
        return function(*args, **kwargs)

    return capped


def _checked_format(value: Any, *args: Any, **kwargs: Any) -> str:
    """Jinja's ``format`` filter (``value % args``) with the format's widths checked."""
    from jinja2.filters import do_format

    _check_percent_format(str(value))
    return do_format(value, *args, **kwargs)


class _ReportEnvironment(ImmutableSandboxedEnvironment):
    """Immutable sandbox that also refuses repetitions, powers and widths that exhaust memory."""

    intercepted_binops = frozenset({"*", "**", "%"})

    def wrap_str_format(self, value: Any) -> Callable[..., str] | None:
        """``str.format``/``format_map`` as Jinja sandboxes them, with their widths checked."""
        wrapped = super().wrap_str_format(value)
        if wrapped is not None:
            _check_brace_format(value.__self__)
        return wrapped

    def call(__self, __context: Any, __obj: Any, *args: Any, **kwargs: Any) -> Any:  # noqa: N805
        """Call from the template; string padding methods have their widths checked."""
        if isinstance(getattr(__obj, "__self__", None), str) and \
                getattr(__obj, "__name__", "") in _WIDTH_METHODS:
            for value in (*args, *kwargs.values()):
                _check_width(value, f"{__obj.__name__} width")
        return super().call(__context, __obj, *args, **kwargs)

    def unsafe_undefined(self, obj: Any, attribute: str) -> Any:
        """Refuse at once (Jinja's default renders an empty string until the value is used)."""
        kind = type(obj).__name__
        raise SecurityError(f"access to attribute {attribute!r} of a {kind} is unsafe")

    def call_binop(self, context: Any, operator: str, left: Any, right: Any) -> Any:
        """Apply an intercepted operator after checking what it would build."""
        if operator == "**" and isinstance(right, (int, float)) and abs(right) > _MAX_EXPONENT:
            raise SecurityError(f"exponent {right} exceeds {_MAX_EXPONENT}")
        if operator == "**" and isinstance(left, int) and isinstance(right, int) and right > 0 \
                and left.bit_length() * right > _MAX_POWER_BITS:
            raise SecurityError(f"a power of {left.bit_length() * right} bits exceeds "
                                f"{_MAX_POWER_BITS}")
        if operator == "%" and isinstance(left, str):
            _check_percent_format(left)
        if operator == "*":
            for seq, count in ((left, right), (right, left)):
                if isinstance(seq, (str, list, tuple)) and isinstance(count, int) \
                        and len(seq) * count > _MAX_REPEAT:
                    raise SecurityError(f"repetition to {len(seq) * count} items refused")
        return super().call_binop(context, operator, left, right)


def _as_float(value: Any) -> float | None:
    """A finite float, or None for missing keys (Undefined), None, NaN and non-numbers."""
    if isinstance(value, Undefined | bool):
        return None
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _num(value: Any, digits: int = 4) -> str:
    """``digits`` significant figures; '—' for missing values."""
    return significant(_as_float(value), digits)


def _fixed(value: Any, decimals: int = 3) -> str:
    """Fixed-point with ``decimals`` places; '—' for missing values."""
    f = _as_float(value)
    return "—" if f is None else f"{f:.{decimals}f}"


def _measurement(value: Any, u: Any = None, unit: str = "", digits: int = 6) -> str:
    """``value ± U unit`` rounded per GUM 7.2.6 (:mod:`aatest.results.rounding`); '—' when
    missing, ``< x`` when the value is below the resolution U allows."""
    return measurement_text(_as_float(value), _as_float(u), str(unit), digits=int(digits))


def make_environment(template_dir: Path | None = None) -> ImmutableSandboxedEnvironment:
    """The sandbox: a lab's ``template_dir`` first (may override), the shipped templates after."""
    loaders = [_ConfinedLoader(BUILTIN_TEMPLATES)]
    if template_dir is not None:
        template_dir = Path(template_dir)
        if not template_dir.is_dir():
            raise TemplateError(f"{template_dir}: template directory does not exist")
        loaders.insert(0, _ConfinedLoader(template_dir))
    env = _ReportEnvironment(
        loader=ChoiceLoader(loaders), autoescape=True, trim_blocks=True, lstrip_blocks=True,
    )
    env.filters.update(num=_num, fixed=_fixed, format=_checked_format, measurement=_measurement)
    env.filters.update({name: _capped_filter(name, env.filters[name]) for name in _WIDTH_FILTERS})
    env.template_dir = template_dir  # type: ignore[attr-defined]  # for render_loaded's child
    for name in ("lipsum", "joiner"):  # nothing a report needs
        env.globals.pop(name, None)
    return env


#: failures a template's own expressions can cause (1/0, bad types, deep recursion)
_TEMPLATE_RUNTIME_ERRORS = (ArithmeticError, TypeError, ValueError, LookupError, AttributeError,
                            RecursionError)


def _translated(where: str, exc: BaseException) -> TemplateError:
    if isinstance(exc, (SecurityError, OverflowError)):  # sandbox limits, range() bombs
        return TemplateSecurityError(f"{where}: template refused by the sandbox: {exc}")
    if isinstance(exc, TemplateNotFound):
        return TemplateError(f"{where}: template not found: {exc.name}")
    if isinstance(exc, TemplateSyntaxError):
        return TemplateError(f"{exc.filename or where}:{exc.lineno}: {exc.message}")
    if isinstance(exc, UndefinedError):
        return TemplateError(f"{where}: {exc.message}")
    if isinstance(exc, JinjaTemplateError):
        return TemplateError(f"{where}: {exc}")
    return TemplateError(f"{where}: template failed: {type(exc).__name__}: {exc}")


@functools.lru_cache(maxsize=1)
def _shipped_environment() -> ImmutableSandboxedEnvironment:
    """The sandbox of the shipped templates alone, made once per process.

    Why: Jinja keeps the templates an environment compiled (≈ 0.1 s of CPU for the
    certificate) and reloads one only when its file's time changes; so the render of a run
    takes the template its preflight compiled (``aatest run``: the plan's checks load it),
    and a render process started ahead compiles it before its request comes
    (:func:`.confined.prestarted`). A lab's ``template_dir`` gets a new sandbox at each load:
    a file added there later must override the shipped one it shadows.
    """
    return make_environment()


def load_template(name: str, template_dir: Path | None = None) -> Template:
    """Find and compile ``name`` (a lab's ``template_dir`` must contain it) before any work."""
    env = make_environment(template_dir) if template_dir is not None else _shipped_environment()
    if template_dir is not None and not (Path(template_dir) / name).is_file():
        raise TemplateError(f"{template_dir}: no {name} in the lab template directory")
    try:
        return env.get_template(name)
    except (SecurityError, JinjaTemplateError) as exc:
        raise _translated(f"{template_dir or BUILTIN_TEMPLATES}/{name}", exc) from exc


def compile_ahead(name: str) -> None:
    """Compile the shipped template ``name`` and those it extends, imports and includes, in
    this process's sandbox of the shipped templates (:func:`_shipped_environment` keeps
    them): what a render process does while it waits for its request
    (:func:`.confined.prestarted`). Jinja compiles a referenced template at the render
    otherwise (the frequency-response report's render: ≈ 70 ms, 9 ms compiled ahead). A
    template that does not load is left to the render, which names the error."""
    env = _shipped_environment()
    names, seen = [name], {name}
    while names:
        current = names.pop()
        try:
            env.get_template(current)
            source = env.loader.get_source(env, current)[0]  # type: ignore[union-attr]
            referenced = meta.find_referenced_templates(env.parse(source))
        except (SecurityError, JinjaTemplateError):
            continue
        for other in referenced:
            if other is not None and other not in seen:
                seen.add(other)
                names.append(other)


def render_loaded(template: Template, context: Mapping[str, Any]) -> str:
    """Render a template from :func:`load_template` in a child process with CPU and memory
    limits (:func:`.confined.render_confined`); refusals and limits become aatest errors."""
    template_dir = getattr(template.environment, "template_dir", None)
    return render_confined(str(template.name), template_dir, context)


def render_in_process(template: Template, context: Mapping[str, Any]) -> str:
    """Render in this process (the child of :func:`render_loaded`); errors become aatest's."""
    try:
        return template.render(dict(context))
    except (SecurityError, JinjaTemplateError, *_TEMPLATE_RUNTIME_ERRORS) as exc:
        raise _translated(str(template.filename or template.name), exc) from exc


def render_template(name: str, context: Mapping[str, Any], template_dir: Path | None = None) -> str:
    """Load and render template ``name`` in the sandbox."""
    return render_loaded(load_template(name, template_dir), context)


_SVG_NS = "{http://www.w3.org/2000/svg}"
_ALLOWED_TAGS = frozenset({
    "svg", "g", "defs", "clipPath", "use", "path", "rect", "circle", "ellipse", "line", "polyline",
    "polygon", "text", "tspan", "title", "desc", "style", "metadata", "image", "linearGradient",
    "radialGradient", "stop", "pattern", "mask", "symbol", "marker",
    # matplotlib's RDF metadata block
    "RDF", "Work", "type", "date", "format", "creator", "Agent",
})
_BAD_CSS = re.compile(r"@import|expression\s*\(|url\(\s*['\"]?(?!#)", re.IGNORECASE)
_PROLOG = re.compile(r"^\s*(<\?xml[^>]*\?>\s*)?(<!DOCTYPE[^>]*>\s*)?", re.IGNORECASE)


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _attribute_problem(name: str, value: str) -> str | None:
    """Why an SVG attribute is not plain drawing (None when it is)."""
    if name.startswith("on"):
        return f"event attribute {name} is not allowed"
    if name == "href" and not value.startswith(("#", "data:image/png")):
        return "external references are not allowed"
    if name == "style" and _BAD_CSS.search(value):
        return "external CSS in a style attribute"
    return None


def _svg_problem(root: ET.Element) -> str | None:
    if _local(root.tag) != "svg":
        return f"root element is <{_local(root.tag)}>, not <svg>"
    for element in root.iter():
        tag = _local(element.tag)
        if tag not in _ALLOWED_TAGS:
            return f"element <{tag}> is not allowed"
        for attr, value in element.attrib.items():
            problem = _attribute_problem(_local(attr).lower(), value)
            if problem is not None:
                return problem
        if tag == "style" and _BAD_CSS.search(element.text or ""):
            return "external CSS in a <style> element"
    return None


def vet_svg(svg: str) -> Markup:
    """Return an SVG figure as :class:`Markup` if it is plain drawing, else a visible notice.

    Figures come from our matplotlib code or from ``results.json`` (which a user can edit),
    so they are parsed and checked: only drawing elements, no scripts, event handlers,
    ``foreignObject``, entity declarations or external references.
    """
    body = _PROLOG.sub("", str(svg), count=1)
    problem = "entity declarations are not allowed" if "<!ENTITY" in body.upper() else None
    if problem is None:
        try:
            problem = _svg_problem(ET.fromstring(body))
        except ET.ParseError as exc:
            problem = f"not well-formed SVG ({exc})"
    if problem is not None:
        return Markup('<p class="withheld">figure withheld: {}</p>').format(problem)
    return Markup(body)
