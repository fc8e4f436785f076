"""What the live table-status poll costs a run: step-loop wall time with and without it.

Usage::

    python bench/status_poll.py [--procedure tests/station/data/quick-sine-3-steps.yaml] [--runs 3]

Runs the procedure on the digital twin ``--runs`` times with the poll (the turntable's
``status()`` read every 0.1 s in its own thread, as ``aatest run`` and the station do) and as
many times without it (the poll replaced by a no-op), alternating, and prints the median step-loop
wall time of each (``run_state.json``'s ``wall_duration_s``) and their ratio. Ratios only: on a
shared machine the absolute times mean little, the ratio of interleaved runs does.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import tempfile
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

from aatest.engine.run import runner
from aatest.engine.run.session import run

DEFAULT = Path(__file__).parents[1] / "tests" / "station" / "data" / "quick-sine-3-steps.yaml"


@contextlib.contextmanager
def _no_poll(*_args: object, **_kwargs: object) -> Iterator[None]:
    yield None


def _loop_wall_s(procedure: Path, out: Path, poll: bool) -> float:
    """The step loop's wall time (s) of one run of ``procedure`` into ``out``."""
    patch = contextlib.nullcontext() if poll else mock.patch.object(
        runner, "polling_status", _no_poll)
    with patch:
        run(procedure, None, out, False, 3, None, show_progress=False)
    return float(json.loads((out / "run_state.json").read_text())["wall_duration_s"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--procedure", type=Path, default=DEFAULT)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    times: dict[bool, list[float]] = {True: [], False: []}
    with tempfile.TemporaryDirectory() as work:
        for k in range(args.runs):
            for poll in (True, False):
                out = Path(work) / f"{'poll' if poll else 'quiet'}-{k}"
                times[poll].append(_loop_wall_s(args.procedure, out, poll))
    polled, quiet = statistics.median(times[True]), statistics.median(times[False])
    print(f"procedure {args.procedure.name}, {args.runs} runs each, step loop on the twin")
    print(f"  with the status poll    {polled:8.3f} s (median)")
    print(f"  without it              {quiet:8.3f} s (median)")
    print(f"  ratio with / without    {polled / quiet:8.3f}")


if __name__ == "__main__":
    main()
