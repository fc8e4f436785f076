"""Benchmark TDMS and MF4 export/import of a recording against the CSV path, and their memory.

Usage::

    python bench/logger_files.py [--steps 4] [--samples 131072] [--dir DIR]

A mid-size run (default 4 twin sine steps of 2^17 samples, both loggers) is recorded, then
exported with ``export_csv``, ``export_tdms`` and ``export_mf4`` and read back with
``read_dataset`` (every step's two logs decoded). It prints wall and CPU seconds of each and
their ratio to CSV's, checks that every format reads back the recording's channels bit for bit,
and prints the peak of Python-traced memory (NumPy's arrays included) during each export
relative to the largest step's logs and to the whole run's: an export that streams per step
stays near one step (a piece at a time for TDMS/MF4), one that gathered the run would not.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
from recording import _twin_steps  # bench/ is the script's directory, hence on sys.path

from aatest.engine.logs import SampledLog
from aatest.recording import RunRecorder, read_dataset
from aatest.recording.data.exporter import export_csv
from aatest.recording.data.logger_export import export_mf4, export_tdms
from aatest.recording.dataset import Dataset

MB = 1e6
EXPORTS: dict[str, Callable[[Dataset, Path], Path]] = {
    "csv": export_csv, "tdms": export_tdms, "mf4": export_mf4}


def _bytes(log: SampledLog) -> int:
    return int(log.time_s.nbytes + sum(v.nbytes for v in log.channels.values()))


def _timed(action: Callable[[], object]) -> tuple[float, float, object]:
    started, cpu = time.perf_counter(), time.process_time()
    result = action()
    return time.perf_counter() - started, time.process_time() - cpu, result


def _read_all(path: Path) -> list[tuple[SampledLog, SampledLog]]:
    return [(s.table, s.daq) for s in read_dataset(path).steps]


def _same(a: list[tuple[SampledLog, SampledLog]], b: Dataset) -> bool:
    return all(np.array_equal(x.time_s, y.time_s) and all(
        np.array_equal(x[name], y[name]) for name in x.channels)
        for pair, step in zip(a, b.steps, strict=True)
        for x, y in zip(pair, (step.table, step.daq), strict=True))


def _peak_mb(action: Callable[[], object]) -> float:
    tracemalloc.start()
    try:
        action()
        return tracemalloc.get_traced_memory()[1] / MB
    finally:
        tracemalloc.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--samples", type=int, default=2**17)
    parser.add_argument("--dir", type=Path, default=None)
    args = parser.parse_args()
    base = args.dir or Path(tempfile.mkdtemp(prefix="aatest-bench-logger-"))
    recorder = RunRecorder(base / "run")
    recorder.write_run_metadata({"procedure": "bench", "plan": []})
    simulated = _twin_steps(args.steps, args.samples)
    for i in range(args.steps):
        data = simulated[i % len(simulated)]
        recorder.write_step(data.step.model_copy(update={"id": f"s{i + 1:03d}"}), data.table,
                            data.daq)
    dataset = read_dataset(recorder.finalize())
    step_mb = max(_bytes(s.table) + _bytes(s.daq) for s in dataset.steps) / MB
    run_mb = sum(_bytes(s.table) + _bytes(s.daq) for s in dataset.steps) / MB
    print(f"{args.steps} steps of {args.samples} samples: {run_mb:.0f} MB of logs, largest "
          f"step {step_mb:.0f} MB; load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    times = {}
    for kind, export in EXPORTS.items():
        out = base / kind
        wrote = _timed(lambda: export(dataset, out))  # noqa: B023 - called at once
        read = _timed(lambda: _read_all(out))  # noqa: B023 - called at once
        times[kind] = (wrote, read)
        size = sum(p.stat().st_size for p in out.iterdir()) / MB
        same = _same(read[2], dataset)  # type: ignore[arg-type]
        print(f"{kind:4s}: {size:6.0f} MB on disk; export {wrote[0]:.2f} s wall {wrote[1]:.2f} s "
              f"CPU; read {read[0]:.2f} s wall {read[1]:.2f} s CPU; bit-identical: {same}")
    for kind in ("tdms", "mf4"):
        (w, r) = times[kind]
        (cw, cr) = times["csv"]
        print(f"{kind} / csv CPU: export {w[1] / cw[1]:.2f}, read {r[1] / cr[1]:.2f}")
    for kind, export in EXPORTS.items():
        peak = _peak_mb(lambda: export(dataset, base / f"{kind}-mem"))  # noqa: B023
        print(f"{kind:4s} export peak traced memory {peak:.0f} MB = {peak / step_mb:.2f} x the "
              f"largest step, {peak / run_mb:.2f} x the run")


if __name__ == "__main__":
    main()
