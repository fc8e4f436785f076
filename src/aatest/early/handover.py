"""A step's logs handed from the run process to the early-analysis child in shared memory,
exactly as the child would decode them from the step file just written.

Why: the child used to read back every step file the run process had just written and decode
it (≈ 14 ms of CPU a stepped-sine step, 38 % of the child's CPU), while the run process held
the very arrays it had handed the recorder. The writer's codes are exact by construction
(:mod:`aatest.recording.channel_codes`: a block is stored as codes only where
``code·quantum + offset`` gives back every value, else as float64 values), so a decode gives
back the logged arrays bit for bit — with one exception, which this module reproduces: a
``-0.0`` in a block stored as codes comes back as ``+0.0`` (a code carries no sign of zero;
the twin's encoders and rates at rest log hundreds a step). So each float channel is copied
block by block, as ``x + 0.0`` where the writer coded the block (which turns ``-0.0`` into
``+0.0`` and leaves every other value, NaN never being in a coded block) and verbatim where it
stored the values (:func:`~aatest.recording.codec.encode_block_pieces` reports which). The rest
of a decoded log is rebuilt as the reader builds it: the step record's sample rate and
quantisation (a JSON round trip of floats is exact), every channel's unit (``""`` where the log
named none), the logged dtypes and order, the time stamps as float64; pieces are the written
blocks (``BLOCK_SAMPLES`` samples each), as :meth:`LazySteps.pieces` decodes them.

How: anonymous memory files (``memfd``, :class:`Segment`), one filled right after each step
file is written, its descriptor passed over a Unix socket and mapped read-only by the child,
which unmaps it before it sends the step's result back; the run process then reuses it for a
later step. Only the channels the child read of the steps before are handed (it decodes any
other from the file). Nothing has a name, so nothing can leak: the kernel frees the memory
when the last descriptor and mapping are gone (the run process closes its own when the child
is reaped, or by dying; a killed child's, and those still queued in the socket, go with it).
``tests/early/test_handover.py`` checks the arrays equal a decode, bit for bit.

Measured on 24 twin stepped-sine steps (CPU per step, medians): the child's work 33.6 ms
decoding the file and fitting the relation, 14.3 ms handed (the same ``Made``, bit for bit);
the run process pays 1.5 ms to fill a reused segment with the 10 arrays the child reads and
0.7 ms to digest the step file it wrote (a new segment per step cost ≈ 13 ms more: its pages'
allocation and zeroing).
"""

from __future__ import annotations

import contextlib
import mmap
import os
from collections.abc import Container, Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from aatest.engine.logs import SampledLog

#: byte alignment of each array in a segment (a cache line)
_ALIGN = 64
#: the float channels whose copies must equal the logged arrays for a clock relation fitted
#: on the latter to be the one the child would fit (besides the time stamps; the sync pass's
#: inputs, :data:`aatest.plugins.analysis.sync_watches.SYNC_CHANNELS`)
RELATION_INPUTS = {"table": ("time_s", "sync_pulse", "fp_latch_s"),
                   "daq": ("time_s", "sync_pulse", "trigger")}


@dataclass(frozen=True)
class ArrayAt:
    """One array of a segment: its channel (``time_s``: the time stamps), dtype and place."""

    name: str
    dtype: str
    offset: int


@dataclass(frozen=True)
class LogLayout:
    """One logger's log in a segment, with what the reader rebuilds around the arrays."""

    source: str
    sample_rate_hz: float
    samples: int
    #: channel name → unit, every channel (``""`` where the log named none), logged order
    units: tuple[tuple[str, str], ...]
    quantisation: tuple[tuple[str, tuple[float, float]], ...]
    #: the time stamps first, then the handed channels in logged order (a step may hand
    #: only the channels the child reads: :func:`layout`)
    arrays: tuple[ArrayAt, ...]

    @property
    def names(self) -> tuple[str, ...]:
        """Every channel of the log, handed or not, in logged order."""
        return tuple(name for name, _ in self.units)


@dataclass(frozen=True)
class Handed:
    """What the child is told with a step handed in shared memory (the segment itself comes
    over the socket)."""

    #: :func:`~aatest.recording.step_chunks.step_digests` of the file the arrays were written to
    digest: str
    size: int
    #: samples of each written block (the pieces :meth:`LazySteps.pieces` yields)
    block_samples: int
    logs: tuple[LogLayout, ...]
    #: whether the relation's inputs (:data:`RELATION_INPUTS`) are the logged arrays bit for
    #: bit (no ``-0.0`` turned ``+0.0``): a relation fitted on the logged arrays is then the
    #: one a fit of these gives
    relation_inputs_exact: bool


def _aligned(size: int) -> int:
    return -(-size // _ALIGN) * _ALIGN


def layout(logs: Sequence[SampledLog], wanted: Mapping[str, Container[str]] | None = None
           ) -> tuple[tuple[LogLayout, ...], int]:
    """Where each array of ``logs`` goes in a segment, and the segment's size in bytes.

    ``wanted``: by logger, the only channels to hand (with the time stamps and the clock
    relation's inputs, :data:`RELATION_INPUTS`); None: every channel.
    """
    offset = 0
    layouts = []
    for log in logs:
        arrays = []
        for name, values in _handed_arrays(log, wanted):
            arrays.append(ArrayAt(name, values.dtype.str, offset))
            offset += _aligned(values.nbytes)
        layouts.append(LogLayout(
            log.source, float(log.sample_rate_hz), len(log),
            tuple((name, str(log.units.get(name, ""))) for name in log.channels),
            tuple((k, (float(q), float(o))) for k, (q, o) in log.quantisation.items()),
            tuple(arrays)))
    return tuple(layouts), max(offset, 1)


def _handed_arrays(log: SampledLog, wanted: Mapping[str, Container[str]] | None
                   ) -> list[tuple[str, np.ndarray]]:
    """The time stamps and the channels of ``log`` to hand (see :func:`layout`)."""
    chosen = log.channels.items() if wanted is None else [
        (name, values) for name, values in log.channels.items()
        if name in wanted.get(log.source, ()) or name in RELATION_INPUTS.get(log.source, ())]
    return [("time_s", log.time_s), *chosen]


_POPULATE = getattr(mmap, "MAP_POPULATE", 0)


class Segment:
    """A memory file the run process fills with a step's logs and hands to the child, then
    fills again with a later step's once the child has sent that step's result back (it has
    unmapped it by then).

    Why reused: a new memory file costs its pages' allocation and zeroing, ≈ 13 ms of CPU for
    a stepped-sine step's 16.5 MB (measured), ten times the copy itself; a reused one keeps
    its pages (resized to each step's arrays: only a longer tail is allocated).
    """

    def __init__(self) -> None:
        self.fd = os.memfd_create("aatest-early-step", os.MFD_CLOEXEC)
        self.size = 0
        self._mapping: mmap.mmap | None = None

    def mapped(self, size: int) -> mmap.mmap:
        """This process's read-write mapping, the file resized to ``size`` bytes."""
        if self._mapping is None or size != self.size:
            self._unmap()
            os.ftruncate(self.fd, size)
            self.size = size
            self._mapping = mmap.mmap(self.fd, size, flags=mmap.MAP_SHARED | _POPULATE,
                                      prot=mmap.PROT_READ | mmap.PROT_WRITE)
        return self._mapping

    def _unmap(self) -> None:
        if self._mapping is not None:
            self._mapping.close()
            self._mapping = None

    def close(self) -> None:
        """Unmap and close (the memory goes once the child has no mapping or descriptor)."""
        self._unmap()
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def fill(segment: Segment, logs: Sequence[SampledLog],
         coded: Mapping[str, Mapping[str, Sequence[bool]]], block_samples: int,
         wanted: Mapping[str, Container[str]] | None = None
         ) -> tuple[tuple[LogLayout, ...], int, bool]:
    """Fill ``segment`` with ``logs`` as a decode of their step file gives them.

    ``coded``: by logger and channel, which written blocks are codes (from the writer);
    ``wanted``: see :func:`layout`. Returns the layouts, the size and whether the relation's
    inputs are unchanged (:attr:`Handed.relation_inputs_exact`).

    Raises
    ------
    OSError
        Out of memory; KeyError when ``coded`` lacks a channel.
    """
    layouts, size = layout(logs, wanted)
    exact = True
    into_bytes = segment.mapped(size)
    for log, placed in zip(logs, layouts, strict=True):
        verdicts = coded[log.source]
        inputs = RELATION_INPUTS.get(log.source, ())
        for at, (_, values) in zip(placed.arrays, _handed_arrays(log, wanted), strict=True):
            into = np.ndarray(values.shape, np.dtype(at.dtype), into_bytes, at.offset)
            _copy_as_decoded(values, into, verdicts[at.name], block_samples)
            if at.name in inputs and values.dtype.kind == "f" and not np.array_equal(
                    values.view(_UINT[values.itemsize]), into.view(_UINT[values.itemsize])):
                exact = False
            del into
    return layouts, size, exact


_UINT = {2: np.uint16, 4: np.uint32, 8: np.uint64}


def _copy_as_decoded(values: np.ndarray, into: np.ndarray, coded: Sequence[bool],
                     block_samples: int) -> None:
    """``values`` into ``into`` as a decode gives them: ``+ 0.0`` in float blocks stored as
    codes (``-0.0`` becomes ``+0.0``, nothing else changes), verbatim elsewhere."""
    if values.dtype.kind != "f" or not any(coded):
        np.copyto(into, values)
        return
    if all(coded):
        np.add(values, 0.0, out=into)
        return
    for block, is_coded in enumerate(coded):
        part = slice(block * block_samples, (block + 1) * block_samples)
        if is_coded:
            np.add(values[part], 0.0, out=into[part])
        else:
            np.copyto(into[part], values[part])


class Mapped:
    """A handed segment mapped read-only, as the logs a decode of the step file gives."""

    def __init__(self, fd: int, handed: Handed) -> None:
        self._segment = mmap.mmap(fd, handed.size, flags=mmap.MAP_SHARED | _POPULATE,
                                  prot=mmap.PROT_READ)
        self.handed = handed
        self.logs: dict[str, SampledLog] = {placed.source: self._log(placed)
                                            for placed in handed.logs}
        self._names = {placed.source: placed.names for placed in handed.logs}
        #: the channels asked for, by logger (handed or not): what the run process hands
        #: of the next steps
        self.read: dict[str, set[str]] = {source: set() for source in self.logs}

    def _log(self, placed: LogLayout) -> SampledLog:
        arrays = [np.frombuffer(self._segment, np.dtype(at.dtype), placed.samples, at.offset)
                  for at in placed.arrays]  # read-only: SampledLog keeps them as they are
        names = [at.name for at in placed.arrays[1:]]
        return SampledLog(placed.source, placed.sample_rate_hz, arrays[0],
                          dict(zip(names, arrays[1:], strict=True)), dict(placed.units),
                          dict(placed.quantisation))

    def samples(self, source: str) -> int:
        """The samples of logger ``source``'s log."""
        return len(self.logs[source])

    def holds(self, source: str, channels: Container[str] | None) -> bool:
        """Whether every channel of ``source``'s log in ``channels`` (all when None) was
        handed (noted in :attr:`read` either way)."""
        asked = [n for n in self._names[source] if channels is None or n in channels]
        self.read[source].update(asked)
        return all(n in self.logs[source].channels for n in asked)

    def log(self, source: str, channels: Container[str] | None = None) -> SampledLog:
        """Logger ``source``'s log with the time stamps and only ``channels`` (all when None),
        as a decode of only those channels gives it (when :meth:`holds` them)."""
        return subset(self.logs[source], channels)

    def pieces(self, source: str, channels: Container[str] | None = None
               ) -> Iterator[SampledLog]:
        """:meth:`log` as the written blocks, in order, as a piecewise decode gives them."""
        whole = self.log(source, channels)
        step = self.handed.block_samples
        for start in range(0, len(whole), step):
            part = slice(start, start + step)
            yield SampledLog(whole.source, whole.sample_rate_hz, whole.time_s[part],
                             {k: v[part] for k, v in whole.channels.items()}, whole.units,
                             whole.quantisation)

    def close(self) -> None:
        """Unmap (later, by the garbage collector, if an array of it is still referenced)."""
        self.logs = {}
        with contextlib.suppress(BufferError):  # still viewed: unmapped when the last goes
            self._segment.close()


def subset(log: SampledLog, channels: Container[str] | None) -> SampledLog:
    """``log`` with only ``channels`` (all when None), in the logged order: what the reader
    gives for a decode of only those channels (units and quantisation of the kept ones)."""
    if channels is None:
        return log
    kept = {name: values for name, values in log.channels.items() if name in channels}
    return SampledLog(log.source, log.sample_rate_hz, log.time_s, kept,
                      {k: v for k, v in log.units.items() if k in kept},
                      {k: v for k, v in log.quantisation.items()
                       if k == "time_s" or k in kept})
