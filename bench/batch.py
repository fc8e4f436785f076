"""Benchmark: ``aatest batch`` over an archive of twin recordings on 1 and 2 local workers.

Builds (or reuses) an archive of ``--count`` tiny scale-factor runs on the twin — several
serials on three rigs with their reference standards, registered in a SQLite records store —
then re-analyses it with ``batch analyze`` and ``batch diagnose`` on a local Dask cluster of 1
and of 2 worker processes, each time on a fresh copy of the store (so nothing is skipped). It
prints recordings per minute (wall time including the cluster's start), the speed-up of 2
workers over 1 (target ≥ 1.8× on 2 free cores) and the peak resident memory per worker.

    python bench/batch.py [--count 200] [--archive DIR] [--modes analyze,diagnose]
                          [--prefix URL | --s3]

``--prefix`` selects the recordings under a URL (e.g. a copy of the archive on object
storage) instead of from the store. ``--s3`` starts moto's S3 server on loopback, uploads the
archive's runs to it and selects them there (so the workers read every recording over HTTP;
moto's own overhead included, not a real network). Runs are simulations and are registered as
such.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

from s3_server import moto_s3

from aatest.batch.archive import TwinUnit, record_run, register_references
from aatest.batch.runner import BatchReport, run_batch
from aatest.batch.selection import Selected, from_prefix, from_store
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore
from aatest.storage import RemotePath, locate, upload_dir

RIGS = {"rig-1": ("ENC-1", "LOG-1"), "rig-2": ("ENC-1", "LOG-2"), "rig-3": ("ENC-3", "LOG-3")}
SERIALS = 40  #: units; each is calibrated count / SERIALS times (its repeat calibrations)


def units(count: int) -> list[TwinUnit]:
    """``count`` runs: unit i % SERIALS on rig i % 3, true deviation spread over ±0.9 %."""
    rigs = list(RIGS)
    return [TwinUnit(f"S{i % SERIALS:03d}", round(-0.9 + 1.8 * (i % SERIALS) / SERIALS, 3),
                     rigs[i % len(rigs)], RIGS[rigs[i % len(rigs)]], seed=i)
            for i in range(count)]


def build(archive: Path, count: int) -> Path:
    """The archive's store, recording the runs it does not hold yet; its path."""
    database = archive / "records.sqlite"
    url = f"sqlite:///{database}"
    fresh = not database.exists()
    archive.mkdir(parents=True, exist_ok=True)
    if fresh:
        register_references(url, ["ENC-1", "ENC-3"], ["LOG-1", "LOG-2", "LOG-3"])
    started = time.perf_counter()
    todo = [u for u in units(count)
            if not (archive / u.rig / f"{u.serial}-{u.seed}" / "recording.mcap").exists()]
    for done, unit in enumerate(todo, start=1):
        record_run(unit, archive, url)
        if done % 20 == 0:
            print(f"  built {done}/{len(todo)} in {time.perf_counter() - started:.0f} s",
                  file=sys.stderr)
    return database


def upload(archive: Path, count: int) -> str:
    """Put the first ``count`` runs of the archive on the S3 server; their URL prefix."""
    remote = locate("s3://bench-batch/archive")
    assert isinstance(remote, RemotePath)
    remote.fs.mkdir("bench-batch")
    for unit in units(count):
        run = Path(unit.rig) / f"{unit.serial}-{unit.seed}"
        upload_dir(archive / run, remote.joinpath(*run.parts))
    return str(remote)


def measure(database: Path, prefix: str | None, mode: str, workers: int,
            scratch: Path, count: int) -> tuple[BatchReport, float]:
    """One batch over the first ``count`` recordings, on a fresh copy of the store: its
    report and wall time, s."""
    copy = scratch / f"{mode}-{workers}.sqlite"
    shutil.copyfile(database, copy)
    with RecordStore.open(f"sqlite:///{copy}") as store:
        chosen: list[Selected] = (from_prefix(prefix, store) if prefix
                                  else from_store(store, RecordFilter(include_simulations=True)))
        chosen = chosen[:count]
        started = time.perf_counter()
        report = run_batch(store, chosen, "analyze" if mode == "analyze" else "diagnose",
                           workers=workers)
        return report, time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--archive", type=Path, default=None,
                        help="archive folder (kept and reused; default: a temporary one)")
    parser.add_argument("--modes", default="analyze,diagnose")
    parser.add_argument("--prefix", default=None, help="select recordings under this URL")
    parser.add_argument("--s3", action="store_true",
                        help="upload the archive to moto's S3 server on loopback; read it there")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="aatest-bench-batch-") as tmp, ExitStack() as stack:
        archive = args.archive or Path(tmp) / "archive"
        started = time.perf_counter()
        database = build(archive, args.count)
        print(f"archive: {args.count} twin recordings, {SERIALS} serials, {len(RIGS)} rigs "
              f"({time.perf_counter() - started:.0f} s to build or reuse)")
        if args.s3:
            stack.enter_context(moto_s3())
            args.prefix = upload(archive, args.count)
            print(f"archive uploaded to {args.prefix} (moto on loopback)")
        for mode in args.modes.split(","):
            rates = {}
            for workers in (1, 2):
                report, wall_s = measure(database, args.prefix, mode, workers, Path(tmp),
                                          args.count)
                done = len(report.completed)
                rates[workers] = 60.0 * done / wall_s
                peak = max(report.worker_peak_mib.values(), default=float("nan"))
                print(f"{mode:8s} workers={workers}: {done} done, {len(report.failures)} failed "
                      f"in {wall_s:.1f} s = {rates[workers]:.1f} recordings/min; peak memory "
                      f"per worker {peak:.0f} MiB")
            print(f"{mode:8s} speed-up 2 vs 1 workers: {rates[2] / rates[1]:.2f}× "
                  "(target ≥ 1.8× on 2 free cores)")


if __name__ == "__main__":
    main()
