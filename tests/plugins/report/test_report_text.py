"""What a person reads: no results.json field name, Python repr or docs path on any report.

Every shipped procedure (its short variant in ``tests/results/data``: the same analyses and
report template) is run on the twin and its report rendered; the visible text (tags, figures
and the verbatim procedure file left out) must name every quantity as the quantity registry
does. A field name is any key of the result models (``scale_v_per_dps2``, ``delta_e_deg``…);
a Python repr is ``True``/``False``/``None`` or a quoted ``{'…`` / ``['…``; a docs path is
``docs/…`` or ``….md``.
"""

from __future__ import annotations

import html
import re
from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel, RootModel

from aatest.engine.run.session import run
from aatest.results import RunResults
from aatest.results.quantities import ANALYSES, QUANTITIES

DATA = Path(__file__).resolve().parents[2] / "results" / "data"
PROCEDURES = ("long-static-drift", "pivoted-misalignment", "scale-factor",
              "static-multi-position", "stepped-sine-frequency-response", "temperature-steps")
REPR = re.compile(r"\b(True|False|None)\b|\{'|\['|'\]|'\}")
DOCS = re.compile(r"docs/|\b\w+\.md\b")
SNAKE = re.compile(r"\b[a-z][a-z0-9]*(?:_[a-z0-9]+)+\b")


def _field_names(model: Any, seen: set[Any] | None = None) -> set[str]:
    """Every field name of a pydantic model and the models nested in it (snake_case ones)."""
    seen = seen if seen is not None else set()
    if not isinstance(model, type) or model in seen:
        return set()
    seen.add(model)
    names: set[str] = set()
    if issubclass(model, BaseModel):
        for name, info in model.model_fields.items():
            names.add(name)
            names |= _annotation_fields(info.annotation, seen)
    return names


def _annotation_fields(annotation: Any, seen: set[Any]) -> set[str]:
    found: set[str] = set()
    if isinstance(annotation, type) and issubclass(annotation, BaseModel | RootModel):
        found |= _field_names(annotation, seen)
        for base in annotation.__mro__:  # PerChannel[T]: the channel model is a parameter
            for arg in getattr(base, "__pydantic_generic_metadata__", {}).get("args", ()):
                found |= _annotation_fields(arg, seen)
    for arg in getattr(annotation, "__args__", ()) or ():
        found |= _annotation_fields(arg, seen)
    return found


#: the names a report must not show: result fields, quantity and analysis keys
FIELDS = {n for n in _field_names(RunResults) | set(QUANTITIES) | set(ANALYSES) if "_" in n}


def visible_text(page: str) -> str:
    """The text a reader sees: no markup, figures, styles or the verbatim procedure file."""
    page = re.sub(r"<svg.*?</svg>|<style.*?</style>|<head>.*?</head>", " ", page, flags=re.S)
    page = re.sub(r"<details><summary>procedure text</summary>.*?</details>", " ", page,
                  flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", " ", page))


def leaks(text: str, channels: frozenset[str] = frozenset()) -> list[str]:
    """Each field name or other snake_case identifier (a sensor channel's own name, e.g.
    ``v_sz``, excepted), Python repr and docs path in ``text``, with a little context."""
    found = [m for m in SNAKE.finditer(text) if m.group(0) not in channels]
    found += list(REPR.finditer(text)) + list(DOCS.finditer(text))
    return [f"{m.group(0)!r} in …{text[max(m.start() - 40, 0):m.end() + 40]}…" for m in found]


def test_the_field_list_knows_the_nested_models() -> None:
    assert {"scale_v_per_dps2", "delta_e_deg", "gain_expanded_uncertainty_db", "drift_ppm",
            "scale_factor_deviation_pct", "transfer_function"} <= FIELDS


def test_leaks_are_found() -> None:
    shown = "bias_v 2.5 V; rig: {'plugin': 'sim'}; see docs/method.md; coherent True"
    assert len(leaks(shown)) == 6  # bias_v, {', '}, docs/, method.md, True
    shown = "Scale factor v_sz: 4.01390e-03 V/(°/s²), Bias deviation from nominal"
    assert leaks(shown, frozenset({"v_sz"})) == []


@pytest.mark.parametrize("name", PROCEDURES, ids=PROCEDURES)
def test_report_names_every_quantity_for_a_person(name: str, tmp_path: Path) -> None:
    run_dir, results = run(DATA / f"{name}.yaml", None, tmp_path / name, False, 7, None,
                     show_progress=False, confirm_prompts="auto")
    channels = frozenset(s.channel for s in results.metadata.sensors)
    found = leaks(visible_text((run_dir / "report.html").read_text(encoding="utf-8")), channels)
    assert not found, f"{len(found)} leaks:\n" + "\n".join(found[:25])
