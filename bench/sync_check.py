"""Benchmark the run-time sync check ``aatest run`` makes on its main thread after each step.

``check_step_sync`` (:mod:`aatest.engine.run.runner`) calls the sync analysis's ``check_step``
(:func:`aatest.clocksync.freeze_pulse.clock_relation`) on every step as it is recorded; it is
on the record phase's critical path. This bench decodes the recorded steps of a run directory
once (all channels, as the run hands them over) and times only ``check_step`` on them, in CPU
seconds per step.

    python bench/sync_check.py RUN_DIR [--rounds 5] [--profile]
    python bench/sync_check.py RUN_DIR --compare BASE/src [--rounds 5]

``RUN_DIR`` is a recorded run (e.g. ``bench/end_to_end.py --steps 20 --seed 7 --dir RUN_DIR``).
``--compare`` runs the bench in fresh processes on another checkout's ``src`` and on this one,
alternately, prints CPU per step for both and their ratio, and how many of the relations'
numbers differ (they must not: the early child takes the relation as the pass would fit it).
"""

from __future__ import annotations

import cProfile
import json
import pickle
import pstats
import statistics
import time
from pathlib import Path
from typing import Any

from child_run import (  # bench/ (the script's directory) is on sys.path
    against,
    checkout_arguments,
    leaves,
    plain,
)

from aatest.engine import registry
from aatest.recording import read_dataset
from aatest.recording.dataset import LazySteps, StepData


def _steps(run_dir: Path) -> list[StepData]:
    """Every recorded step of ``run_dir``, decoded now (all channels)."""
    data = read_dataset(run_dir)
    steps = data.steps
    assert isinstance(steps, LazySteps)
    return [StepData(steps.planned[i], steps.log(i, "table"), steps.log(i, "daq"))
            for i in range(len(steps)) if steps.planned[i].recorded]


def measure(run_dir: Path, rounds: int, dump: Path | None, profile: bool) -> dict[str, Any]:
    """CPU ms per step of ``check_step`` (median over ``rounds``)."""
    from threadpoolctl import threadpool_limits

    with registry.pinned(), threadpool_limits(limits=1, user_api="blas"):
        check = registry.load("analysis", "sync").target.check_step
        decoded = _steps(run_dir)
        cpu: list[float] = []
        found: list[Any] = []
        profiler = cProfile.Profile() if profile else None
        for _ in range(rounds):
            t = time.process_time()
            if profiler is not None:
                profiler.enable()
            found = [check(step) for step in decoded]
            if profiler is not None:
                profiler.disable()
            cpu.append((time.process_time() - t) / len(decoded))
    if profiler is not None:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(25)
    if dump is not None:
        dump.write_bytes(pickle.dumps(plain(found)))
    return {"steps": len(decoded), "cpu_ms": 1e3 * statistics.median(cpu)}


def compare(run_dir: Path, base_src: Path, rounds: int) -> None:
    """This bench on the base checkout and on this one, alternately; the ratio."""
    docs, outputs = against(__file__, base_src, [str(run_dir), "--rounds", str(rounds)],
                            "sync check", 3)
    runs = {label: [d["cpu_ms"] for d in got] for label, got in docs.items()}
    doc = docs["this"][-1]
    a, b = (dict(leaves(outputs[label])) for label in ("base", "this"))
    differ = sum(1 for k in a.keys() | b.keys()
                 if repr(a.get(k)) != repr(b.get(k)))  # repr: NaN == NaN, bits of floats
    base, this = min(runs["base"]), min(runs["this"])
    print(f"run-time sync check of {run_dir} ({doc['steps']} steps), CPU ms per step, "
          f"best of 3 processes x median of {rounds} rounds")
    print(f"  base {base:8.3f}  this {this:8.3f}  ratio {base / this:6.2f}")
    print(f"relation numbers: {differ} of {len(a)} differ")


def main() -> None:
    parser = checkout_arguments(__doc__, "run_dir", rounds=5)
    parser.add_argument("--profile", action="store_true", help="cProfile the check")
    args = parser.parse_args()
    if args.compare is not None:
        compare(args.run_dir, args.compare, args.rounds)
        return
    doc = measure(args.run_dir, args.rounds, args.dump, args.profile)
    if args.json:
        print(json.dumps(doc))
        return
    print(f"run-time sync check of {args.run_dir} ({doc['steps']} steps): "
          f"{doc['cpu_ms']:.3f} ms CPU per step")


if __name__ == "__main__":
    main()
