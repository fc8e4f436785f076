"""One story in every output, an honest null, lines at any frequency (issue 30).

Datasets come from the foreign-dataset generator (no aatest simulation code): clean data, a
vocabulary effect, sensor-only lines at frequencies between, on and far above the
excitation's harmonics with amplitudes 2× to 10× the 1 mV sensor noise, a bias drifting with
session time, and a random-walk bias no generic model captures. Each is diagnosed through the
CLI as a user would; the terminal, ``--json`` and ``diagnosis.html`` must tell the same story,
and "the nominal model explains the data" is said only when the residual is noise.
"""

from __future__ import annotations

import html
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foreign_dataset import Hidden, write_dataset
from typer.testing import CliRunner

from aatest.cli import app
from aatest.diagnose.noise_floor import EXPLAINED_RATIO, noise_floor

#: samples per step of the default-suite cases (eight steps: a few seconds a diagnosis)
QUICK = 8192
#: "explains the data" is never said when the nominal residual is this far above the floor
NEVER_EXPLAINED_ABOVE = 1.5
NOISE_V = 0.001  # the generator's white sensor noise (RMS)
FLAT_SPLINE_HZ = 400.0  # fs/5 of the generator's 2 kHz records


@dataclass
class Run:
    """One diagnosis as a user sees it: exit code, terminal text, JSON and report text."""

    code: int
    terminal: str
    doc: dict[str, Any]
    report: str

    def report_text(self) -> str:
        """The report's visible text (tags and figures removed, entities decoded)."""
        body = re.sub(r"<svg.*?</svg>|<style.*?</style>", " ", self.report, flags=re.S)
        return html.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", body)))

    def table(self, css_class: str) -> list[list[str]]:
        """Cell texts of the report table with ``css_class`` (header row dropped)."""
        found = re.search(rf'<table class="{css_class}"[^>]*>(.*?)</table>', self.report,
                          flags=re.S)
        assert found, f"no {css_class} table in the report"
        rows = re.findall(r"<tr>(.*?)</tr>", found.group(1), flags=re.S)[1:]
        return [[html.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                 for c in re.findall(r"<td[^>]*>(.*?)</td>", r, flags=re.S)] for r in rows]


def diagnose(data: Path) -> Run:
    out = data.parent / "diagnosis.json"
    result = CliRunner().invoke(app, ["diagnose", str(data), "--json", str(out)])
    assert "Traceback" not in result.output, result.output
    report = (data.parent / "diagnosis.html").read_text(encoding="utf-8")
    return Run(result.exit_code, result.output, json.loads(out.read_text()), report)


def _headline_problems(run: Run, text: str) -> list[str]:
    """The verdict: the same sentence in all three, the right kind and exit code."""
    doc, problems = run.doc, []
    headline = doc["verdict"]["headline"]
    if headline not in run.terminal:
        problems.append("terminal headline differs from the JSON's")
    if headline not in text:
        problems.append("report headline differs from the JSON's")
    kind = doc["verdict"]["kind"]
    expected = ("findings" if doc["findings"] else "unexplained" if doc["unexplained"]
                else "explained")
    if kind != expected or run.code != (0 if kind == "explained" else 1):
        problems.append(f"verdict {kind}, exit {run.code}, expected {expected}")
    if "explains the data" in text and kind != "explained":
        problems.append("the report says 'explains the data' beside a finding")
    return problems


def _table_problems(run: Run) -> list[str]:
    """The report's unexplained, gain and per-step tables against the JSON."""
    doc, problems = run.doc, []
    rows = run.table("unexplained") if doc["unexplained"] else []
    if [r[0] for r in rows] != [u["kind"] for u in doc["unexplained"]]:
        problems.append(f"report unexplained kinds {[r[0] for r in rows]}")
    for row, u in zip(rows, doc["unexplained"], strict=False):
        gain = 100 * (1 - u["evidence"]["rmse_v_after"] / u["evidence"]["rmse_v_before"])
        if row[2] != u["description"] or float(row[5]) != pytest.approx(gain, abs=0.051):
            problems.append(f"report row {row[:3]} differs from {u['description']}")
    gain_row = run.table("gain")[0]  # num(4): 4 significant digits
    if float(gain_row[3]) != pytest.approx(doc["gain"]["rmse_v_after"], rel=1e-3):
        problems.append(f"report gain {gain_row} differs from {doc['gain']}")
    for ch, view in doc["residuals"].items():  # num(3): 3 significant digits
        extended = [float(r[3]) for r in run.table(f'per-step" data-channel="{ch}')]
        if extended != pytest.approx([r["rms_v_extended"] for r in view["per_step"]], rel=6e-3):
            problems.append(f"report per-step residuals differ on {ch}")
    return problems


def _reason_problems(run: Run, text: str) -> list[str]:
    """Every favourable candidate not accepted says why, in all three outputs."""
    problems = []
    for c in run.doc["candidates"]:
        if c.get("delta_bic") is None or c["delta_bic"] >= 0 or c["accepted"]:
            continue
        if not c.get("reason"):
            problems.append(f"favourable candidate {c['effect']} without a reason")
        elif c["reason"] not in text or c["reason"] not in run.terminal:
            problems.append(f"reason of {c['effect']} missing in the report or terminal")
    return problems


def story_problems(run: Run) -> list[str]:
    """Where the terminal, the JSON and the report disagree (empty list = one story)."""
    text = run.report_text()
    return _headline_problems(run, text) + _table_problems(run) + _reason_problems(run, text)


def _ratios(doc: dict[str, Any]) -> tuple[float, float]:
    """(nominal, final) held-out residual over the noise floor, worst channel."""
    channels = doc["noise_floor"]["channels"].values()
    return max(c["ratio_nominal"] for c in channels), max(c["ratio"] for c in channels)


def null_problems(doc: dict[str, Any]) -> list[str]:
    """An honest null: 'explained' only for a residual at the noise floor."""
    nominal, final = _ratios(doc)
    if doc["verdict"]["kind"] == "explained" and (
            final > EXPLAINED_RATIO or nominal > NEVER_EXPLAINED_ABOVE):
        return [f"explained at {nominal:.2f}× / {final:.2f}× the floor"]
    if doc["verdict"]["kind"] != "explained" and final > EXPLAINED_RATIO and not any(
            u["kind"] == "other" for u in doc["unexplained"]):
        return [f"final residual {final:.2f}× the floor without an 'other' entry"]
    return []


CASES = {"findings": Hidden("bias_temperature", 2e-4),
         "unexplained": Hidden("sensor_line", 2 * NOISE_V, 37.3),
         "explained": Hidden()}


@pytest.mark.parametrize("kind", list(CASES), ids=list(CASES))
def test_the_three_kinds_read_the_same_in_report_terminal_and_json(tmp_path: Path, kind: str
                                                                  ) -> None:
    run = diagnose(write_dataset(tmp_path / "data", CASES[kind], samples=QUICK, seed=11))
    assert run.doc["verdict"]["kind"] == kind
    assert story_problems(run) == []
    assert null_problems(run.doc) == []
    if kind == "explained":  # clean data: nothing at all, the residual at its floor
        assert run.doc["findings"] == [] and run.doc["unexplained"] == []
        assert run.code == 0
        # the held-out residual of white noise is the noise (two-fold fit: ≈ 1 + p/n)
        assert 0.95 <= _ratios(run.doc)[0] <= EXPLAINED_RATIO
    if kind == "unexplained":  # a sensor line between the harmonics, 2× the noise
        line = CASES[kind]
        assert line_problems(run, line.frequency_hz, line.value) == []
    if kind == "findings":
        assert [f["effect"] for f in run.doc["findings"]] == ["bias_temperature"]
        accepted = [r[1] for r in run.table("candidates") if r[4] == "yes"]
        assert accepted == ["bias_temperature"]


#: (frequency Hz, amplitude in units of the noise): on the harmonics of two steps (6×2 Hz,
#: 3×4 Hz, which were once dropped as motion) and far above them; a line between the
#: harmonics at 2× the noise is the three-kinds test's "unexplained" case
LINES = {"12Hz-on-harmonics-10x": (12.0, 10.0), "333.3Hz-5x": (333.3, 5.0)}


def line_problems(run: Run, f_hz: float, amp_v: float) -> list[str]:
    """The line found at its own frequency (not a bin's), its amplitude, sensor only."""
    lines = [u for u in run.doc["unexplained"] if u["kind"] == "spectral_line"]
    if not lines:
        return [f"no line in {[u['description'] for u in run.doc['unexplained']]}"]
    ext = lines[0]["extension"]
    problems = [f"wrong name {f['effect']}" for f in run.doc["findings"]]
    # bins are 2000/8192 = 0.24 Hz wide; the estimate's own scatter is ~1e-4 Hz at 2× noise
    if abs(ext["frequency_hz"] - f_hz) > 0.02:
        problems.append(f"frequency {ext['frequency_hz']:.4f} Hz, truth {f_hz}")
    # amplitude scatter ≈ σ·√(2/n) per step ≈ 0.3 % at 2× noise; the median over steps. The
    # DAQ record reaches the table grid through a cubic spline, whose response is flat to ~1 %
    # below fs/5 and falls towards Nyquist (0.71 at 777.7 Hz): above fs/5 only a lower bound
    flat = f_hz < FLAT_SPLINE_HZ
    low, high = (0.95, 1.05) if flat else (0.5, 1.05)
    if not low * amp_v <= ext["amplitude_v"] <= high * amp_v or ext["seen_by_table"]:
        problems.append(f"amplitude {ext['amplitude_v']:.4g} V / table {ext['seen_by_table']}")
    ev = lines[0]["evidence"]
    if not ev["rmse_v_after"] < ev["rmse_v_before"]:
        problems.append(f"no gain {ev}")
    return problems


@pytest.mark.parametrize("case", list(LINES), ids=list(LINES))
def test_lines_at_any_frequency_are_found_measured_and_classified(tmp_path: Path, case: str
                                                                 ) -> None:
    f_hz, times = LINES[case]
    hidden = Hidden("sensor_line", times * NOISE_V, f_hz)
    run = diagnose(write_dataset(tmp_path / "data", hidden, samples=QUICK, seed=12))
    assert line_problems(run, f_hz, times * NOISE_V) == []
    assert story_problems(run) == [] and null_problems(run.doc) == []
    assert _ratios(run.doc)[1] <= EXPLAINED_RATIO  # the line fitted, noise is left


def test_a_slow_bias_drift_is_a_trend(tmp_path: Path) -> None:
    hidden = Hidden("bias_drift", 0.3)  # V/h, with the step temperatures cycled
    run = diagnose(write_dataset(tmp_path / "data", hidden, samples=QUICK, seed=13))
    trend = [u for u in run.doc["unexplained"] if u["kind"] == "trend"]
    assert run.doc["findings"] == [] and trend
    # the pauses between steps are not in the data: the rate lies between truth and 2× truth
    assert hidden.value <= trend[0]["extension"]["bias_v_per_h"] <= 2 * hidden.value
    assert story_problems(run) == [] and null_problems(run.doc) == []


def test_a_residual_no_generic_model_fits_is_reported_not_explained(tmp_path: Path) -> None:
    """A random-walk bias: above the noise floor, but no line, straight trend or single step."""
    run = diagnose(write_dataset(tmp_path / "data", Hidden("bias_wander", 2 * NOISE_V),
                                 samples=QUICK, seed=14))
    other = [u for u in run.doc["unexplained"] if u["kind"] == "other"]
    assert run.doc["verdict"]["kind"] == "unexplained" and run.code == 1
    assert other, run.doc["unexplained"]
    where = other[0]["extension"]["where"]
    assert other[0]["extension"]["ratio"] > EXPLAINED_RATIO
    assert {"steps", "motion_state", "trend", "lines"} <= set(where)
    assert where["lines"] and where["lines"][0]["frequency_hz"] < 5.0  # a walk is slow
    assert story_problems(run) == [] and null_problems(run.doc) == []


def test_the_noise_floor_ignores_lines_and_slow_structure() -> None:
    """White noise under a strong line and a random walk: the floor is the noise alone."""
    rng = np.random.default_rng(3)
    dt_s, n = 5e-4, 8192
    t = np.arange(n) * dt_s
    residuals = {}
    for k in range(8):
        walk = np.cumsum(rng.normal(size=n))
        residuals[f"s{k}"] = (rng.normal(0.0, NOISE_V, n) + 0.01 * np.sin(2 * np.pi * 77.7 * t)
                              + 0.002 * (walk - walk.mean()) / walk.std())
    floor = noise_floor(residuals, dt_s)
    # white noise alone reads within 1 % (≈ 16 independent 64-bin median windows of ~14-dof
    # bins per step, 8 steps); the walk's 1/f² tail, above the noise over the lowest ~17 bins,
    # shifts the median windows there and adds 2–3 % (measured over seeds)
    assert floor.rms_v == pytest.approx(NOISE_V, rel=0.05)
    assert floor.ratio(float(np.sqrt(np.mean(np.concatenate(list(residuals.values())) ** 2)))) > 5


def _sweep() -> list[tuple[str, Hidden, int]]:
    """Lines over the band at 2×, 5×, 10× the noise, trends, steps, wander and clean data."""
    cases = [(f"line-{f:g}Hz-{a:g}x", Hidden("sensor_line", a * NOISE_V, f), 100 + k)
             for k, (f, a) in enumerate((f, a) for f in (3.3, 7.77, 24.0, 61.9, 151.1, 777.7)
                                        for a in (2.0, 5.0, 10.0))]
    cases += [("drift-0.2", Hidden("bias_drift", 0.2), 130), ("drift-1", Hidden("bias_drift", 1.0),
                                                               131),
              ("step-3mV", Hidden("bias_step", 0.003), 132),
              ("step-10mV", Hidden("bias_step", 0.010), 133),
              ("wander-2x", Hidden("bias_wander", 2 * NOISE_V), 134)]
    return cases + [(f"clean-{s}", Hidden(), 140 + s) for s in range(3)]


@pytest.mark.slow
def test_story_sweep(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Every case: one story, an honest null, structure reported; clean data explained."""
    failures = {}
    for name, hidden, seed in _sweep():
        run = diagnose(write_dataset(tmp_path_factory.mktemp(name) / "data", hidden,
                                     samples=QUICK, seed=seed))
        problems = story_problems(run) + null_problems(run.doc)
        explained = run.doc["verdict"]["kind"] == "explained"
        if hidden.effect is None and not explained:
            problems.append("clean data not explained")
        elif hidden.effect is not None and explained:
            problems.append("structure not reported")
        if hidden.effect == "sensor_line":
            problems += line_problems(run, hidden.frequency_hz, hidden.value)
        if problems:
            failures[name] = problems
        nominal, final = _ratios(run.doc)
        print(f"{name}: {run.doc['verdict']['kind']}, residual {nominal:.2f}× → {final:.2f}× "
              f"the floor, {'; '.join(problems) or 'correct'}", flush=True)
    print(f"\nstory sweep: {len(_sweep()) - len(failures)}/{len(_sweep())} correct")
    for name, problems in failures.items():
        print(f"  {name}: {'; '.join(problems)}")
    assert not failures
