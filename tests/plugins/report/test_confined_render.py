"""Hostile report templates fail fast: capped widths and powers, then CPU and memory limits.

Each case is a template a lab could ship (``aatest report --template DIR``); each must end in a
TemplateError (exit 2) naming the template, never in minutes of CPU or gigabytes of memory.
"""

from __future__ import annotations

import re
import resource
from pathlib import Path
from typing import Any

import pytest

from aatest.plugins.report.confined import render_confined
from aatest.plugins.report.html import CalibrationCertificate
from aatest.plugins.report.sandbox import TemplateSecurityError, render_template

#: refused by the sandbox's caps before anything large is built
CAPPED = {
    "power-of-powers": "{{ ((10**999)**999)**999 }}",
    "center": "{{ 'x'|center(2e9) }}",
    "percent-format-filter": "{{ '%2000000000d'|format(1) }}",
    "percent-operator": "{{ '%2000000000d' % 1 }}",
    "star-width": "{{ '%*d'|format(2000000000, 1) }}",
    "brace-format": "{{ '{:2000000000}'.format(1) }}",
    "nested-brace-format": "{{ '{:{}}'.format(1, 2000000000) }}",
    "ljust": "{{ 'x'.ljust(2000000000) }}",
    "zfill": "{{ '1'.zfill(2000000000) }}",
    "indent": "{{ 'a\\nb'|indent(2000000000) }}",
    "wordwrap": "{{ 'a b'|wordwrap(2000000000) }}",
    "batch-fill": "{{ [1]|batch(2000000000, 0)|list }}",
    "slice": "{{ [1]|slice(2000000000)|list }}",
}


def _lab(tmp_path: Path, source: str) -> Path:
    lab = tmp_path / "lab"
    lab.mkdir(exist_ok=True)
    (lab / "evil.html.j2").write_text(source)
    return lab


@pytest.mark.parametrize("name", list(CAPPED), ids=list(CAPPED))
def test_capped_template_is_refused(tmp_path: Path, name: str) -> None:
    lab = _lab(tmp_path, f"<p>{CAPPED[name]}</p>")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with pytest.raises(TemplateSecurityError) as info:
        render_template("evil.html.j2", {}, lab)
    assert info.value.exit_code == 2 and "evil.html.j2" in str(info.value)
    spent = resource.getrusage(resource.RUSAGE_CHILDREN)
    # refused by a cap, not by the 10 s CPU limit: the child's start-up is ~0.3 s of CPU
    assert spent.ru_utime - before.ru_utime < 5.0


def test_modest_widths_still_render(tmp_path: Path) -> None:
    lab = _lab(tmp_path, "{{ 'x'|center(9) }}|{{ '%5.2f'|format(3.14159) }}|{{ 2 ** 10 }}|"
                         "{{ '{:>4}'.format(7) }}|{{ 'ab'.ljust(4, '.') }}|"
                         "{{ 'abcdefghijklmnop'|truncate(8, true) }}|"
                         "{{ 1234567|string|wordwrap(3) }}")
    assert render_template("evil.html.j2", {}, lab) == \
        "    x    | 3.14|1024|   7|ab..|abcde...|123\n456\n7"


def test_endless_loops_stop_at_the_cpu_limit(tmp_path: Path) -> None:
    lab = _lab(tmp_path, "{% for i in range(100000) %}{% for j in range(100000) %}"
                         "{% endfor %}{% endfor %}")
    with pytest.raises(TemplateSecurityError, match=r"evil.html.j2.*limit of 1 s CPU"):
        render_confined("evil.html.j2", lab, {}, cpu_s=1)


def test_allocation_stops_at_the_memory_limit(tmp_path: Path) -> None:
    # 100 000 × 100 000 characters = 10 GB of output, built from widths under every cap
    lab = _lab(tmp_path, "{% set s = 'x' * 100000 %}"
                         "{% for i in range(100000) %}{{ s }}{% endfor %}")
    with pytest.raises(TemplateSecurityError, match=r"evil.html.j2.*64 MiB memory"):
        render_confined("evil.html.j2", lab, {}, cpu_s=20, memory_bytes=64 * 2**20)


def test_shipped_certificate_renders_confined(results: dict[str, Any], run_dir: Path) -> None:
    fast = CalibrationCertificate(CalibrationCertificate.Config(plots=False))
    html = fast.render(results, run_dir, None).read_text()
    assert "Calibration certificate" in html


def test_a_child_started_ahead_renders_with_the_same_limits_or_is_ended(tmp_path: Path
                                                                        ) -> None:
    from aatest.plugins.report import confined

    lab = _lab(tmp_path, "<p>{{ x }}</p>")
    with confined.prestarted():
        (_, ahead), = confined._WAITING
        assert render_confined("evil.html.j2", lab, {"x": 41 + 1}) == "<p>42</p>"
        assert ahead.returncode == 0 and not confined._WAITING  # that child answered
    with confined.prestarted():
        (_, unused), = confined._WAITING
    assert unused.returncode is not None and not confined._WAITING  # ended, not left behind
    with confined.prestarted(), pytest.raises(TemplateSecurityError, match=r"evil\.html\.j2"):
        render_confined("evil.html.j2", _lab(tmp_path, "{% for i in range(10**8) %}"
                        "{% for j in range(10**8) %}{% endfor %}{% endfor %}"), {}, cpu_s=1)
    assert not confined._WAITING


def _untimed(html: str) -> str:
    """The page without its times (the issue and generation times are those of the render)."""
    return re.sub(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", "<time>", html)


def test_a_child_started_ahead_for_a_template_renders_it_the_same(
        results: dict[str, Any], run_dir: Path, tmp_path: Path) -> None:
    """A child that compiled the shipped certificate while it waited renders the same page
    as one started at the render; it renders a lab's template, or one that does not exist
    ahead, as well."""
    from aatest.plugins.report import confined

    fast = CalibrationCertificate(CalibrationCertificate.Config(plots=False))
    cold = _untimed(fast.render(results, run_dir, None).read_text())
    with confined.prestarted("calibration-certificate.html.j2"):
        assert _untimed(fast.render(results, run_dir, None).read_text()) == cold
        assert not confined._WAITING  # the child started ahead rendered it
    with confined.prestarted("calibration-certificate.html.j2"):
        lab = _lab(tmp_path, "<p>{{ x }}</p>")
        assert render_confined("evil.html.j2", lab, {"x": 5}) == "<p>5</p>"
    with confined.prestarted("no-such.html.j2"):
        assert render_confined("evil.html.j2", lab, {"x": 6}) == "<p>6</p>"


def test_a_block_inside_another_starts_no_second_child(tmp_path: Path) -> None:
    from aatest.plugins.report import confined

    lab = _lab(tmp_path, "<p>{{ x }}</p>")
    with confined.prestarted():
        with confined.prestarted():
            assert len(confined._WAITING) == 1
            assert render_confined("evil.html.j2", lab, {"x": 7}) == "<p>7</p>"
        assert not confined._WAITING
    assert not confined._WAITING
