"""Run a batch on Dask: one task per recording, results stored as each one completes.

The coordinator (this process) selects the recordings, skips those already re-analysed with
the same method (:mod:`aatest.batch.ledger`), submits one :func:`~aatest.batch.task.run_task`
per remaining recording to a Dask ``distributed`` cluster — a local one with ``workers``
processes by default, or an existing scheduler — and stores each result the moment it
arrives. Why here and not on the workers: workers need no access to the records database
(a remote cluster may not reach it), and a result is in the store before the next one is
awaited, so killing a worker loses at most the tasks it was running; Dask reruns those on
another worker (up to its ``allowed-failures``), and what still failed is reported with its
recording and error without stopping the others. Re-running the batch then runs only what is
missing.
"""

from __future__ import annotations

import logging
import resource
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from aatest.batch import ledger
from aatest.batch.correction import ReferenceCorrection
from aatest.batch.method import Mode, method_hash, method_of
from aatest.batch.selection import Selected
from aatest.batch.task import Task, run_task
from aatest.engine.errors import InputError
from aatest.records.store import RecordStore

#: how long to wait for an existing scheduler before giving up, s
CONNECT_TIMEOUT_S = 15.0

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Failure:
    """A task that did not complete: its recording and the error."""

    subject: str
    recording: str
    error: str


@dataclass
class BatchReport:
    """What a batch did: how many were selected, skipped as done, completed and failed."""

    method_hash: str
    selected: int
    skipped: int
    completed: list[str] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)
    #: peak resident memory of each worker process, MiB (from the workers themselves)
    worker_peak_mib: dict[str, float] = field(default_factory=dict)

    def line(self) -> str:
        """``done 5 · failed 1 · remaining 0`` (``remaining`` counts this run's tasks)."""
        remaining = self.selected - self.skipped - len(self.completed) - len(self.failures)
        return (f"done {len(self.completed)} · failed {len(self.failures)} · "
                f"remaining {remaining}")


def _peak_rss_mib() -> float:
    """This process's peak resident set, MiB (``ru_maxrss`` is KiB on Linux, bytes on macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 2**10)


@contextmanager
def client_for(scheduler: str | None, workers: int, processes: bool = True) -> Iterator[Any]:
    """A Dask client: on ``scheduler`` when given, else on a local cluster of ``workers``
    single-threaded worker processes (threads with ``processes=False``) bound to loopback,
    its HTTP server too.

    Raises
    ------
    InputError
        The scheduler cannot be reached, or ``workers`` < 1.
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect: {exc}") from exc
        with client:
            yield client
        return
    if workers < 1:
        raise InputError(f"--workers {workers}: at least one worker is needed")
    loopback = {"host": "127.0.0.1"} if processes else {}  # threads talk in-process
    # the scheduler's and workers' HTTP servers always start: on loopback, on free ports
    # (never 8787, which another cluster on the machine may hold)
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                      dashboard_address="127.0.0.1:0", worker_dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR,
                      **loopback) as cluster, Client(cluster) as client:
        yield client


def _stored_values(item: Selected, mode: Mode, mhash: str, method: dict[str, Any],
                   result: dict[str, Any]) -> dict[str, Any]:
    return {"subject": item.subject, "record_id": item.record.id if item.record else None,
            "recording": item.recording, "mode": mode, "method_hash": mhash, "method": method,
            "aatest_version": method["aatest_version"], **result}


def run_batch(store: RecordStore, selected: Sequence[Selected], mode: Mode,
              correction: ReferenceCorrection | None = None, *, scheduler: str | None = None,
              workers: int = 2, processes: bool = True,
              progress: Progress | None = None) -> BatchReport:
    """Re-analyse (``mode="analyze"``) or diagnose every selected recording not done yet.

    Each result is stored (:func:`ledger.append`) as soon as its task completes; a task that
    raised — or whose workers kept dying — is a :class:`Failure` and the others go on.
    """
    say = progress or (lambda _text: None)
    method = method_of(mode, correction)
    mhash = method_hash(method)
    unique = list({item.subject: item for item in selected}.values())
    done = ledger.done_subjects(store, mhash, [item.subject for item in unique])
    todo = [item for item in unique if item.subject not in done]
    report = BatchReport(mhash, len(unique), len(unique) - len(todo))
    say(f"{report.selected} selected, {report.skipped} done already with method "
        f"{mhash[:12]}, {len(todo)} to run")
    if not todo:
        return report
    with client_for(scheduler, workers, processes) as client:
        _submit_and_store(client, store, todo, mode, method, report, say)
        report.worker_peak_mib = {str(k): float(v)
                                  for k, v in client.run(_peak_rss_mib).items()}
    return report


def _submit_and_store(client: Any, store: RecordStore, todo: Sequence[Selected], mode: Mode,
                      method: dict[str, Any], report: BatchReport, say: Progress) -> None:
    from distributed import as_completed

    mhash = report.method_hash
    futures = {}
    for index, item in enumerate(todo):
        task = Task(item.subject, item.record.id if item.record else None, item.recording,
                    mode, method["correction"])
        future = client.submit(run_task, task, key=f"aatest-{mode}-{mhash[:12]}-{index}",
                               pure=False)
        futures[future] = item
    for future in as_completed(futures):
        item = futures.pop(future)
        try:
            result = future.result()
        except Exception as exc:  # noqa: BLE001 - any task error is reported, the batch goes on
            report.failures.append(Failure(item.subject, item.recording,
                                           f"{type(exc).__name__}: {' '.join(str(exc).split())}"))
            say(f"failed {item.recording}: {report.failures[-1].error}")
        else:
            ledger.append(store, _stored_values(item, mode, mhash, method, result))
            report.completed.append(item.subject)
        future.release()
        say(report.line())
