"""Benchmark ``aatest diagnose``: wall time on a 10-step dataset of 2^15 samples per step.

The dataset is the diagnostic plan (static ±1 g, sines at several frequencies, accelerations
and temperatures, outer-axis sines, a constant-rate step) simulated on the twin, exported in
the import format and diagnosed as a user would (``diagnose_command``), with every candidate
of the effect library tested. Target: under 20 s on the project machine.

    python bench/diagnose.py [--samples 32768] [--effect time_delay] [--seed 1] [--suite]

``--suite`` also runs the full hidden-effect suite and prints its score.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

from aatest.diagnose.command import diagnose_command
from aatest.diagnose.scenarios import (
    clean_rig,
    diagnostic_plan,
    draw_hidden,
    judge,
    scenario_dataset,
    suite_cases,
    with_effects,
)
from aatest.engine.data.exporter import export_csv
from aatest.twin.api import simulate_dataset

#: the two steps of the 12-step diagnostic plan left out to make the 10-step bench dataset
_LEFT_OUT = ("f1-a400", "rate50")


def bench_once(samples: int, effect: str | None, seed: int) -> tuple[float, list[dict], int]:
    """(diagnose wall seconds, findings, candidates tested) for one exported dataset."""
    hidden = [draw_hidden(effect, seed)] if effect else []
    plan = [s for s in diagnostic_plan(samples) if s.id not in _LEFT_OUT]
    data = simulate_dataset(with_effects(clean_rig(seed), hidden), plan, seed)
    with tempfile.TemporaryDirectory() as tmp:
        export_csv(data, Path(tmp) / "import")
        out = Path(tmp) / "d.json"
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            findings = diagnose_command(Path(tmp) / "import", out, None)
        wall = time.perf_counter() - start
        tested = sum(1 for c in json.loads(out.read_text())["candidates"] if c.get("testable"))
    return wall, findings, tested


def run_suite(samples: int) -> None:
    """Score the hidden-effect suite (in-process pipeline on exported/imported data)."""
    from aatest.diagnose.pipeline import diagnose_dataset
    from aatest.engine.recording import read_dataset

    cases, bad = suite_cases(), 0
    for name, hidden, seed in cases:
        with tempfile.TemporaryDirectory() as tmp:
            export_csv(scenario_dataset(hidden, seed, samples), tmp)
            problems = judge(diagnose_dataset(read_dataset(Path(tmp))), hidden)
        bad += bool(problems)
        print(f"{name:40s} {'ok' if not problems else '; '.join(problems)}")
    print(f"suite score: {len(cases) - bad}/{len(cases)} = {100 * (1 - bad / len(cases)):.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2**15)
    parser.add_argument("--effect", default=None, help="hide this effect (default: clean)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--suite", action="store_true")
    args = parser.parse_args()
    for effect in ([args.effect] if args.effect else [None, "time_delay", "motor_vibration"]):
        wall, findings, tested = bench_once(args.samples, effect, args.seed)
        names = ", ".join(f.get("effect") or f"unexplained {f['kind']}" for f in findings) or "none"
        print(f"diagnose 10 steps × {args.samples} samples, hidden {effect or 'nothing'}: "
              f"{wall:.1f} s wall, {tested} candidates tested, findings: {names}")
    if args.suite:
        run_suite(2**14)


if __name__ == "__main__":
    main()
