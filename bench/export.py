"""Benchmark CSV export and import of a recording: Arrow's C++ CSV paths against the old ones.

Usage::

    python bench/export.py [--steps 4] [--samples 131072] [--dir DIR]
    python bench/export.py --recording RUN_DIR [--dir DIR]

A mid-size run (default 4 twin sine steps of 2^17 samples, both loggers) is recorded, then
exported with ``export_csv`` and imported back with ``import_dataset``. The same export and
import are timed through the previous implementation — NumPy's ``astype(str)`` and a Python
join per row for writing, the tolerant ``np.loadtxt`` path of ``csv_table`` for reading — and
both are printed in MB/s of CSV text with their ratio (issue 14 asks for ≥ 10×). The imports
are checked to give bit-identical channels.

``--recording`` times ``aatest export --csv`` of a whole run instead (read, decode, write), the
measurement issue 14 started from: the shipped stepped-sine recording took
:data:`ISSUE_EXPORT_S` s. It prints wall and CPU seconds, the ratio to that, and the load
average (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from recording import _twin_steps  # bench/ is the script's directory, hence on sys.path

from aatest.engine.data import csv_table, exporter
from aatest.engine.data.exporter import export_csv
from aatest.engine.data.importer import import_dataset
from aatest.engine.dataset import Dataset
from aatest.engine.recording import RunRecorder, read_dataset

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


#: CPU seconds (all threads) of each timed action, by the order they ran
CPU_S: list[float] = []


def _timed(action: Callable[[], object]) -> tuple[float, object]:
    """Wall seconds of ``action`` (its CPU seconds, all threads, go to :data:`CPU_S`)."""
    started, cpu = time.perf_counter(), time.process_time()
    result = action()
    CPU_S.append(time.process_time() - cpu)
    return time.perf_counter() - started, result


def _csv_bytes(directory: Path) -> int:
    return sum(p.stat().st_size for p in directory.glob("*.csv"))


def _same(a: Dataset, b: Dataset) -> bool:
    return all(
        np.array_equal(x.table[name], y.table[name]) for x, y in zip(a.steps, b.steps, strict=True)
        for name in x.table.channels
    ) and all(np.array_equal(x.daq.time_s, y.daq.time_s) for x, y in zip(a.steps, b.steps,
                                                                          strict=True))


def _export_import(dataset: Dataset, out: Path) -> tuple[float, float, int, Dataset]:
    export_s, _ = _timed(lambda: export_csv(dataset, out))
    import_s, imported = _timed(lambda: import_dataset(out))
    assert isinstance(imported, Dataset)
    return export_s, import_s, _csv_bytes(out), imported


def _whole_recording(run_dir: Path, out: Path) -> None:
    """Time the export of a whole recording against the issue's 462 s."""
    wall, _ = _timed(lambda: export_csv(read_dataset(run_dir), out))
    cpu = CPU_S[-1]
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"{run_dir}: {_csv_bytes(out) / MB:.0f} MB of CSV in {wall:.1f} s wall, {cpu:.1f} s "
          f"CPU (all threads); {ISSUE_EXPORT_S:.0f} s before: {ISSUE_EXPORT_S / wall:.1f}x "
          f"faster by wall, {ISSUE_EXPORT_S / cpu:.1f}x by CPU (target ≥ 10x); load average "
          f"{load}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--samples", type=int, default=2**17)
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
    for data in _twin_steps(args.steps, args.samples)[: args.steps]:
        recorder.write_step(data.step, data.table, data.daq)
    dataset = read_dataset(recorder.finalize())
    new_export, new_import, size, new = _export_import(dataset, base / "arrow")
    write_csv, read_plain = exporter.write_csv, csv_table._read_plain
    exporter.write_csv = _old_write_csv  # type: ignore[assignment]
    csv_table._read_plain = lambda *_: None  # type: ignore[assignment]
    try:
        old_export, old_import, _, old = _export_import(dataset, base / "old")
    finally:
        exporter.write_csv, csv_table._read_plain = write_csv, read_plain
    print(f"{len(dataset.steps)} steps, {size / MB:.1f} MB of CSV; imports identical: "
          f"{_same(new, old) and _same(new, dataset)}")
    cpu = dict(zip(("new export", "new import", "old export", "old import"), CPU_S,
                   strict=True))
    for what, new_s, old_s in (("export", new_export, old_export),
                               ("import", new_import, old_import)):
        new_cpu, old_cpu = cpu[f"new {what}"], cpu[f"old {what}"]
        print(f"{what}: {size / MB / new_s:.0f} MB/s ({new_s:.2f} s) vs old "
              f"{size / MB / old_s:.1f} MB/s ({old_s:.2f} s): {old_s / new_s:.1f}x faster; "
              f"CPU {new_cpu:.2f} s vs {old_cpu:.2f} s: {old_cpu / new_cpu:.1f}x less "
              "(wall suffers on a shared machine; CPU counts every thread)")
    print("load average " + ", ".join(f"{x:.1f}" for x in os.getloadavg()))


if __name__ == "__main__":
    main()
