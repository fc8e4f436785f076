"""Benchmark the per-step reductions the sync pass makes of every recorded step, decode apart.

While the sync pass (and, during ``aatest run``'s record phase, the early-analysis child)
decodes a step, the watches registered on the recording's lazy steps reduce it: the clock
relation, synchronisation and the synced watches (FRF points, the transfer function's
cross-correlation terms, phase trends; :mod:`aatest.plugins.analysis.sync_watches`), the
uncertainty evidence and the logged temperatures. This bench decodes each recorded step of a
run directory once (the union of the channels the watches read, as the pass's decode does)
and then times only the watches' reductions, per watch, in CPU seconds per step.

    python bench/step_reductions.py RUN_DIR [--rounds 3]
    python bench/step_reductions.py RUN_DIR --compare BASE/src [--rounds 3]

``RUN_DIR`` is a recorded run (e.g. ``bench/end_to_end.py --steps 30 --seed 7 --dir RUN_DIR``).
``--compare`` runs this bench in fresh processes on another checkout's ``src`` and on this one,
alternately, prints each watch's CPU per step for both and their ratio (only ratios measured
side by side mean anything on a shared machine), and the largest difference of any reduced
number between the two (relative to the number itself).
"""

from __future__ import annotations

import json
import math
import pickle
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


def _decoded(steps: LazySteps, index: int) -> StepData | None:
    """Step ``index`` decoded with the union of the channels its due watches read."""
    step = steps.planned[index]
    due = [w for w, _ in steps._watches.values() if w.applies(step)]
    if not due:
        return None
    logs = []
    for source in ("table", "daq"):
        parts = [w.channels(step).get(source, ()) for w in due]
        logs.append(steps.log(index, source, _Any(parts)))
    return StepData(step, logs[0], logs[1])


class _Any:
    """A name in any of ``parts`` (the union the pass's decode asks for)."""

    def __init__(self, parts: list[Any]) -> None:
        self.parts = parts

    def __contains__(self, name: object) -> bool:
        return any(name in part for part in self.parts)


def measure(run_dir: Path, rounds: int, dump: Path | None) -> dict[str, Any]:
    """CPU seconds per step of each watch's reduction (median over ``rounds``)."""
    from threadpoolctl import threadpool_limits

    from aatest.engine.analysis.passes import register_watches

    with registry.pinned(), threadpool_limits(limits=1, user_api="blas"):
        data = read_dataset(run_dir)
        steps = data.steps
        assert isinstance(steps, LazySteps)
        register_watches(data, list(data.metadata.get("analysis", [])))
        decoded = [(i, s) for i in range(len(steps)) if steps.planned[i].recorded
                   and (s := _decoded(steps, i)) is not None]
        cpu: dict[str, list[float]] = {name: [] for name in steps._watches}
        results: dict[str, list[Any]] = {}
        for _ in range(rounds):  # step by step, each step's watches in order, as a decode
            spent = dict.fromkeys(cpu, 0.0)
            results = {name: [] for name in cpu}
            for _i, step in decoded:
                for name, (watch, _done) in steps._watches.items():
                    t = time.process_time()
                    results[name].append(watch.reduce(step) if watch.applies(step.step)
                                         else None)
                    spent[name] += time.process_time() - t
            for name, seconds in spent.items():
                cpu[name].append(seconds / len(decoded))
    if dump is not None:
        dump.write_bytes(pickle.dumps(plain(results)))
    return {"steps": len(decoded),
            "cpu_ms": {name: 1e3 * statistics.median(v) for name, v in cpu.items()}}


def largest_change(a: Any, b: Any) -> tuple[float, str, int]:
    """The largest relative difference of two dumps' numbers, where, and how many differ."""
    na, nb = dict(leaves(a)), dict(leaves(b))
    if na.keys() != nb.keys():
        return math.inf, f"keys differ: {sorted(na.keys() ^ nb.keys())[:3]}", -1
    worst, where, count = 0.0, "", 0
    for key, x in na.items():
        y = nb[key]
        if x == y or (isinstance(x, float) and isinstance(y, float)
                      and math.isnan(x) and math.isnan(y)):
            continue
        count += 1
        if not (isinstance(x, (int, float)) and isinstance(y, (int, float))):
            return math.inf, f"{key}: {x!r} vs {y!r}", count
        rel = abs(x - y) / max(abs(x), abs(y), 1e-300)
        if rel > worst:
            worst, where = rel, key
    return worst, where, count


def compare(run_dir: Path, base_src: Path, rounds: int) -> None:
    """This bench on the base checkout and on this one, alternately; ratios per watch."""
    docs, outputs = against(__file__, base_src, [str(run_dir), "--rounds", str(rounds)],
                            "step reductions", 2)
    runs = {label: [d["cpu_ms"] for d in got] for label, got in docs.items()}
    doc = docs["this"][-1]
    worst, where, count = largest_change(outputs["base"], outputs["this"])
    print(f"per-step reductions of {run_dir} ({doc['steps']} steps), CPU ms per step, "
          f"best of 2 processes × median of {rounds} rounds")
    print(f"  {'watch':<28} {'base':>8} {'this':>8} {'ratio':>6}")
    total = {"base": 0.0, "this": 0.0}
    for name in runs["this"][0]:
        b = min(r.get(name, math.nan) for r in runs["base"])
        t = min(r[name] for r in runs["this"])
        total["base"] += 0.0 if math.isnan(b) else b
        total["this"] += t
        print(f"  {name:<28} {b:8.2f} {t:8.2f} {b / t:6.2f}")
    print(f"  {'all':<28} {total['base']:8.2f} {total['this']:8.2f} "
          f"{total['base'] / total['this']:6.2f}")
    print(f"reduced numbers: {count} differ, largest relative change {worst:.2e} ({where})")


def main() -> None:
    args = checkout_arguments(__doc__, "run_dir", rounds=3).parse_args()
    if args.compare is not None:
        compare(args.run_dir, args.compare, args.rounds)
        return
    doc = measure(args.run_dir, args.rounds, args.dump)
    if args.json:
        print(json.dumps(doc))
        return
    print(f"per-step reductions of {args.run_dir} ({doc['steps']} steps), CPU ms per step:")
    for name, ms in doc["cpu_ms"].items():
        print(f"  {name:<28} {ms:8.2f}")


if __name__ == "__main__":
    main()
