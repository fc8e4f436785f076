"""Uniform random numbers drawn ahead of the computation that consumes them.

Why: a short step's table log and DAQ log draw from one generator, the table log's draws
first (:func:`aatest.twin.step_synthesis.synthesise`). Those draws are cheap; the computation
around them (the axes' motion on the table grid, the estimates) is not. Drawing the table
log's uniforms first, in one call, hands the generator on to the DAQ log at once, so the two
logs compute on two threads while every number drawn stays the one a serial synthesis
draws: PCG64's ``random(a + b)`` is ``random(a)`` followed by ``random(b)``, one 64-bit output
per double.

The tape only serves ``random(size)`` (what :func:`aatest.twin.fastmath.standard_normal`
draws) and counts: a consumer that asks for anything else, or for more or fewer numbers than
were drawn ahead, is reported (:class:`DrawsDiffer`) and the caller redoes the step serially
from the generator's saved state, so a change of what the table log draws costs time, never
a recorded byte.
"""

from __future__ import annotations

from typing import Any, NoReturn

import numpy as np


class DrawsDiffer(Exception):  # noqa: N818 - control flow inside the twin, never raised out
    """The consumer drew differently from the draws made ahead (the caller falls back)."""


class UniformTape:
    """``count`` uniforms drawn now from ``rng``, served in order through :meth:`random`.

    Parameters
    ----------
    rng
        The generator the consumer would have drawn from; it is advanced by ``count`` doubles.
    count
        How many uniforms the consumer will draw in all.
    """

    def __init__(self, rng: np.random.Generator, count: int) -> None:
        self._uniforms = rng.random(count)
        self._used = 0

    def random(self, size: Any = None, dtype: Any = None, out: Any = None) -> np.ndarray:
        """The next ``size`` uniforms, as ``Generator.random(size)`` would return them."""
        if dtype is not None or out is not None or not isinstance(size, int | np.integer):
            raise DrawsDiffer(f"random(size={size!r}, dtype={dtype!r}, out={out!r})")
        end = self._used + int(size)
        if end > self._uniforms.size:
            raise DrawsDiffer(f"{end} uniforms asked, {self._uniforms.size} drawn ahead")
        chunk = self._uniforms[self._used:end]  # regions are disjoint: the caller owns it
        self._used = end
        return chunk

    def __getattr__(self, name: str) -> NoReturn:
        raise DrawsDiffer(f"the consumer calls Generator.{name}, not drawn ahead")

    @property
    def exhausted(self) -> bool:
        """Whether the consumer drew exactly the numbers drawn ahead."""
        return self._used == self._uniforms.size


def normal_uniforms(n: int) -> int:
    """Uniforms consumed by ``fastmath.standard_normal(rng, n)`` (Box–Muller in pairs)."""
    return 2 * ((n + 1) // 2)
