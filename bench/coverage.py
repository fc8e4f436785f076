"""Coverage of the certified uncertainties on simulated rigs with drawn imperfections.

Each rig is the twin's realistic rig with its instrument errors drawn (seeded) within the rig
description's stated specifications (:meth:`aatest.twin.model.RigModel.draw_imperfections`:
logger gain and offset error, encoder error, lab temperature, mounting scatter). On every rig
three reduced procedures run in-process through the engine (plan → rig → runner → recording
→ analyses → uncertainty, no report): the scale-factor calibration (1 Hz, 400 °/s²), the
static multi-position test (six positions, three repetitions, original and pivoted) and a
stepped sine at three frequencies. Each certified value is compared with the true value of
the same measurand from the twin's model (:mod:`aatest.twin.truth`). Printed per quantity:
coverage (share of results whose true value lies within ±U) with its Clopper–Pearson 95 %
interval, and median U / RMS(error). Targets: coverage ≥ 95 %, median U ≤ 3 × RMS error.
The scale-factor and static procedures run on 40 rigs, the stepped sine on 120 (see
:data:`FRF_RIGS`: its phase rows lie close to the target).

    python bench/coverage.py [--rigs 40] [--frf-rigs 120] [--first-seed 1000] [--out DIR]
                             [--only stepped-sine]
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from aatest.engine.analysis.passes import run_analyses
from aatest.engine.analysis.results_file import build_results, results_json
from aatest.engine.rig_description import Instruments
from aatest.engine.run.events import RunEvents, terminal_responder
from aatest.engine.run.rig import build_rig, sensor_datasheet
from aatest.engine.run.run_state import open_state
from aatest.engine.run.runner import procedure_sha256, run_metadata, run_plan
from aatest.engine.run.session import decide, prepare
from aatest.engine.steps import SensorRef
from aatest.recording import RunRecorder, read_dataset
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.model import RigModel, dump_rig_model
from aatest.twin.truth import (
    bias_truth_v,
    frf_truth,
    g_sensitivity_truth_dps2_per_g,
    scale_factor_truth_v_per_dps2,
)

#: rigs each procedure runs on by default (the issue asks for ≥ 40)
RIGS = 40
#: rigs of the stepped sine: its phase coverage lies near the target, where 40 rigs measure it
#: to ±3.4 points (binomial standard error at 95 %) — a budget with exactly 95 % true coverage
#: shows < 95 % on 40 rigs one time in three; on 120 rigs the scatter is ±2.0 points
FRF_RIGS = 120
#: coverage target: the share of rigs whose true value lies within ±U
TARGET_COVERAGE = 0.95
#: honesty target: median U at most this many times the RMS of the actual errors
TARGET_RATIO = 3.0

#: reduced procedures: the shipped ones with shorter records (and three FRF frequencies)
PROCEDURES: dict[str, str] = {
    "scale-factor": """
procedure: coverage-scale-factor
standard: IEEE-671-style
sensor: {model: sr207, serial: "COV-1"}
sampling: {rate_hz: 2000, samples: 20000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
""",
    "static": """
procedure: coverage-static
standard: IEEE-671-style
sensor: {model: sr207-aamu, serial: "COV-2"}
sampling: {rate_hz: 2000, samples: 3000, settle_s: 0.5}
steps:
  - multi_position:
      positions: [[0, 0], [0, 180], [0, 90], [90, 90], [180, 90], [270, 90]]
      repetitions: 3
      mountings: [original, pivoted]
      original_prompt: Mount the unit in its original orientation.
      pivoted_prompt: Pivot every sensor 180° about its sensitive axis and re-mount.
analysis: [sync, bias]
""",
    "stepped-sine": """
procedure: coverage-stepped-sine
standard: IEEE-671-style
sensor: {model: sr207, serial: "COV-3"}
sampling: {rate_hz: 2000, samples: 16384, settle_s: 1}
steps:
  - sine_sweep:
      axis: inner
      frequencies: {include: [1, 4, 9], snap: coherent}
      accelerations_dps2: [100]
analysis: [sync, frf]
""",
}

#: the rig description of every simulated rig (its stated specifications, with traceability)
RIG_INSTRUMENTS: dict[str, Any] = {
    "encoder": {"accuracy_arcsec": 1.0, "cert_id": "SIM-ENC-1", "cert_date": "2026-01-12",
                "lab": "simulated"},
    "logger": {"offset_accuracy_v": 0.001, "gain_accuracy_pct": 0.1, "bits": 16,
               "range_v": [-10, 10], "cert_id": "SIM-LOG-1", "cert_date": "2026-03-01"},
    "thermometer": {"accuracy_c": 0.2, "cert_id": "SIM-T-1"},
    "lab": {"reference_temperature_c": 25.0, "temperature_tolerance_c": 3.0},
    "mounting_accuracy_deg": 0.3,
}


@dataclass(frozen=True)
class Check:
    """One certified value against its truth."""

    quantity: str
    value: float
    expanded_uncertainty: float
    truth: float

    @property
    def error(self) -> float:
        """value − truth, in the quantity's unit."""
        return self.value - self.truth

    @property
    def covered(self) -> bool:
        """The true value lies within value ± U."""
        return abs(self.error) <= self.expanded_uncertainty


def run_in_process(procedure: Path, rig_file: Path, out_dir: Path, seed: int) -> dict[str, Any]:
    """Run a procedure on the rig through the engine, analyse and decide; no report.

    Returns the results.json document (with uncertainty and verdicts).
    """
    prepared = prepare(procedure, rig_file)
    plan = prepared.plan
    state = open_state(out_dir, plan.procedure, procedure_sha256(prepared.text), seed, False)
    recorder = RunRecorder(out_dir)
    rig = build_rig(prepared.rig_config, plan.sensor, seed)
    recorder.write_run_metadata(run_metadata(plan, rig, prepared.text, seed, "coverage bench"))
    events = RunEvents(responder=terminal_responder(plan, [], "bench", "auto", False))
    run_plan(plan, rig, recorder, state, out_dir, show_progress=False, events=events)
    recorder.finalize()
    data = read_dataset(out_dir)
    analysis = run_analyses(data, list(data.metadata.get("analysis", [])))
    results = build_results(data, analysis, plan.lab_duration_s, 0.0)
    document = results_json(decide(results, data))
    (out_dir / "results.json").write_text(json.dumps(document), encoding="utf-8")
    return document


def drawn_rig(sensor_model: str, rig_seed: int, directory: Path) -> tuple[RigModel, Path]:
    """A realistic rig for the sensor with imperfections drawn by ``rig_seed``; its rig file."""
    sheet, _ = sensor_datasheet(SensorRef(model=sensor_model))
    model = realistic_rig_model(sheet).draw_imperfections(
        rig_seed, Instruments.model_validate(RIG_INSTRUMENTS))
    model_path = directory / f"model-{sensor_model}.yaml"
    dump_rig_model(model, model_path)
    rig_path = directory / f"rig-{sensor_model}.yaml"
    rig_path.write_text(json.dumps({
        "turntable": {"plugin": "sim", "model": str(model_path)},
        "daq": {"plugin": "sim", "model": str(model_path)},
        "instruments": RIG_INSTRUMENTS}), encoding="utf-8")
    return model, rig_path


def _scale_checks(doc: dict[str, Any], model: RigModel) -> Iterator[Check]:
    temperature = model.chamber.ambient_c
    for channel, entry in doc["analysis"]["scale_factor"].items():
        step = next(s for s in doc["steps"] if s["id"] in entry["steps"])
        truth = scale_factor_truth_v_per_dps2(model, channel, step["frequency_hz"],
                                              step["accel_dps2"], temperature)
        yield Check("scale factor", entry["scale_v_per_dps2"], entry["expanded_uncertainty"],
                    truth)


def _static_checks(doc: dict[str, Any], model: RigModel) -> Iterator[Check]:
    temperature = model.chamber.ambient_c
    for channel, entry in doc["analysis"]["bias"].items():
        yield Check("bias", entry["bias_v"], entry["expanded_uncertainty"],
                    bias_truth_v(model, channel, temperature))
        yield Check("g-sensitivity", entry["g_sensitivity_dps2_per_g"],
                    entry["g_sensitivity_expanded_uncertainty_dps2_per_g"],
                    g_sensitivity_truth_dps2_per_g(model, channel))


def _frf_checks(doc: dict[str, Any], model: RigModel) -> Iterator[Check]:
    temperature = model.chamber.ambient_c
    for channel, points in doc["analysis"]["frf"].items():
        for p in points:
            gain_db, phase_deg = frf_truth(model, channel, p["frequency_hz"], p["accel_dps2"],
                                           temperature)
            f = f"{p['frequency_hz']:g} Hz"
            yield Check(f"FRF gain {f}", p["gain_db"], p["gain_expanded_uncertainty_db"],
                        gain_db)
            wrapped = (p["phase_deg"] - phase_deg + 180.0) % 360.0 - 180.0
            yield Check(f"FRF phase {f}", phase_deg + wrapped, p["phase_expanded_uncertainty_deg"],
                        phase_deg)


CHECKS = {"scale-factor": _scale_checks, "static": _static_checks, "stepped-sine": _frf_checks}
#: the sensor model each procedure runs with (the rig is drawn per sensor model)
SENSOR_OF = {"scale-factor": "sr207", "static": "sr207-aamu", "stepped-sine": "sr207"}


def rig_checks(rig_seed: int, workdir: Path, only: tuple[str, ...] = ()) -> list[Check]:
    """Run the three procedures (or the ``only`` ones) on one drawn rig; every certified value
    with its truth."""
    checks: list[Check] = []
    for name, text in PROCEDURES.items():
        if only and name not in only:
            continue
        directory = workdir / f"rig{rig_seed}-{name}"
        directory.mkdir(parents=True)
        model, rig_file = drawn_rig(SENSOR_OF[name], rig_seed, directory)
        procedure = directory / "procedure.yaml"
        procedure.write_text(text, encoding="utf-8")
        doc = run_in_process(procedure, rig_file, directory / "run", seed=rig_seed)
        checks += list(CHECKS[name](doc, model))
    return checks


def rigs_per_procedure(rigs: int = RIGS, frf_rigs: int = FRF_RIGS, only: tuple[str, ...] = ()
                       ) -> dict[str, int]:
    """How many drawn rigs each procedure (or each of the ``only`` ones) runs on."""
    return {name: frf_rigs if name == "stepped-sine" else rigs for name in PROCEDURES
            if not only or name in only}


def drawn_rig_checks(first_seed: int, rigs: dict[str, int], workdir: Path) -> list[Check]:
    """Every certified value with its truth, each procedure on its number of rigs (seeds
    ``first_seed``, ``first_seed + 1``, …: a procedure on fewer rigs runs on the first ones)."""
    checks: list[Check] = []
    for seed in range(first_seed, first_seed + max(rigs.values())):
        names = tuple(n for n, count in rigs.items() if seed < first_seed + count)
        checks += rig_checks(seed, workdir, names)
    return checks


@dataclass(frozen=True)
class Row:
    """Coverage of one certified quantity over the rigs."""

    quantity: str
    n: int
    coverage: float
    median_u: float
    rms_error: float

    @property
    def ratio(self) -> float:
        """median U / RMS(error)."""
        return self.median_u / self.rms_error if self.rms_error > 0 else math.inf

    @property
    def met(self) -> bool:
        """The issue's targets: coverage ≥ 95 % and median U ≤ 3 × RMS error."""
        return self.coverage >= TARGET_COVERAGE and self.ratio <= TARGET_RATIO

    @property
    def coverage_interval(self) -> tuple[float, float]:
        """Clopper–Pearson 95 % interval of the coverage: how far the share of n rigs may lie
        from the budgets' true coverage by the draw alone (±3.4 points at 95 % on 40 rigs)."""
        covered = round(self.coverage * self.n)
        ci = stats.binomtest(covered, self.n).proportion_ci(confidence_level=0.95)
        return float(ci.low), float(ci.high)


def table(checks: list[Check]) -> list[Row]:
    """Per quantity: coverage, median U and RMS error."""
    rows = []
    for quantity in dict.fromkeys(c.quantity for c in checks):
        mine = [c for c in checks if c.quantity == quantity]
        errors = np.array([c.error for c in mine])
        rows.append(Row(quantity, len(mine), float(np.mean([c.covered for c in mine])),
                        float(np.median([c.expanded_uncertainty for c in mine])),
                        float(np.sqrt(np.mean(errors**2)))))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", type=int, default=RIGS,
                        help="rigs for the scale-factor and static procedures")
    parser.add_argument("--frf-rigs", type=int, default=FRF_RIGS,
                        help="rigs for the stepped sine (its phase rows sit near the target)")
    parser.add_argument("--first-seed", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=None, help="keep the runs here")
    parser.add_argument("--only", action="append", choices=sorted(PROCEDURES), default=[],
                        help="run only this procedure (repeatable; default: all three)")
    args = parser.parse_args()
    start = time.perf_counter()
    rigs = rigs_per_procedure(args.rigs, args.frf_rigs, tuple(args.only))
    with tempfile.TemporaryDirectory() as tmp:
        checks = drawn_rig_checks(args.first_seed, rigs, args.out or Path(tmp))
    wall = time.perf_counter() - start
    print(f"rigs per procedure {rigs} (seeds from {args.first_seed}), {len(checks)} certified "
          f"values, wall {wall:.0f} s")
    print(f"{'quantity':22s} {'n':>4s} {'coverage':>9s} {'95 % interval':>15s} {'median U':>11s} "
          f"{'RMS error':>11s} {'U/RMS':>6s}  target")
    for row in table(checks):
        low, high = row.coverage_interval
        print(f"{row.quantity:22s} {row.n:4d} {row.coverage * 100:8.1f}% "
              f"{f'{low * 100:.1f}–{high * 100:.1f} %':>15s} {row.median_u:11.4g} "
              f"{row.rms_error:11.4g} {row.ratio:6.2f}  {'met' if row.met else 'MISSED'}")


if __name__ == "__main__":
    main()
