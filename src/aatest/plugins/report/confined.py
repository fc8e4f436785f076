"""Render a report template in a child process with CPU and memory limits.

The sandbox (:mod:`.sandbox`) refuses what a template could do to the machine through Python
(internals, files) and caps the obvious bombs (repetition, powers, widths), but a template is
code: nested loops can spin for minutes, and Jinja has more ways to allocate than can be
enumerated. So the render runs in a fresh Python process (not a fork: the station renders
from a worker thread) whose limits the kernel enforces — :data:`RENDER_CPU_S` of CPU
(``RLIMIT_CPU``) and :data:`RENDER_MEMORY_BYTES` of address space beyond what the child holds
once loaded (``RLIMIT_AS``) — and the parent waits at most :data:`RENDER_WALL_S`. Exceeding
any of them is a :class:`~.sandbox.TemplateSecurityError` (exit 2) naming the template.

The child (:mod:`.confined_child`) receives the template's name, its lab directory and the
view model (pickled: the parent built it, so nothing untrusted is unpickled) on stdin and
answers the same way.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from aatest.plugins.report.template_errors import TemplateError, TemplateSecurityError

#: CPU seconds a render may use (the shipped certificate renders in well under 1 s)
RENDER_CPU_S = 10
#: address space a render may add to the loaded child (the certificate needs a few MB)
RENDER_MEMORY_BYTES = 512 * 1024 * 1024
#: wall seconds the parent waits (the CPU limit plus start-up on a busy machine)
RENDER_WALL_S = 60.0
_PACKAGE_ROOT = Path(__file__).resolve().parents[3]
#: the module the child runs: it imports the sandbox, which imports this module for the parent
_CHILD = "aatest.plugins.report.confined_child"


def _child_env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(_PACKAGE_ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]),
        "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _spawn(env: Mapping[str, str], ahead: str | None = None) -> subprocess.Popen[bytes]:
    """A render child: it imports the sandbox (and compiles the shipped template ``ahead``,
    when named), then waits for its request on stdin."""
    return subprocess.Popen([sys.executable, "-m", _CHILD, *([ahead] if ahead else [])],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=dict(env))


#: render children started ahead (:func:`prestarted`), with the environment each was given
_WAITING: list[tuple[dict[str, str], subprocess.Popen[bytes]]] = []
_WAITING_LOCK = threading.Lock()


def _end(child: subprocess.Popen[bytes]) -> None:
    child.kill()
    child.communicate()


def _take(env: Mapping[str, str]) -> subprocess.Popen[bytes] | None:
    """A child started ahead with this environment (else None; a stale one is ended)."""
    with _WAITING_LOCK:
        waiting, _WAITING[:] = list(_WAITING), []
    found = None
    for child_env, child in waiting:
        if found is None and child_env == env and child.poll() is None:
            found = child
        else:
            _end(child)
    return found


@contextlib.contextmanager
def prestarted(template: str | None = None) -> Iterator[None]:
    """Start a render child now and let :func:`render_confined` inside this block use it.

    Why: the child spends ≈ 0.4 s of CPU importing Jinja2 and the results models before it
    reads its request; started while the caller still works (writing results.json), that
    time overlaps the caller's, on another core. So does its compile of the shipped
    ``template`` (a file name), when named (≈ 0.05 s; a render of another template, or from a
    lab's directory, compiles its own). A child no render took is ended on exit.
    Inside another such block whose child still waits, it starts none.
    Nothing else changes: the request, the limits (counted from when the child reads the
    request) and the answer are those of a child started at the render.
    """
    env = _child_env()
    with _WAITING_LOCK:
        if any(child_env == env for child_env, _ in _WAITING):  # an outer block's child waits
            child = None
        else:
            child = _spawn(env, template)
            _WAITING.append((env, child))
    try:
        yield
    finally:
        with _WAITING_LOCK:
            left = [(e, c) for e, c in _WAITING if c is child]
            _WAITING[:] = [(e, c) for e, c in _WAITING if c is not child]
        for _, unused in left:
            _end(unused)


def render_confined(name: str, template_dir: Path | None, context: Mapping[str, Any],
                    cpu_s: int = RENDER_CPU_S, memory_bytes: int = RENDER_MEMORY_BYTES) -> str:
    """Render template ``name`` (from ``template_dir`` or the shipped ones) in a child process.

    The child may use ``cpu_s`` CPU seconds and ``memory_bytes`` more address space than it
    holds once loaded (defaults :data:`RENDER_CPU_S`, :data:`RENDER_MEMORY_BYTES`); a child
    started ahead (:func:`prestarted`) is used when there is one.

    Raises :class:`~.sandbox.TemplateError` (exit 2) for a broken template and
    :class:`~.sandbox.TemplateSecurityError` for one refused by the sandbox or stopped by a
    limit; the message names the template.
    """
    where = f"{template_dir}/{name}" if template_dir is not None else name
    payload = pickle.dumps((name, template_dir, dict(context), cpu_s, memory_bytes))
    env = _child_env()
    child = _take(env) or _spawn(env)
    try:
        stdout, stderr = child.communicate(payload, timeout=RENDER_WALL_S)
    except subprocess.TimeoutExpired as exc:
        _end(child)
        raise TemplateSecurityError(
            f"{where}: template stopped after {RENDER_WALL_S:.0f} s of wall time") from exc
    if child.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        raise TemplateSecurityError(f"{where}: template stopped at its limit of {cpu_s} s CPU")
    try:
        kind, value = pickle.loads(stdout)
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError) as exc:
        tail = stderr.decode("utf-8", "replace").strip().splitlines()[-1:] or ["no output"]
        raise TemplateError(f"{where}: the render process failed (exit {child.returncode}): "
                            f"{tail[0]}") from exc
    if kind == "ok":
        return str(value)
    error = TemplateSecurityError if kind == "refused" else TemplateError
    raise error(str(value))
