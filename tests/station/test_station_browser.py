"""The station in a real browser: run, watch, answer prompts, abort and resume."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from station_process import Station, shot

pytestmark = pytest.mark.browser

#: the step of ``quick-sine-hold`` the operator's check comes before
HELD = "s002-sine-inner-1.9531Hz-100dps2"


def _open(page: Any, station: Station, procedure_id: str) -> None:
    page.goto(station.url)
    page.wait_for_function("document.getElementById('role').textContent.includes('control')")
    page.select_option("#procedure", procedure_id)
    page.click("#validate")
    page.wait_for_selector(f"#plan[data-procedure='{procedure_id}'] tbody tr")


def _only_run(station: Station) -> Path:
    (run,) = [d for d in station.runs.iterdir() if (d / "run_state.json").is_file()]
    return run


def test_scale_factor_from_the_page_shows_the_verdict(station: Station, page: Any) -> None:
    _open(page, station, "lab/quick-scale-factor.yaml")
    assert page.locator("#plan tbody tr").count() == 1
    shot(page, "scale-factor-validated")
    page.click("#start")
    page.wait_for_selector("#verdict:has-text('Verdict')", timeout=120_000)
    shot(page, "scale-factor-verdict")
    results = json.loads((_only_run(station) / "results.json").read_text())
    scale = results["analysis"]["scale_factor"]["v_sz"]["scale_v_per_dps2"]
    assert scale == pytest.approx(0.004014, rel=0.01)  # the twin's sensor: nominal within 1 %
    # a twin run is a simulation, and the verdict says so (issue 23)
    assert page.locator("#verdict").inner_text() == (
        "Verdict: PASS — Simulation report — not a calibration certificate")
    verdicts = page.locator("#verdicts").inner_text()
    assert "Scale-factor deviation from nominal" in verdicts  # the quantity's name and unit
    assert "scale_factor_deviation_pct" not in verdicts and " %" in verdicts
    assert page.locator("#links a[href$='report.html']").count() == 1
    report = page.locator("#links a[href$='report.html']").get_attribute("href")
    assert page.request.get(station.url + report).ok


def test_plots_update_step_by_step(station: Station, page: Any) -> None:
    # the twin records a step faster than the browser polls, so the page's event log, not a
    # race against the sample counter, shows the order: each step's samples are plotted after
    # it starts and before the next one does, and the point count grows with each step
    _open(page, station, "lab/quick-sine-3-steps.yaml")
    page.click("#start")
    page.wait_for_selector("#verdict", state="visible", timeout=120_000)
    shot(page, "live-plot")
    assert page.locator("#plot-table canvas").count() == 1
    assert page.locator("#plot-daq canvas").count() == 1
    log = page.evaluate("state.log")
    running = [e["id"] for e in log if e["type"] == "step" and e["state"] == "running"]
    assert len(running) == 3
    order = [(e["type"], e["id"]) for e in log if e["type"] in ("step", "samples")
             and (e["type"] == "samples" or e["state"] == "running")]
    expected = [entry for step in running for entry in (("step", step), ("samples", step))]
    assert order == expected
    counts = [e["received"] for e in log if e["type"] == "samples"]
    assert counts[0] > 0 and counts == sorted(set(counts))
    assert int(page.locator("#sample-count").inner_text()) == counts[-1]
    # the plot now holds the last step, s003 (3.9062 Hz at 100 °/s²): the plotted table
    # position swings by the commanded 0.1660°, the sensor about its 2.5 V bias by
    # 100 °/s² × 4.014 mV/(°/s²) = 0.4014 V
    position = page.evaluate("state.plots.tdata[1]")
    assert max(map(abs, position)) == pytest.approx(0.1660, rel=0.03)
    volts = page.evaluate("state.plots.ddata[1]")
    assert max(volts) == pytest.approx(2.5 + 0.4014, abs=0.05)
    assert min(volts) == pytest.approx(2.5 - 0.4014, abs=0.05)


def test_prompts_of_a_pivoted_misalignment_answered_in_the_page(
    station: Station, page: Any
) -> None:
    _open(page, station, "lab/quick-pivoted-misalignment.yaml")
    page.fill("#operator", "Ada Operator")
    page.click("#start")
    for step, orientation in (("s001-mis-A-e1-inner-r1", "original orientation"),
                              ("s002-mis-B-e4-inner-r1", "pivoted 180°")):
        page.wait_for_selector(f"#prompt-step:has-text('{step}')")
        assert orientation in page.locator("#prompt-sensors").inner_text()
        shot(page, f"prompt-{step}")
        page.click("#continue")
    page.wait_for_selector("#verdict", state="visible", timeout=120_000)
    shot(page, "misalignment-finished")
    state = json.loads((_only_run(station) / "run_state.json").read_text())
    assert [a["step_id"] for a in state["prompt_answers"]] == [
        "s001-mis-A-e1-inner-r1", "s002-mis-B-e4-inner-r1"]
    assert {a["answered_by"] for a in state["prompt_answers"]} == {"Ada Operator"}
    assert {a["via"] for a in state["prompt_answers"]} == {"station"}
    results = json.loads((_only_run(station) / "results.json").read_text())
    assert results["metadata"]["prompt_answers"] == state["prompt_answers"]
    assert results["metadata"]["confirm_prompts"] == "station"


def test_abort_a_held_step_then_resume(station: Station, page: Any) -> None:
    # the twin records a step in well under a second: the run is held at the operator's check
    # before s002, where Abort is pressed
    _open(page, station, "lab/quick-sine-hold.yaml")
    page.click("#start")
    page.wait_for_selector(
        "#steps li[data-id='s001-sine-inner-0.9766Hz-100dps2'][data-state='done']")
    page.wait_for_selector(f"#prompt-step:has-text('{HELD}')")
    page.wait_for_function("Number(document.getElementById('sample-count').textContent) > 0"
                           " && document.getElementById('current').textContent.startsWith('s002')")
    page.click("#abort")
    page.wait_for_selector("#stopped", state="visible")
    shot(page, "aborted")
    assert "aborted" in page.locator("#stopped-text").inner_text()
    run = _only_run(station)
    state = json.loads((run / "run_state.json").read_text())
    assert not state["finished"]
    kept = sorted(p.name for p in run.rglob("*.mcap"))
    assert len(kept) == 1 and "s001" in kept[0]  # only the completed step is on disk
    page.click("#resume")
    page.wait_for_selector(f"#prompt-step:has-text('{HELD}')")  # not confirmed: asked again
    page.click("#continue")
    page.wait_for_selector("#verdict", state="visible", timeout=120_000)
    shot(page, "resumed-finished")
    results = json.loads((run / "results.json").read_text())
    assert [s["id"] for s in results["steps"]] == [
        "s001-sine-inner-0.9766Hz-100dps2", "s002-sine-inner-1.9531Hz-100dps2",
        "s003-sine-inner-3.9062Hz-100dps2"]


def test_upload_a_bad_then_a_good_procedure_and_start_it(
    station: Station, page: Any, tmp_path: Path
) -> None:
    """A bad file shows its FILE:LINE:COLUMN lines; a good one its steps, and it runs."""
    page.goto(station.url)
    page.wait_for_function("document.getElementById('role').textContent.includes('control')")
    broken = Path(__file__).parents[1] / "data" / "procedures" / "broken-unknown-key.yaml"
    page.set_input_files("#upload", str(broken))
    page.wait_for_selector("#problems li")
    problems = page.locator("#problems li").all_inner_texts()
    assert problems[0].startswith("broken-unknown-key.yaml:8:7: steps.0.sine.amplitde_deg:")
    assert page.locator("#plan tbody tr").count() == 0
    assert "not valid" in page.locator("#upload-state").inner_text()
    shot(page, "upload-rejected")
    good = tmp_path / "my-scale-factor.yaml"
    good.write_text((station.lab / "quick-scale-factor.yaml").read_text())
    page.set_input_files("#upload", str(good))
    page.wait_for_selector("#plan[data-procedure^='upload/my-scale-factor.'] tbody tr")
    assert page.locator("#problems li").count() == 0
    assert page.locator("#plan tbody tr").count() == 1
    assert "sine" in page.locator("#plan tbody").inner_text()
    chosen = page.locator("#procedure").input_value()
    assert chosen.startswith("upload/my-scale-factor.") and chosen.endswith(".yaml")
    shot(page, "upload-validated")
    page.click("#start")
    page.wait_for_selector("#verdict:has-text('Verdict')", timeout=120_000)
    # a twin run is a simulation, and the verdict says so (issue 23)
    assert page.locator("#verdict").inner_text() == (
        "Verdict: PASS — Simulation report — not a calibration certificate")
    stored = station.runs / ".station" / "uploads" / chosen.removeprefix("upload/")
    assert stored.read_text() == good.read_text()
    results = json.loads((_only_run(station) / "results.json").read_text())
    assert results["procedure"] == "quick-scale-factor"
