"""Uniforms drawn ahead must be the numbers the generator would have given the consumer."""

from __future__ import annotations

import numpy as np
import pytest

from aatest.twin.drawn_ahead import DrawsDiffer, UniformTape, normal_uniforms
from aatest.twin.fastmath import standard_normal


def test_the_tape_serves_the_generators_own_sequence() -> None:
    """PCG64 gives one double per 64-bit output: drawn in one call or in pieces, the same
    numbers, and the generator ends in the same state (exact: no arithmetic involved)."""
    tape = UniformTape(np.random.default_rng(3), 2 * normal_uniforms(1001) + 10)
    reference = np.random.default_rng(3)
    assert np.array_equal(standard_normal(tape, 1001), standard_normal(reference, 1001))  # type: ignore[arg-type]
    assert np.array_equal(tape.random(10), reference.random(10))
    assert not tape.exhausted
    assert np.array_equal(standard_normal(tape, 1001), standard_normal(reference, 1001))  # type: ignore[arg-type]
    assert tape.exhausted


def test_the_generator_is_advanced_by_exactly_the_count() -> None:
    rng, reference = np.random.default_rng(4), np.random.default_rng(4)
    UniformTape(rng, 77)
    reference.random(77)
    assert rng.bit_generator.state == reference.bit_generator.state


@pytest.mark.parametrize("draw", [
    lambda t: t.random(5),  # more than drawn ahead
    lambda t: t.random(2, dtype=np.float32),
    lambda t: t.random((2, 1)),
    lambda t: t.standard_normal(2),
], ids=["too-many", "dtype", "shape", "other-method"])
def test_any_other_draw_is_reported(draw: object) -> None:
    tape = UniformTape(np.random.default_rng(0), 4)
    with pytest.raises(DrawsDiffer):
        draw(tape)  # type: ignore[operator]
