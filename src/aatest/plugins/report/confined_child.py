"""The child process of a confined render (:mod:`.confined`): limit itself, render, answer.

Run as ``python -m aatest.plugins.report.confined_child [TEMPLATE…]`` with the pickled request
on stdin (the shipped templates named are compiled while it waits for it); it answers
``(kind, text)`` pickled on stdout. It lives apart from the parent's side so that
the sandbox, which it renders with, can call the parent's side without an import cycle.
"""

from __future__ import annotations

import pickle
import resource
import sys

from aatest.plugins.report.sandbox import compile_ahead, load_template, render_in_process
from aatest.plugins.report.template_errors import TemplateError, TemplateSecurityError


def _limit_child(cpu_s: int, memory_bytes: int) -> None:
    """Cap this (child) process: CPU seconds, and address space beyond what it holds now."""
    used_s = resource.getrusage(resource.RUSAGE_SELF)
    spent = int(used_s.ru_utime + used_s.ru_stime) + 1  # start-up and loading count too
    resource.setrlimit(resource.RLIMIT_CPU, (spent + cpu_s, spent + cpu_s + 1))
    with open("/proc/self/statm", encoding="ascii") as fh:
        held = int(fh.read().split()[0]) * resource.getpagesize()
    resource.setrlimit(resource.RLIMIT_AS, (held + memory_bytes,) * 2)


def _child(ahead: list[str]) -> None:
    """The child's work: compile the shipped templates named ``ahead`` and those they
    reference (their sandbox keeps them: a request for one finds them compiled), read the
    request, limit itself, render, answer on stdout."""
    for name in ahead:
        compile_ahead(name)
    name, template_dir, context, cpu_s, memory_bytes = pickle.loads(sys.stdin.buffer.read())
    template = load_template(name, template_dir)
    where = str(template.filename or name)
    _limit_child(cpu_s, memory_bytes)
    try:
        answer: tuple[str, str] = ("ok", render_in_process(template, context))
    except TemplateSecurityError as exc:
        answer = ("refused", str(exc))
    except TemplateError as exc:
        answer = ("error", str(exc))
    except MemoryError:
        answer = ("refused", f"{where}: template stopped at its limit of "
                             f"{memory_bytes // 2**20} MiB memory")
    sys.stdout.buffer.write(pickle.dumps(answer))


if __name__ == "__main__":
    _child(sys.argv[1:])
