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

import os
import pickle
import signal
import subprocess
import sys
from collections.abc import Mapping
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


def render_confined(name: str, template_dir: Path | None, context: Mapping[str, Any],
                    cpu_s: int = RENDER_CPU_S, memory_bytes: int = RENDER_MEMORY_BYTES) -> str:
    """Render template ``name`` (from ``template_dir`` or the shipped ones) in a child process.

    The child may use ``cpu_s`` CPU seconds and ``memory_bytes`` more address space than it
    holds once loaded (defaults :data:`RENDER_CPU_S`, :data:`RENDER_MEMORY_BYTES`).

    Raises :class:`~.sandbox.TemplateError` (exit 2) for a broken template and
    :class:`~.sandbox.TemplateSecurityError` for one refused by the sandbox or stopped by a
    limit; the message names the template.
    """
    where = f"{template_dir}/{name}" if template_dir is not None else name
    payload = pickle.dumps((name, template_dir, dict(context), cpu_s, memory_bytes))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(_PACKAGE_ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]),
        "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    try:
        done = subprocess.run([sys.executable, "-m", _CHILD], input=payload,
                              capture_output=True, timeout=RENDER_WALL_S, env=env, check=False)
    except subprocess.TimeoutExpired as exc:
        raise TemplateSecurityError(
            f"{where}: template stopped after {RENDER_WALL_S:.0f} s of wall time") from exc
    if done.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        raise TemplateSecurityError(f"{where}: template stopped at its limit of {cpu_s} s CPU")
    try:
        kind, value = pickle.loads(done.stdout)
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError) as exc:
        tail = done.stderr.decode("utf-8", "replace").strip().splitlines()[-1:] or ["no output"]
        raise TemplateError(f"{where}: the render process failed (exit {done.returncode}): "
                            f"{tail[0]}") from exc
    if kind == "ok":
        return str(value)
    error = TemplateSecurityError if kind == "refused" else TemplateError
    raise error(str(value))
