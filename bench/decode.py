"""Benchmark decoding recorded steps: CPU ms per step, whole and partly, and a digest of them.

Every step of a run directory (or recording file) is decoded as the analysis pass reads it:
both logs whole (``step.table``, ``step.daq``), then only the sync pulses (the partial decode
the sync pass and the early-analysis child make). Each is repeated ``--rounds`` times and the
least CPU time is kept (the file is in the page cache after the first round).

    python bench/decode.py RUN_DIR [--rounds 3]
    python bench/decode.py RUN_DIR --compare BASE/src [--rounds 3]

``--compare`` runs it in fresh processes on another checkout's ``src`` (a baseline, e.g. from
``git worktree add``) and on this one, alternately, and prints both and their ratios, and
whether every decoded channel of every step is the same: a SHA-256 per step over each
channel's name, dtype, shape and bytes (equal bytes: ``np.array_equal`` and more, NaN
included). Make a run with ``python bench/end_to_end.py --steps 30 --seed 7 --dir DIR``.
"""

from __future__ import annotations

import hashlib
import json
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from child_run import (  # bench/ is the script's directory, hence on sys.path
    checkout_arguments,
    child_json,
    this_src,
)

from aatest.engine.logs import SampledLog
from aatest.recording import read_dataset

#: the partial decode of the sync pass (channels by source)
SYNC = {"table": ["sync_pulse"], "daq": ["sync_pulse"]}


def _digest(logs: list[SampledLog]) -> str:
    """SHA-256 over every channel (time stamps first) of ``logs``: name, dtype, shape, bytes."""
    digest = hashlib.sha256()
    for log in logs:
        for name, values in (("time_s", log.time_s), *log.channels.items()):
            digest.update(f"{log.source}/{name}/{values.dtype.str}/{values.shape}".encode())
            digest.update(values.tobytes())
    return digest.hexdigest()


def _least_cpu_ms(rounds: int, count: int, decode: Callable[[int], Any]) -> float:
    """The least CPU ms per step over ``rounds`` passes of ``decode(i)`` for every step."""
    best = float("inf")
    for _ in range(rounds):
        started = time.process_time()
        for i in range(count):
            decode(i)
        best = min(best, time.process_time() - started)
    return 1e3 * best / max(count, 1)


def measure(path: Path, rounds: int) -> dict[str, Any]:
    """CPU ms per step of the whole and the sync decode, and each step's digest."""
    steps = read_dataset(path).steps
    digests = [_digest([steps[i].table, steps[i].daq]) for i in range(len(steps))]
    sync = [_digest([steps.log(i, source, SYNC[source]) for source in ("table", "daq")])
            for i in range(len(steps))]
    whole_ms = _least_cpu_ms(rounds, len(steps), lambda i: (steps[i].table, steps[i].daq))
    sync_ms = _least_cpu_ms(rounds, len(steps),
                            lambda i: [steps.log(i, s, SYNC[s]) for s in ("table", "daq")])
    return {"steps": len(steps), "whole_ms": whole_ms, "sync_ms": sync_ms,
            "digests": digests, "sync_digests": sync}


def compare(base_src: Path, path: Path, rounds: int) -> None:
    """Alternate the baseline checkout and this one; print medians, ratios and equality."""
    docs: dict[str, list[dict[str, Any]]] = {"base": [], "this": []}
    for _ in range(rounds):
        for label, src in (("base", base_src), ("this", this_src(__file__))):
            docs[label].append(child_json(__file__, src, [str(path), "--json", "--rounds", "3"],
                                          "decode benchmark"))
    steps = docs["this"][0]["steps"]
    print(f"{path}: {steps} steps; median of {rounds} rounds (each the least of 3 passes)")
    for key, label in (("whole_ms", "whole step (table + daq)"),
                       ("sync_ms", "sync pulses only")):
        base = statistics.median(d[key] for d in docs["base"])
        this = statistics.median(d[key] for d in docs["this"])
        print(f"  {label:<26} base {base:7.2f} ms CPU/step  this {this:7.2f}  "
              f"ratio {base / this:5.2f}")
    same = all(d["digests"] == docs["base"][0]["digests"]
               and d["sync_digests"] == docs["base"][0]["sync_digests"]
               for d in docs["base"] + docs["this"])
    print(f"decoded channels of every step equal (bytes) between base and this: {same}; "
          f"load average {os.getloadavg()[0]:.1f}")


def main() -> None:
    args = checkout_arguments(__doc__, "path", rounds=3, dumps=False,
                              target_help="run directory or recording file").parse_args()
    if args.compare is not None:
        compare(args.compare, args.path, args.rounds)
        return
    doc = measure(args.path, args.rounds)
    if args.json:
        print(json.dumps(doc))
        return
    print(f"{args.path}: {doc['steps']} steps: whole {doc['whole_ms']:.2f} ms CPU/step, "
          f"sync pulses {doc['sync_ms']:.2f} ms CPU/step")


if __name__ == "__main__":
    main()
