"""Benchmark: read a recording from local disk and from an S3-compatible server; print MB/s.

A synthetic recording (``--steps`` coherent sine steps of ``--samples`` samples on both
loggers, seeded) is written with the recorder, uploaded to moto's S3 server started here on
loopback, then read three ways from each place: every step decoded (what ``analyze`` reads),
the whole object hashed (what signing and ``verify`` read), and one step alone (a partial
read: the bytes fetched from the server are counted by fsspec's cache). Numbers on loopback
moto measure the client path and the server's own overhead, not a real network or AWS S3.

    python bench/storage.py [--steps 8] [--samples 131072] [--seed 1]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from s3_server import moto_s3

from aatest.bundle.manifest import file_sha256
from aatest.engine.logs import DAQ, TABLE, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import RunRecorder, read_dataset
from aatest.storage import FETCHED, RemotePath, locate, upload_dir

RATE_HZ = 2000.0


def _step(index: int, samples: int) -> PlannedStep:
    freq_hz = (4 + index) * RATE_HZ / samples
    return PlannedStep(id=f"s{index:02d}", kind="sine", axis="inner", samples=samples,
                       sample_rate_hz=RATE_HZ, duration_s=samples / RATE_HZ,
                       frequency_hz=freq_hz, cycles=4 + index, accel_dps2=100.0,
                       amplitude_deg=100.0 / (2 * np.pi * freq_hz) ** 2, outer_deg=0.0)


def _logs(step: PlannedStep, rng: np.random.Generator) -> tuple[SampledLog, SampledLog]:
    t = np.arange(step.samples) / RATE_HZ
    accel = 100.0 * np.sin(2 * np.pi * (step.frequency_hz or 0.0) * t)
    sync = ((np.arange(step.samples) // 10) % 2 == 0).astype(np.uint8)
    table = SampledLog(TABLE, RATE_HZ, t, {
        "inner_accel_dps2": accel + rng.normal(0, 1e-3, t.size), "sync_pulse": sync},
        {"inner_accel_dps2": "deg/s^2", "sync_pulse": "1"})
    daq = SampledLog(DAQ, RATE_HZ, t, {
        "v_sz": 2.5 + 0.004 * accel + rng.normal(0, 3e-3, t.size), "sync_pulse": sync},
        {"v_sz": "V", "sync_pulse": "1"})
    return table, daq


def write_recording(folder: Path, steps: int, samples: int, seed: int) -> Path:
    """A finished run directory holding a synthetic ``recording.mcap``."""
    rng = np.random.default_rng(seed)
    plan = [_step(i, samples) for i in range(1, steps + 1)]
    recorder = RunRecorder(folder)
    recorder.write_run_metadata({"procedure": "bench-storage", "seed": seed,
                                 "plan": [s.model_dump(mode="json") for s in plan]})
    for step in plan:
        recorder.write_step(step, *_logs(step, rng))
    path = recorder.finalize()
    recorder.prune_step_files()
    return path


def decode_all(where: str) -> None:
    for step in read_dataset(where).steps:
        _ = step.table, step.daq


def decode_one(where: str) -> None:
    _ = read_dataset(where).steps[1].daq


def timed(action: Callable[[], object], repeats: int = 3) -> float:
    """Best of ``repeats`` wall times (s)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--samples", type=int, default=131072)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    with moto_s3(), tempfile.TemporaryDirectory() as tmp:
        recording = write_recording(Path(tmp), args.steps, args.samples, args.seed)
        remote = locate("s3://bench/runs/r1")
        assert isinstance(remote, RemotePath)
        remote.fs.mkdir("bench")
        upload_dir(Path(tmp), remote)
        size_mb = recording.stat().st_size / 1e6
        url = str(remote / "recording.mcap")
        print(f"recording: {args.steps} steps x {args.samples} samples, {size_mb:.1f} MB")
        for label, local_action, remote_action in (
            ("decode every step", lambda: decode_all(str(recording)), lambda: decode_all(url)),
            ("sha256 of the file", lambda: file_sha256(recording),
             lambda: file_sha256(remote / "recording.mcap")),
        ):
            local_s, remote_s = timed(local_action), timed(remote_action)
            print(f"{label:20s} local {size_mb / local_s:8.1f} MB/s   s3 (moto) "
                  f"{size_mb / remote_s:8.1f} MB/s   s3 time / local time "
                  f"{remote_s / local_s:5.2f}")
        before = FETCHED["bytes"]
        decode_one(url)
        fetched = FETCHED["bytes"] - before
        print(f"one step of {args.steps} from s3: fetched {fetched / 1e6:.2f} MB of "
              f"{size_mb:.1f} MB ({fetched / 1e6 / size_mb:.1%} of the object)")


if __name__ == "__main__":
    main()
