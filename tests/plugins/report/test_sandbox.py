"""Lab templates run sandboxed: no Python internals, no files outside their folder, no bombs."""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import pytest
from matplotlib.figure import Figure

from aatest.engine.errors import InputError
from aatest.plugins.report.html import CalibrationCertificate
from aatest.plugins.report.sandbox import (
    TemplateError,
    TemplateSecurityError,
    render_template,
    vet_svg,
)

FAST = CalibrationCertificate(CalibrationCertificate.Config(plots=False))
SECRET = "TOP-SECRET-7f3a"

MALICIOUS = {
    "mro-subclasses": ("{{ ''.__class__.__mro__[1].__subclasses__() }}", TemplateSecurityError),
    "cycler-globals-os": ("{{ cycler.__init__.__globals__.os }}", TemplateSecurityError),
    "namespace-init": ("{{ namespace.__init__.__globals__['__builtins__'] }}",
                       TemplateSecurityError),
    "format-escape": ("{{ '{0.__class__}'.format(channels) }}", TemplateSecurityError),
    "mutate-results": ("{{ channels.append(1) }}", TemplateSecurityError),
    "string-bomb": ("{{ 'a' * 1000000000 }}", TemplateSecurityError),
    "power-bomb": ("{{ 10 ** 100000000 }}", TemplateSecurityError),
    "range-bomb": ("{% for i in range(10**9) %}{% endfor %}", TemplateSecurityError),
    "division-by-zero": ("{{ 1 / 0 }}", TemplateError),
    "recursion": ("{% macro r() %}{{ r() }}{% endmacro %}{{ r() }}", TemplateError),
    "include-etc-passwd": ("{% include '/etc/passwd' %}", TemplateError),
    "include-parent": ("{% include '../secret.txt' %}", TemplateError),
    "include-symlink": ("{% include 'link.txt' %}", TemplateSecurityError),
}


@pytest.fixture
def lab_dir(tmp_path: Path) -> Path:
    """A lab template folder next to a secret, with a symlink pointing at the secret."""
    (tmp_path / "secret.txt").write_text(SECRET)
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "link.txt").symlink_to(tmp_path / "secret.txt")
    return lab


@pytest.mark.parametrize("name", list(MALICIOUS), ids=list(MALICIOUS))
def test_malicious_template_is_refused(name: str, lab_dir: Path) -> None:
    source, error = MALICIOUS[name]
    (lab_dir / "evil.html.j2").write_text(f"<p>{source}</p>")
    with pytest.raises(error) as info:
        render_template("evil.html.j2", {"channels": [{"name": "v_sz"}]}, lab_dir)
    assert isinstance(info.value, InputError) and info.value.exit_code == 2
    assert "evil.html.j2" in str(info.value)
    assert SECRET not in str(info.value) and "root:" not in str(info.value)


@pytest.mark.parametrize("name", ["cycler-globals-os", "include-etc-passwd"])
def test_refused_lab_certificate_writes_no_report(name: str, lab_dir: Path,
                                                  results: dict[str, Any], run_dir: Path) -> None:
    (lab_dir / "calibration-certificate.html.j2").write_text(MALICIOUS[name][0])
    with pytest.raises(TemplateError, match=re.escape("calibration-certificate.html.j2")):
        FAST.render(results, run_dir, lab_dir)
    assert not (run_dir / "report.html").exists()


def test_lab_template_can_extend_the_shipped_base(lab_dir: Path, results: dict[str, Any],
                                                  run_dir: Path) -> None:
    (lab_dir / "calibration-certificate.html.j2").write_text(
        '{% extends "base.html.j2" %}{% block content %}<p id="lab">Lab layout: '
        "{% for c in channels %}{{ c.name }}={{ c.u.scale_factor.value|num(5) }};{% endfor %}"
        "{{ trace.operator }}</p>{% endblock %}"
    )
    html = FAST.render(results, run_dir, lab_dir).read_text()
    assert "Lab layout: v_sz=0.0040140;v_sy=0.0040104;v_sx=0.0040068;" in html
    assert "A. Tester &lt;script&gt;" in html  # autoescape applies to lab templates too


def test_missing_lab_template_names_the_file(lab_dir: Path, results: dict[str, Any],
                                             run_dir: Path) -> None:
    with pytest.raises(TemplateError, match=re.escape("no calibration-certificate.html.j2")):
        FAST.render(results, run_dir, lab_dir)
    with pytest.raises(TemplateError, match="does not exist"):
        FAST.render(results, run_dir, lab_dir / "nope")


def test_syntax_error_has_file_and_line(lab_dir: Path) -> None:
    (lab_dir / "x.html.j2").write_text("line one\n{% if %}\n")
    with pytest.raises(TemplateError, match=r"x\.html\.j2:2:"):
        render_template("x.html.j2", {}, lab_dir)


def _matplotlib_svg() -> str:
    fig = Figure(figsize=(2, 1))
    fig.subplots().plot([0, 1], [1, 0])
    buffer = io.StringIO()
    fig.savefig(buffer, format="svg")
    return buffer.getvalue()


def test_matplotlib_svg_passes_vetting() -> None:
    vetted = vet_svg(_matplotlib_svg())
    assert str(vetted).startswith("<svg") and "withheld" not in vetted


BAD_SVG = {
    "script": '<svg xmlns="http://www.w3.org/2000/svg"><script>alert(1)</script></svg>',
    "onload": '<svg xmlns="http://www.w3.org/2000/svg" onload="alert(1)"/>',
    "foreign": '<svg xmlns="http://www.w3.org/2000/svg"><foreignObject><p>x</p></foreignObject></svg>',
    "external-href": ('<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink">'
                      '<use xlink:href="http://evil.example/x.svg#a"/></svg>'),
    "css-import": '<svg xmlns="http://www.w3.org/2000/svg"><style>@import "http://evil";</style></svg>',
    "entity": '<!DOCTYPE svg [<!ENTITY x SYSTEM "file:///etc/passwd">]><svg>&x;</svg>',
    "not-svg": "<html><body>hi</body></html>",
    "broken": "<svg><g></svg>",
}


@pytest.mark.parametrize("name", list(BAD_SVG), ids=list(BAD_SVG))
def test_unsafe_svg_is_withheld(name: str) -> None:
    vetted = str(vet_svg(BAD_SVG[name]))
    assert vetted.startswith('<p class="withheld">figure withheld:')
    assert "alert" not in vetted and "evil" not in vetted and "passwd" not in vetted


def test_shipped_templates_compile_once_per_process_and_a_labs_at_each_load(
        lab_dir: Path) -> None:
    """The shipped sandbox keeps what it compiled (the run's preflight compiles the template
    its render takes); a lab's directory is read anew at each load, so its edits show."""
    from aatest.plugins.report.sandbox import load_template

    first = load_template("frequency-response.html.j2")
    assert load_template("frequency-response.html.j2") is first
    (lab_dir / "page.html.j2").write_text("<p>one</p>")
    assert load_template("page.html.j2", lab_dir).render() == "<p>one</p>"
    (lab_dir / "page.html.j2").write_text("<p>two</p>")
    assert load_template("page.html.j2", lab_dir).render() == "<p>two</p>"


def test_compile_ahead_compiles_the_templates_a_template_references() -> None:
    """What a render process started ahead compiles while it waits: the template, and those
    it extends, imports and includes (compiled at the render otherwise)."""
    from aatest.plugins.report.sandbox import _shipped_environment, compile_ahead

    env = _shipped_environment()
    env.cache.clear()  # type: ignore[union-attr]
    compile_ahead("frequency-response.html.j2")
    cached = {name for _, name in env.cache}  # type: ignore[union-attr]
    assert cached == {"frequency-response.html.j2", "base.html.j2", "macros.html.j2",
                      "sections.html.j2", "style.css"}  # the base inlines the style sheet
    compile_ahead("no-such-template.html.j2")  # left to the render, which names it
    with pytest.raises(TemplateError, match="no-such-template"):
        render_template("no-such-template.html.j2", {})
