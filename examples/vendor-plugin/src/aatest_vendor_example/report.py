"""A vendor's report: a one-page calibration summary, written from the typed results.

aatest hands a report plugin the typed record (:class:`aatest.results.RunResults`), the same
object ``results.json`` is written from: read it by attribute (``results.verdicts``,
``results.analysis.scale_factor``), and name each quantity as
:mod:`aatest.results.quantities` does, so the page shows "Scale factor ± U V/(°/s²)", never a
field name. Values, uncertainties and verdicts are the engine's; a report never decides.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import ClassVar

from pydantic import BaseModel, ConfigDict

from aatest.results import RunResults
from aatest.results.quantities import QUANTITIES, quantity


class SummaryConfig(BaseModel):
    """Options of the summary page (the rig file's ``report`` options)."""

    model_config = ConfigDict(extra="forbid")
    #: the page's heading
    title: str = "ACME calibration summary"


def _rows(results: RunResults) -> list[str]:
    """One table row per judged quantity: its name, channel, value, limit and verdict."""
    rows = []
    for v in results.verdicts:
        q = quantity(v.quantity)
        cells = (q.name, v.channel, q.show(v.value, v.expanded_uncertainty),
                 f"±{q.show(v.limit)}", v.verdict)
        rows.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
    return rows


def _scale_factors(results: RunResults) -> list[str]:
    """The certified scale factor of every channel, with its expanded uncertainty."""
    scale, q = results.analysis.scale_factor, QUANTITIES["scale_factor"]
    shown = [(channel, q.show(entry.scale_v_per_dps2, entry.expanded_uncertainty))
             for channel, entry in (scale.items() if scale else [])]
    return [f"<li>{html.escape(channel)}: {html.escape(text)}</li>" for channel, text in shown]


class CalibrationSummary:
    """``acme-summary``: the overall verdict, the scale factors and every judged quantity."""

    Config: ClassVar[type[SummaryConfig]] = SummaryConfig

    def __init__(self, config: SummaryConfig | None = None) -> None:
        self.config = config if config is not None else SummaryConfig()

    def render(self, results: RunResults, run_dir: Path, template_dir: Path | None) -> Path:
        """Write ``run_dir/summary.html`` from the typed results and return its path."""
        unit = results.metadata.sensor
        serial = unit.serial if unit and unit.serial else "not recorded"
        page = "\n".join([
            "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
            f"<title>{html.escape(self.config.title)}</title></head><body>",
            f"<h1>{html.escape(self.config.title)}</h1>",
            f"<p>Procedure {html.escape(results.procedure)}, unit {html.escape(serial)}, "
            f"certificate {html.escape(results.certificate_number or 'not numbered')}.</p>",
            f"<p>Overall verdict: <b>{html.escape(results.overall)}</b></p>",
            "<ul>", *_scale_factors(results), "</ul>",
            "<table><tr><th>quantity</th><th>channel</th><th>value ± U</th><th>limit</th>"
            "<th>verdict</th></tr>", *_rows(results), "</table></body></html>"])
        path = Path(run_dir) / "summary.html"
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(page, encoding="utf-8")
        os.replace(tmp, path)  # never half a page
        return path
