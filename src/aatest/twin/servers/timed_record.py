"""A logger's timed record served by a simulated controller: what the ACUTROL-class and the
Modbus controller simulators share when the CAN logger asks them to stream a long record.

The World generates the record lazily; the table's head log must be made after the record's
first chunk, as the in-process table makes it after the DAQ's, so the two draw the same random
streams and the simulator's logs equal the in-process rig's sample for sample.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator

from aatest.engine.errors import RigFault
from aatest.engine.logs import SampledLog
from aatest.twin.world import World


def start_timed_record(world: World, samples: int) -> None:
    """Give the World's record the logger's length (``samples`` after the trigger) and raise
    the DAQ's trigger line.

    Raises
    ------
    ValueError
        The World refuses that length (the logger refuses the timed record).
    """
    try:
        world.set_record_samples(samples)
    except RigFault as exc:
        raise ValueError(str(exc)) from exc
    world.start_daq()


def stream_after_first_chunk(world: World, after_first: Callable[[], None]
                             ) -> Iterator[SampledLog]:
    """The record's DAQ log in chunks (one in memory at a time), calling ``after_first`` once
    the first chunk exists (the controller arms its head log there)."""
    chunks = world.stream_daq(1)
    first = next(chunks, None)
    after_first()
    return itertools.chain([] if first is None else [first], chunks)
