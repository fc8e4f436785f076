"""The run directory's small state file, so ``--resume`` knows what it is continuing.

Recorded steps are known from the atomic per-step recording files; this file adds what the
recording cannot show (the procedure hash the run belongs to, seed, finished chamber steps,
wall time spent so far). It is replaced atomically on every change. While a run executes, it
holds an exclusive ``fcntl.flock`` on ``run.lock`` (which names its PID), so a second
``run --resume`` on the same directory stops at once with exit 2 (docs/interfaces.md §1).
"""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

from aatest.engine.errors import InputError
from aatest.storage import RemotePath

STATE_FILE = "run_state.json"
LOCK_FILE = "run.lock"


@dataclass
class RunState:
    """What ``--resume`` needs beyond the recording.

    The procedure hash and seed the run belongs to, the finished chamber steps, the wall time
    spent so far (``wall_duration_s``, s), the operator prompts already shown and their answers.
    """

    procedure: str
    procedure_sha256: str
    seed: int
    chamber_steps_done: list[str] = field(default_factory=list)
    wall_duration_s: float = 0.0
    prompts_shown: list[str] = field(default_factory=list)
    #: who confirmed each prompt and when (``PromptAnswer.as_json()``), for traceability
    prompt_answers: list[dict[str, str]] = field(default_factory=list)
    #: what each soak until stable achieved (set-point, sensor °C, spread, window, soak time)
    soak_stability: list[dict[str, float]] = field(default_factory=list)
    finished: bool = False

    def save(self, run_dir: Path) -> None:
        """Write the state atomically (temporary file, fsync, rename) into ``run_dir``.

        A state unchanged since this object last saved it to the same file is not written
        again: the file holds it already, and the fsync (≈ 12 ms on a virtual disk, in the
        step loop after every step) bought nothing.
        """
        text = json.dumps(asdict(self), indent=2)
        path = run_dir / STATE_FILE
        if vars(self).get("_saved_as") == (path, text) and path.exists():
            return
        tmp = run_dir / (STATE_FILE + ".tmp")
        with tmp.open("w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        vars(self)["_saved_as"] = (path, text)

    @classmethod
    def load(cls, run_dir: Path | RemotePath) -> RunState:
        """Read the state of ``run_dir``; a missing or damaged file is an InputError."""
        path = run_dir / STATE_FILE
        try:
            return cls(**json.loads(path.read_text(encoding="utf-8")))
        except FileNotFoundError as exc:
            raise InputError(f"{run_dir}: nothing to resume (no {STATE_FILE})") from exc
        except (json.JSONDecodeError, TypeError) as exc:
            raise InputError(f"{path}: unreadable run state: {exc}") from exc


def open_state(run_dir: Path, procedure: str, sha256: str, seed: int, resume: bool) -> RunState:
    """New state for a fresh run, or the saved one for ``--resume`` (same procedure only)."""
    if not resume:
        if (run_dir / STATE_FILE).exists():
            raise InputError(
                f"{run_dir} already holds a run; "
                "use --resume to continue it or choose another --out"
            )
        run_dir.mkdir(parents=True, exist_ok=True)
        state = RunState(procedure, sha256, seed)
        state.save(run_dir)
        return state
    state = RunState.load(run_dir)
    if state.procedure_sha256 != sha256:
        raise InputError(
            f"{run_dir}: the procedure file changed since the run started "
            f"(sha256 {state.procedure_sha256[:12]}… vs {sha256[:12]}…); resume refused"
        )
    return state


@contextmanager
def run_lock(run_dir: Path) -> Iterator[None]:
    """Hold the run directory's lock for the duration of a run.

    The kernel drops an ``flock`` when its holder dies, so a crashed or killed run never leaves
    a stale lock behind; the PID written into the file is only there to name the holder.

    Raises
    ------
    InputError
        Another process holds the lock (the message names its PID).
    """
    run_dir.mkdir(parents=True, exist_ok=True)
    path = run_dir / LOCK_FILE
    with path.open("a+", encoding="utf-8") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError as exc:
            fh.seek(0)
            holder = fh.read().strip() or "unknown"
            raise InputError(f"{run_dir} is in use by another aatest run (PID {holder}, lock "
                             f"{path}); wait for it to end or stop it first") from exc
        try:
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
            fh.flush()
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
