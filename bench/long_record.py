"""Benchmark: long static records on the twin with every static analysis, 1, 2 and 8 h.

The procedure (``--drift-only``: the shipped ``long-static-drift`` instead) holds two static
records of the given length, the sensitive axis up and down (motor off), analysed with
``[sync, bias, noise, drift]``: the table logs its full-rate head only (its log buffer), sync
fits the clocks on it and carries the drift over the rest, bias and noise read each record
block by block. Issue 26 asks ≤ 300 MB for the whole process tree, flat in record length.
With the motor off the twin's axes creep over hours and the floor's rocking (5–15 Hz) enters
the record: the noise of an 8-h record is above the sensor's own (twin physics, not the
reduction; the shipped drift procedure keeps the motor on for this reason).

Prints, per record length, lab time ÷ wall time and peak memory of each phase in its own
process (the summed PSS of that process and the analysis' forked workers, :mod:`tree_memory`):
*record* (``aatest run`` up to the merged recording: the DAQ streams 60 s chunks into the step
file, the table logs 1 s snapshots),
*analyse* (``aatest analyze`` of the run: reading the recording, the drift analysis, the
uncertainty stage and the certificate) and *run* (the whole ``aatest run`` in one process, as
an operator runs it), plus the recording's size. Issue 14 asks ≤ 800 MB for the 2 h record;
none of the phases should grow with the record length (the recording is read block by block).
Then the drift figures of each record: the white-noise coefficient N of the Allan fit against
the twin's truth (its white noise through the logger's pre-sample filter), and the longest τ.

    python bench/long_record.py [--minutes 60 120 480] [--drift-only] [--keep DIR] [--no-run]
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tree_memory import TreeMemory  # bench/ is the script's directory, hence on sys.path

PROCEDURE = "long-static-drift"


def _procedure_text(minutes: float, drift_only: bool) -> str:
    """The procedure with its record length set to ``minutes``."""
    import aatest

    if not drift_only:
        return STATIC.format(seconds=f"{minutes * 60:g}")
    text = (Path(aatest.__file__).parent / "procedures" / f"{PROCEDURE}.yaml").read_text()
    return text.replace("duration_s: 7200", f"duration_s: {minutes * 60:g}")


#: two long static records, axis up and down, with every static analysis
STATIC = """\
procedure: long-static-all
sensor: {{model: sr207, serial: "SR207-0001"}}
rig: {{turntable: sim, daq: sim, chamber: none}}
sampling: {{rate_hz: 2000, settle_s: 5}}
steps:
  - static: {{label: up, inner_deg: 0, outer_deg: 0, duration_s: {seconds}, motor_on: false}}
  - static: {{label: down, inner_deg: 0, outer_deg: 180, duration_s: {seconds}, motor_on: false}}
analysis: [sync, bias, noise, drift]
report: {{template: calibration-certificate, sign: false}}
"""


def _record(procedure: Path, run_dir: Path) -> None:
    """Child process: run the procedure up to the merged recording (no analysis)."""
    from aatest.engine.run import session

    def skip_analysis(*_args: object, **_kwargs: object) -> dict[str, object]:
        return {}

    session.analyse_and_report = skip_analysis  # type: ignore[assignment] # measure recording only
    session.run(procedure, None, run_dir, False, 0, None, show_progress=False)


def _run(procedure: Path, run_dir: Path) -> None:
    """Child process: the whole ``aatest run`` (record, analyse, report) in one process."""
    from aatest.engine.run import session

    session.run(procedure, None, run_dir, False, 0, None, show_progress=False)


def _white_noise_truth() -> float:
    """N of the shipped sensor on the twin, °/s²·√s: its white noise (V rms per sample) as it
    leaves the logger's pre-sample filter, over √fs, in °/s² (tests/engine/test_long_record)."""
    import numpy as np

    from aatest.engine.datasheet import SensorDatasheet
    from aatest.twin.daq import antialias_filter
    from aatest.twin.defaults import realistic_rig_model

    model = realistic_rig_model(SensorDatasheet(model="sr207"))
    sensor, fs_hz = model.sensors[0], 2000.0
    gain = antialias_filter(float(model.daq.antialias_hz), 1.0 / fs_hz)[2]
    return float(sensor.noise_rms_v / gain / np.sqrt(fs_hz) / sensor.scale_v_per_dps2)


def _analyse(run_dir: Path, out_dir: Path) -> None:
    """Child process: read the recording and run its analyses (``aatest analyze``)."""
    from aatest.engine.run import session

    session.analyse_and_report(run_dir, out_dir)


def _measured(phase: Callable[[Path, Path], None], first: Path, second: Path) -> None:
    """Run one phase; print its wall time and the peak memory of its process tree (summed
    PSS, :mod:`tree_memory`: this process and the analysis' forked workers, shared pages
    counted once; without ``/proc``, this process's peak RSS)."""
    with TreeMemory() as tree:
        started = time.perf_counter()
        phase(first, second)
        wall_s = time.perf_counter() - started
    peak_mb = tree.peak_mb if tree.peak_mb is not None else \
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"wall_s": wall_s, "peak_mb": peak_mb}))


def _child(*args: str) -> dict[str, float]:
    """Run one phase in a fresh process; its failure ends the bench with the phase's own
    error (the last lines it wrote), not a bare exit status."""
    done = subprocess.run([sys.executable, __file__, "--child", *args],
                          check=False, capture_output=True, text=True)
    if done.returncode != 0:
        tail = "\n".join(done.stderr.strip().splitlines()[-5:])
        raise SystemExit(f"the {args[0]} phase failed (exit {done.returncode}):\n{tail}")
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, nargs="+", default=[60.0, 120.0, 480.0])
    parser.add_argument("--drift-only", action="store_true",
                        help="the shipped long-static-drift procedure instead")
    parser.add_argument("--keep", type=Path, default=None, help="keep the runs under DIR")
    parser.add_argument("--no-run", action="store_true", help="skip the whole-run phase")
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        phases = {"record": _record, "run": _run, "analyse": _analyse}
        _measured(phases[args.child[0]], Path(args.child[1]), Path(args.child[2]))
        return
    root = args.keep or Path(tempfile.mkdtemp(prefix="aatest-long-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        _bench(args, root)
    finally:  # an 8 h run leaves GBs: only --keep keeps them
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)


def _bench(args: argparse.Namespace, root: Path) -> None:
    """Record, analyse and run each record length under ``root``; print the table."""
    print(f"{'record':>8} {'lab s':>8} {'phase':>8} {'wall s':>8} {'lab/wall':>9} "
          f"{'peak MB':>12} {'recording MB':>13}")
    drifts = []
    for minutes in args.minutes:
        name = PROCEDURE if args.drift_only else "long-static-all"
        procedure = root / f"{name}-{minutes:g}min.yaml"
        procedure.write_text(_procedure_text(minutes, args.drift_only))
        run_dir = root / f"run-{minutes:g}min"
        phases = {"record": _child("record", str(procedure), str(run_dir))}
        from aatest.engine.run.session import prepare

        lab_s = prepare(procedure, None).plan.lab_duration_s
        size_mb = (run_dir / "recording.mcap").stat().st_size / 1e6
        phases["analyse"] = _child("analyse", str(run_dir), str(run_dir / "analysis"))
        if not args.no_run:
            phases["run"] = _child("run", str(procedure), str(root / f"whole-{minutes:g}min"))
        for phase, numbers in phases.items():
            print(f"{minutes:>6g}min {lab_s:>8.0f} {phase:>8} {numbers['wall_s']:>8.1f} "
                  f"{lab_s / numbers['wall_s']:>9.0f} {numbers['peak_mb']:>12.0f} "
                  f"{size_mb:>13.1f}")
        results = json.loads((run_dir / "analysis" / "results.json").read_text())
        drifts.append((minutes, results["analysis"]["drift"]))
        _print_static(minutes, results["analysis"])
    truth = _white_noise_truth()
    print(f"\n{'record':>8} {'channel':>8} {'N °/s²·√s':>10} {'truth':>8} {'max τ s':>8} "
          f"{'drift V/h':>10}")
    for minutes, drift in drifts:
        for channel, values in drift.items():
            n = values["allan_fit"]["white_noise_dps2_sqrt_s"]
            print(f"{minutes:>6g}min {channel:>8} {n:>10.5f} {truth:>8.5f} "
                  f"{values['max_tau_s']:>8.0f} {values['drift_v_per_h']:>10.2e}")


def _print_static(minutes: float, analysis: dict[str, Any]) -> None:
    """The clock fit's coverage and the bias and noise with their U (when analysed)."""
    for entry in (analysis.get("sync") or {}).get("steps", []):
        print(f"{minutes:>6g}min sync {entry['step']}: coverage {entry['fit_coverage']:.4f}, "
              f"u_ext {entry['extrapolation_u_s'] * 1e6:.3g} µs")
    for key, value in (("bias", "bias_v"), ("noise", "rms_max_v")):
        for channel, entry in (analysis.get(key) or {}).items():
            rows = {row["name"]: row for row in entry.get("budget", [])}
            clock = rows.get("clock_coverage", {}).get("standard_uncertainty")
            print(f"{minutes:>6g}min {key} {channel}: {entry[value]:.6g} V, "
                  f"U {entry.get('expanded_uncertainty')}, clock row u {clock}")


if __name__ == "__main__":
    main()
