"""Calls made aside (:mod:`aatest.parallel.aside`): the results of calling in place, made by
other processes while this one goes on; in place wherever aside cannot serve, errors raised
here; nothing left behind."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from aatest.parallel import aside
from aatest.parallel.forked import WORKERS_ENV
from aatest.plugins.analysis.sync_summary import sync_plot
from aatest.presentation.figures import DrawnFigures, drawing_aside, drawn

PARENT = os.getpid()
#: set by :func:`_warm` in the process that warms up
WARMED: list[int] = []


@pytest.fixture(autouse=True)
def _two_workers(two_workers: None) -> None:
    """Two workers, the test's own threads counted (``two_workers``, tests/conftest.py)."""


def _warm() -> None:
    WARMED.append(os.getpid())


def _product_and_pid(x: int, y: float) -> tuple[float, int, list[int]]:
    return x * y, os.getpid(), list(WARMED)


def _raises(x: int) -> None:
    raise ValueError(f"call {x} failed in process {os.getpid()}")


def _children() -> set[int]:
    """The live (not zombie) child processes of this one."""
    found = set()
    for task in Path(f"/proc/{PARENT}/task").iterdir():
        children = (task / "children").read_text().split()
        for pid in map(int, children):
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            if state != "Z":
                found.add(pid)
    return found


def _asides() -> list[Path]:
    """This process's blocks' directories (other test processes make theirs meanwhile)."""
    return sorted(Path(tempfile.gettempdir()).glob(f"aatest-aside-{PARENT}-*"))


def test_results_are_those_in_place_made_by_two_warmed_processes() -> None:
    before, dirs = _children(), _asides()
    with aside.running(_warm):
        laters = [aside.submit(_product_and_pid, x, 1.5) for x in range(6)]
        out = [later.result() for later in laters]
    assert [value for value, _, _ in out] == [x * 1.5 for x in range(6)]
    pids = {pid for _, pid, _ in out}
    assert PARENT not in pids and len(pids) == 2  # the lanes, in turn
    # warmed once, in the first process aside, before it forked the second
    assert all(warmed == [out[0][1]] for _, _, warmed in out) and not WARMED
    assert _children() == before and _asides() == dirs  # all ended, the directory gone


def test_outside_a_block_calls_are_made_now_in_place() -> None:
    later = aside.submit(_product_and_pid, 2, 3.0)
    assert later.result()[:2] == (6.0, PARENT)


def test_a_call_that_fails_aside_raises_here_with_its_own_error() -> None:
    with aside.running(), pytest.raises(ValueError, match=f"call 3 failed in process {PARENT}$"):
        aside.submit(_raises, 3).result()


def test_calls_that_do_not_pickle_are_made_in_place() -> None:
    lock = threading.Lock()
    with aside.running():
        later = aside.submit(lambda: (lock.locked(), os.getpid()))
        assert later.result() == (False, PARENT)


def test_a_process_aside_killed_leaves_its_calls_to_this_one() -> None:
    with aside.running():
        first = aside.submit(_product_and_pid, 1, 1.0)
        assert first.result()[1] != PARENT
        block = aside._SLOT.block
        assert block is not None
        for pid in block.started:
            os.kill(pid, signal.SIGKILL)
        time.sleep(0.05)
        later = aside.submit(_product_and_pid, 4, 2.0)
        assert later.result()[0] == 8.0


def test_idle_processes_end_and_later_calls_start_new_ones() -> None:
    with aside.running():
        first = aside.submit(_product_and_pid, 1, 1.0).result()[1]
        block = aside._SLOT.block
        assert block is not None and len(block.started) == 1
        deadline = time.monotonic() + 10 * aside.IDLE_S + 5.0
        while {p for p in _children() if p in block.started} and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not {p for p in _children() if p in block.started}, "still running when idle"
        value, pid, _ = aside.submit(_product_and_pid, 3, 2.0).result()
        assert value == 6.0 and pid not in (first, PARENT) and len(block.started) == 2


def test_a_block_that_raises_kills_its_processes_and_calls_are_made_in_place() -> None:
    before = _children()
    with pytest.raises(KeyError), aside.running():
        later = aside.submit(_product_and_pid, 5, 1.0)
        raise KeyError("stop")
    assert _children() == before
    assert later.result()[0] == 5.0


def test_a_killed_process_leaves_its_directory_to_the_next_block(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    """A run killed inside its block leaves its directory; the next block removes it, and
    keeps the directories of processes that live."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    dead = tmp_path / f"aatest-aside-{gone}-x1"
    alive = tmp_path / f"aatest-aside-{os.getppid()}-x2"
    for directory in (dead, alive):
        directory.mkdir()
        (directory / "0.call").write_bytes(b"left")
    with aside.running():
        assert aside.submit(_product_and_pid, 2, 2.0).result()[0] == 4.0
    assert not dead.exists() and alive.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [alive.name]  # the block's own: gone


#: where :func:`_warm_marking` marks that it ran (set by the test that starts ahead)
MARKS: list[Path] = []


def _warm_marking() -> None:
    WARMED.append(os.getpid())
    (MARKS[0] / f"warmed-{os.getpid()}").touch()


def test_processes_started_ahead_warm_before_the_first_call(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """:func:`aside.ahead` forks the block's processes before any call: they warm while this
    process goes on, and serve the calls sent later (none is started again)."""
    monkeypatch.setattr(aside, "IDLE_S", 10.0)  # a loaded machine's pauses do not end them
    before = _children()
    MARKS[:] = [tmp_path]
    with aside.running(_warm_marking):
        aside.ahead()
        block = aside._SLOT.block
        assert block is not None and len(block.started) == 1
        assert _children() - before, "nothing forked ahead"
        deadline = time.monotonic() + 10.0  # no call sent yet: the warm runs on its own
        while not list(tmp_path.glob("warmed-*")) and time.monotonic() < deadline:
            time.sleep(0.01)
        marks = [p.name for p in tmp_path.glob("warmed-*")]
        assert marks == [f"warmed-{block.started[0]}"], marks
        out = [aside.submit(_product_and_pid, x, 2.0).result() for x in range(4)]
        aside.ahead()  # processes run: none started again
        assert len(block.started) == 1
    assert [value for value, _, _ in out] == [x * 2.0 for x in range(4)]
    assert PARENT not in {pid for _, pid, _ in out} and out[0][1] == block.started[0]
    assert all(warmed == [block.started[0]] for _, _, warmed in out) and not WARMED
    assert _children() == before


def test_nothing_starts_ahead_outside_a_block_or_beside_a_thread() -> None:
    before = _children()
    aside.ahead()
    assert _children() == before
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, name="other", daemon=True)
    other.start()
    try:
        with aside.running():
            aside.ahead()
            block = aside._SLOT.block
            assert block is not None and block.started == [] and _children() == before
    finally:
        stop.set()
        other.join()


def test_no_process_aside_while_another_thread_runs() -> None:
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, name="other", daemon=True)
    other.start()
    try:
        with aside.running():
            assert aside.submit(_product_and_pid, 1, 2.0).result()[1] == PARENT
    finally:
        stop.set()
        other.join()


def test_a_figure_drawn_aside_is_the_same_svg_as_drawn_here() -> None:
    drift_ppm, residual_us = [1.0, 1.5, 0.5, 2.0], [3.0, 2.0, 4.0, 1.0]
    here = sync_plot(drift_ppm, residual_us)
    with drawing_aside():
        figures = DrawnFigures({"sync": drawn(sync_plot, drift_ppm, residual_us),
                                "given": "<svg/>"})
        assert len(figures) == 2 and list(figures) == ["sync", "given"]
        assert figures["sync"] == here and figures["given"] == "<svg/>"


_ANALYSE = """
import json, logging, sys
from pathlib import Path
logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
logging.getLogger("aatest.workers").setLevel(logging.DEBUG)
from aatest.engine.run import session
out = Path(sys.argv[2])
session.analyse_and_report(Path(sys.argv[1]), out, lab_duration_s=1.0, wall_duration_s=1.0)
print(json.dumps(json.loads((out / "results.json").read_text())["figures"]))
"""


def test_an_analysis_pass_draws_its_figures_aside_the_same_svg(tmp_path: Path) -> None:
    """``aatest analyze`` of a small stepped sine in a fresh process (no thread beside it,
    unlike this test process): its figures drawn aside are the bytes drawn in place."""
    recording = Path(__file__).parents[1] / "recording/data/streaming/recording.mcap"
    figures, logs = {}, {}
    for workers in ("2", "1"):
        run = tmp_path / f"run-{workers}"
        run.mkdir()
        shutil.copy(recording, run / "recording.mcap")
        env = {**os.environ, WORKERS_ENV: workers}
        done = subprocess.run([sys.executable, "-c", _ANALYSE, str(run), str(run)], env=env,
                              capture_output=True, text=True, timeout=300, check=True)
        figures[workers], logs[workers] = json.loads(done.stdout), done.stderr
    assert "calls made aside by 2 processes" in logs["2"], logs["2"]
    assert "calls made aside" not in logs["1"]
    assert {"sync", "frf", "transfer_function"} <= set(figures["2"])
    assert figures["2"] == figures["1"]
