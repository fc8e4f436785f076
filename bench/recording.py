"""Benchmark the MCAP recording: write/read throughput of a 2^17-sample step, and a whole run.

Usage::

    python bench/recording.py [--steps N] [--samples 131072] [--dir DIR]
    python bench/recording.py --measure RUN_DIR   # size of a finished run's recording.mcap

Data come from the digital twin (realistic rig model: noise, ripple, drift), so the zstd
compression ratio is that of real-looking data, not of zeros. Prints, per step: raw and
on-disk size, write (atomic step file incl. fsync) and read MB/s of raw sample data, and the
ratio lab time / wall time (how much faster than the rig the recorder is); for the run:
finalize (one-pass merge) time and throughput, and the full read_dataset time. Sizes are in
MB (10^6 bytes); "ratio" is raw sample bytes / bytes on disk. ``--measure`` prints the same for
a recorded run (e.g. the shipped stepped-sine procedure, whose format-v1 recording was
:data:`V1_STEPPED_SINE_MB`) and how it compares with the ≤ :data:`TARGET_MB` MB target.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import RunRecorder, read_dataset
from aatest.recording.dataset import StepData
from aatest.twin.api import realistic_rig_model, simulate_dataset

MB = 1e6
#: the shipped stepped-sine recording in format v1 (aatest.block/v1), measured on main
V1_STEPPED_SINE_MB = 657.0
#: issue 14's target for that recording
TARGET_MB = 250.0


def _raw_bytes(log: SampledLog) -> int:
    return log.time_s.nbytes + sum(v.nbytes for v in log.channels.values())


def _twin_steps(n_steps: int, samples: int) -> list[StepData]:
    """Distinct sine steps (coherent, 400 °/s²) simulated once; reused cyclically if needed."""
    unique = min(n_steps, 4)
    steps = []
    for i in range(unique):
        cycles = 64 * (i + 1)
        freq_hz = cycles * 2000.0 / samples
        steps.append(PlannedStep(
            id=f"s{i + 1:03d}", kind="sine", axis="inner", samples=samples, sample_rate_hz=2000.0,
            duration_s=samples / 2000.0, frequency_hz=freq_hz, cycles=cycles, accel_dps2=400.0,
            amplitude_deg=400.0 / (2 * math.pi * freq_hz) ** 2))
    return list(simulate_dataset(realistic_rig_model(), steps, seed=1).steps)


def measure(run_dir: Path) -> None:
    """Print a finished run's recording size, its raw/disk ratio and the v1 comparison."""
    recording = run_dir / "recording.mcap" if run_dir.is_dir() else run_dir
    disk = recording.stat().st_size
    started = time.perf_counter()
    dataset = read_dataset(recording)
    read_s = time.perf_counter() - started
    raw = sum(_raw_bytes(s.table) + _raw_bytes(s.daq) for s in dataset.steps)
    print(f"{recording}: {len(dataset.steps)} steps, raw {raw / MB:.1f} MB, on disk "
          f"{disk / MB:.1f} MB (ratio {raw / disk:.2f}); read in {read_s:.1f} s")
    print(f"vs format v1 of the stepped-sine run ({V1_STEPPED_SINE_MB:.0f} MB): "
          f"{V1_STEPPED_SINE_MB * MB / disk:.2f}x smaller; target <= {TARGET_MB:.0f} MB: "
          f"{'met' if disk <= TARGET_MB * MB else 'NOT met'}")
    print(preview_share(recording))


def preview_share(recording: Path) -> str:
    """Bytes on disk of the ``/preview/*`` chunks and their share of the rest of the file."""
    with open(recording, "rb") as stream:
        summary = make_reader(stream).get_summary()
    preview_ids = {cid for cid, ch in summary.channels.items() if ch.topic.startswith("/preview/")}
    view = sum(ix.chunk_length + ix.message_index_length for ix in summary.chunk_indexes
               if set(ix.message_index_offsets) <= preview_ids)
    rest = recording.stat().st_size - view
    return (f"preview {view / MB:.2f} MB = +{100 * view / rest:.1f} % on the "
            f"{rest / MB:.1f} MB without it (target <= +10 %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--samples", type=int, default=2**17)
    parser.add_argument("--dir", type=Path, default=None)
    parser.add_argument("--measure", type=Path, default=None, help="a finished run directory")
    args = parser.parse_args()
    if args.measure is not None:
        measure(args.measure)
        return
    base = args.dir or Path(tempfile.mkdtemp(prefix="aatest-bench-"))
    data = _twin_steps(args.steps, args.samples)
    recorder = RunRecorder(base / "run")
    recorder.write_run_metadata({"procedure": "bench", "plan": []})
    raw_total, write_s, lab_s = 0, 0.0, 0.0
    for i in range(args.steps):
        source = data[i % len(data)]
        step = source.step.model_copy(update={"id": f"s{i + 1:03d}"})
        started = time.perf_counter()
        path = recorder.write_step(step, source.table, source.daq)
        write_s += time.perf_counter() - started
        raw_total += _raw_bytes(source.table) + _raw_bytes(source.daq)
        lab_s += step.duration_s
        if i == 0:
            raw = _raw_bytes(source.table) + _raw_bytes(source.daq)
            disk = path.stat().st_size
            t0 = time.perf_counter()
            read_dataset(path)
            read_s = time.perf_counter() - t0
            print(f"one step of {args.samples} samples: raw {raw / MB:.1f} MB, on disk "
                  f"{disk / MB:.1f} MB (ratio {raw / disk:.2f}); read {raw / MB / read_s:.0f} MB/s")
    print(f"write {args.steps} steps: {raw_total / MB / write_s:.0f} MB/s raw, "
          f"{write_s / args.steps * 1e3:.0f} ms/step, lab/wall = {lab_s / write_s:.0f}x")
    started = time.perf_counter()
    merged = recorder.finalize()
    finalize_s = time.perf_counter() - started
    print(f"finalize: {finalize_s:.2f} s, {raw_total / MB / finalize_s:.0f} MB/s raw, "
          f"recording.mcap {merged.stat().st_size / MB:.1f} MB "
          f"(ratio {raw_total / merged.stat().st_size:.2f}), "
          f"lab/wall = {lab_s / finalize_s:.0f}x")
    print(preview_share(merged))
    started = time.perf_counter()
    dataset = read_dataset(base / "run")
    read_s = time.perf_counter() - started
    print(f"read_dataset: {len(dataset.steps)} steps in {read_s:.2f} s, "
          f"{raw_total / MB / read_s:.0f} MB/s raw")


if __name__ == "__main__":
    main()
