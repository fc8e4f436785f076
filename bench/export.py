"""Benchmark CSV export and import of a recording: Arrow's C++ CSV paths against the old ones.

Usage::

    python bench/export.py [--steps 4] [--samples 131072] [--rounds 1] [--dir DIR]
    python bench/export.py --recording RUN_DIR [--dir DIR]

A mid-size run (default 4 twin sine steps of 2^17 samples, both loggers) is recorded, then
exported with ``export_csv`` and imported back with ``import_dataset``. The same export and
import are timed through the previous implementation — NumPy's ``astype(str)`` and a Python
join per row for writing, the tolerant ``np.loadtxt`` path of ``csv_table`` for reading — and
both are printed in MB/s of CSV text with their ratio by wall and by CPU seconds (issue 14 asks
for ≥ 10×). The imports are checked to give bit-identical channels. ``--rounds N`` repeats new
and old export+import N times, interleaved, so that both see the same drift of a shared
machine's load, and prints the median ratio with its range.

``--recording`` times ``aatest export --csv`` of a whole run instead (read, decode, write), the
measurement issue 14 started from: the shipped stepped-sine recording took
:data:`ISSUE_EXPORT_S` s. It prints wall and CPU seconds, the ratio to that, and the load
average (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from recording import _twin_steps  # bench/ is the script's directory, hence on sys.path

from aatest.recording import RunRecorder, read_dataset
from aatest.recording.data import csv_table, exporter
from aatest.recording.data.exporter import export_csv
from aatest.recording.data.importer import import_dataset
from aatest.recording.dataset import Dataset

MB = 1e6
#: ``aatest export --csv`` of the shipped stepped-sine recording when issue 14 was opened, s
ISSUE_EXPORT_S = 462.0


def _old_write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    """The exporter before Arrow: NumPy text conversion and one Python join per row."""
    texts = [np.asarray(v).astype(np.uint8 if np.asarray(v).dtype.kind == "b" else
                                  np.asarray(v).dtype).astype(str) for v in columns.values()]
    with open(path, "w", encoding="utf-8", newline="\n") as stream:
        stream.write(",".join(columns) + "\n")
        for row in map(",".join, zip(*texts, strict=True)):
            stream.write(row + "\n")


@dataclass(frozen=True)
class Timing:
    """Wall and CPU seconds (CPU of every thread of the process) of one timed action."""

    wall_s: float
    cpu_s: float


def _timed(action: Callable[[], object]) -> tuple[Timing, object]:
    started, cpu = time.perf_counter(), time.process_time()
    result = action()
    return Timing(time.perf_counter() - started, time.process_time() - cpu), result


def _load() -> str:
    return ", ".join(f"{x:.1f}" for x in os.getloadavg())


def _csv_bytes(directory: Path) -> int:
    return sum(p.stat().st_size for p in directory.glob("*.csv"))


def _same(a: Dataset, b: Dataset) -> bool:
    return all(
        np.array_equal(x.table[name], y.table[name]) for x, y in zip(a.steps, b.steps, strict=True)
        for name in x.table.channels
    ) and all(np.array_equal(x.daq.time_s, y.daq.time_s) for x, y in zip(a.steps, b.steps,
                                                                          strict=True))


def _export_import(dataset: Dataset, out: Path) -> tuple[Timing, Timing, Dataset]:
    export, _ = _timed(lambda: export_csv(dataset, out))
    imported_in, imported = _timed(lambda: import_dataset(out))
    assert isinstance(imported, Dataset)
    return export, imported_in, imported


def _old_export_import(dataset: Dataset, out: Path) -> tuple[Timing, Timing, Dataset]:
    """:func:`_export_import` through the previous writer and the tolerant reader."""
    write_csv, read_plain = exporter.write_csv, csv_table._read_plain
    exporter.write_csv = _old_write_csv  # type: ignore[assignment]
    csv_table._read_plain = lambda *_: None  # type: ignore[assignment]
    try:
        return _export_import(dataset, out)
    finally:
        exporter.write_csv, csv_table._read_plain = write_csv, read_plain


def _whole_recording(run_dir: Path, out: Path) -> None:
    """Time the export of a whole recording against the issue's 462 s."""
    took, _ = _timed(lambda: export_csv(read_dataset(run_dir), out))
    print(f"{run_dir}: {_csv_bytes(out) / MB:.0f} MB of CSV in {took.wall_s:.1f} s wall, "
          f"{took.cpu_s:.1f} s CPU (all threads); {ISSUE_EXPORT_S:.0f} s before: "
          f"{ISSUE_EXPORT_S / took.wall_s:.1f}x faster by wall, {ISSUE_EXPORT_S / took.cpu_s:.1f}x "
          f"by CPU (target ≥ 10x); load average {_load()}")


def _spread(ratios: list[float]) -> str:
    """Median of the per-round ratios and, over several rounds, their range."""
    if len(ratios) == 1:
        return f"{ratios[0]:.1f}x"
    return f"{statistics.median(ratios):.1f}x (rounds {min(ratios):.1f}-{max(ratios):.1f}x)"


def _report(what: str, size: int, new: list[Timing], old: list[Timing]) -> None:
    """One line per action: throughput of the first round, ratios over all rounds."""
    wall = [o.wall_s / n.wall_s for n, o in zip(new, old, strict=True)]
    cpu = [o.cpu_s / n.cpu_s for n, o in zip(new, old, strict=True)]
    print(f"{what}: {size / MB / new[0].wall_s:.0f} MB/s ({new[0].wall_s:.2f} s) vs old "
          f"{size / MB / old[0].wall_s:.1f} MB/s ({old[0].wall_s:.2f} s): {_spread(wall)} faster; "
          f"CPU {new[0].cpu_s:.2f} s vs {old[0].cpu_s:.2f} s: {_spread(cpu)} less "
          "(wall suffers on a shared machine; CPU counts every thread)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--samples", type=int, default=2**17)
    parser.add_argument("--rounds", type=int, default=1,
                        help="rounds of new then old export+import; ratios per round, median")
    parser.add_argument("--dir", type=Path, default=None)
    parser.add_argument("--recording", type=Path, default=None, metavar="RUN_DIR",
                        help="time the export of this whole run instead")
    args = parser.parse_args()
    base = args.dir or Path(tempfile.mkdtemp(prefix="aatest-bench-export-"))
    if args.recording is not None:
        _whole_recording(args.recording, base / "whole")
        return
    recorder = RunRecorder(base / "run")
    recorder.write_run_metadata({"procedure": "bench", "plan": []})
    simulated = _twin_steps(args.steps, args.samples)  # at most 4 distinct, reused cyclically
    for i in range(args.steps):
        data = simulated[i % len(simulated)]
        recorder.write_step(data.step.model_copy(update={"id": f"s{i + 1:03d}"}), data.table,
                            data.daq)
    dataset = read_dataset(recorder.finalize())
    load_before = _load()
    timings: dict[str, list[Timing]] = {k: [] for k in ("new export", "new import",
                                                         "old export", "old import")}
    for _ in range(max(1, args.rounds)):  # interleaved: both paths see the same load drift
        for path, run in (("new", _export_import), ("old", _old_export_import)):
            export, imported_in, imported = run(dataset, base / path)
            timings[f"{path} export"].append(export)
            timings[f"{path} import"].append(imported_in)
            if path == "new":
                new = imported
        old = imported
    size = _csv_bytes(base / "new")
    print(f"{len(dataset.steps)} steps, {size / MB:.1f} MB of CSV, {max(1, args.rounds)} "
          f"round(s); imports identical: {_same(new, old) and _same(new, dataset)}")
    for what in ("export", "import"):
        _report(what, size, timings[f"new {what}"], timings[f"old {what}"])
    print(f"load average {load_before} before, {_load()} after")


if __name__ == "__main__":
    main()
