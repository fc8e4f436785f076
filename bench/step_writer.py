"""Benchmark the step-file writer's CPU: ``write_step_file`` on twin steps, ms of CPU a step.

The recording writer runs beside the twin while a campaign records (a thread of its own), so
its CPU is taken from the record phase. This times :func:`aatest.recording.writer.write_step_file`
alone, into memory (no disk, no fsync), on sine steps of 2^17 samples at 2 kHz from the
realistic twin (seed 7, as the stepped sine records them): CPU seconds per step (the least of
``--rounds``), and the SHA-256 of all step files written, which must not change with a speed
change (the run metadata is fixed, so the files are byte for byte reproducible).

    python bench/step_writer.py [--steps 8] [--rounds 3]
    python bench/step_writer.py --compare BASE/src [--steps 8] [--rounds 3]

``--compare`` runs the benchmark in fresh processes on another checkout's ``src`` (first on
``PYTHONPATH``) and on this one, alternately, and prints the ratio of CPU per step and
whether the step files are identical: under load, only ratios measured side by side mean
anything.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import math
import os
import time
from pathlib import Path

from child_run import child_json  # bench/ is the script's directory, hence on sys.path

from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import StepData
from aatest.recording.writer import write_step_file
from aatest.twin.api import realistic_rig_model, simulate_dataset

SAMPLES = 2**17
RUN_META = {"procedure": "bench", "format": 3, "plan": [], "started_utc": "2026-01-01T00:00:00Z"}


def _steps(count: int) -> list[StepData]:
    """``count`` distinct coherent sine steps (64·k cycles, 400 °/s²) of the realistic twin."""
    steps = []
    for i in range(count):
        cycles = 64 * (i + 1)
        freq_hz = cycles * 2000.0 / SAMPLES
        steps.append(PlannedStep(
            id=f"s{i + 1:03d}", kind="sine", axis="inner", samples=SAMPLES,
            sample_rate_hz=2000.0, duration_s=SAMPLES / 2000.0, frequency_hz=freq_hz,
            cycles=cycles, accel_dps2=400.0,
            amplitude_deg=400.0 / (2 * math.pi * freq_hz) ** 2))
    return list(simulate_dataset(realistic_rig_model(), steps, seed=7).steps)


def measure(count: int, rounds: int) -> tuple[float, str]:
    """(least CPU seconds per step over ``rounds``, SHA-256 of every step file written)."""
    data = _steps(count)
    best, digest = math.inf, hashlib.sha256()
    for round_ in range(rounds):
        cpu = 0.0
        for index, step in enumerate(data, start=1):
            stream = io.BytesIO()
            started = time.process_time()
            write_step_file(stream, RUN_META, step.step, index, (step.table, step.daq))
            cpu += time.process_time() - started
            if round_ == 0:
                digest.update(stream.getvalue())
        best = min(best, cpu / count)
    return best, digest.hexdigest()


def _child(src: Path, argv: list[str]) -> tuple[float, str]:
    doc = child_json(__file__, src, ["--json", *argv], "benchmark")
    return float(doc["cpu_s"]), str(doc["sha256"])


def compare(base_src: Path, argv: list[str], repeats: int = 2) -> None:
    """Alternate the baseline checkout and this one; print CPU per step and the ratio."""
    this_src = Path(__file__).resolve().parents[1] / "src"
    best = {"base": math.inf, "this": math.inf}
    digests: dict[str, str] = {}
    for _ in range(repeats):
        for label, src in (("base", base_src), ("this", this_src)):
            cpu_s, digests[label] = _child(src, argv)
            best[label] = min(best[label], cpu_s)
    print(f"write_step_file CPU per step: base {best['base'] * 1e3:.1f} ms, this "
          f"{best['this'] * 1e3:.1f} ms, base ÷ this {best['base'] / best['this']:.2f}; "
          f"step files {'identical' if digests['base'] == digests['this'] else 'DIFFER'}; "
          "load average " + ", ".join(f"{x:.1f}" for x in os.getloadavg()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--compare", type=Path, default=None, metavar="BASE_SRC")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    argv = [f"--steps={args.steps}", f"--rounds={args.rounds}"]
    if args.compare is not None:
        compare(args.compare.resolve(), argv)
        return
    cpu_s, digest = measure(args.steps, args.rounds)
    if args.json:
        print(json.dumps({"cpu_s": cpu_s, "sha256": digest}))
        return
    print(f"write_step_file: {cpu_s * 1e3:.1f} ms CPU per step of {SAMPLES} samples "
          f"(least of {args.rounds}); step files sha256 {digest[:16]}")


if __name__ == "__main__":
    main()
