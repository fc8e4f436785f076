"""Chunk accounting of a timed CAN record: every frame the logger says it sent, chunk by chunk.

A timed record (``TIMED_START``, docs/can-logger-frames.md) arrives as sample frames cut by
the logger's CHUNK marks, each carrying how many frames it has sent so far. The
:class:`ChunkAccount` gathers the frames of whole marks until a chunk of the length the runner
asked for is due, then decodes only that chunk (vectorised), unwraps its sequence counters from
the record frame index it starts at, and finds every frame missing among those the logger
reports sent. Memory is one chunk plus one logger block, whatever the record's length.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from aatest.protocols import can_frames as cf

Decode = Callable[[list[bytes]], cf.DecodedSamples]


@dataclass(frozen=True)
class Chunk:
    """One decoded chunk: the samples received (on the full frame grid when losses are
    recorded as NaN), and the frames lost in it (record frame indices)."""

    samples: cf.DecodedSamples | None
    gaps: list[cf.Gap]
    #: frames of the chunk the logger reports sent
    sent: int


@dataclass
class ChunkAccount:
    """Frames of one timed record received and accounted for so far.

    Parameters
    ----------
    decode
        Payloads → decoded samples (the plugin's built-in or DBC decoder).
    chunk_frames
        Frames per chunk handed on (the runner's ``chunk_s`` at the logger's rate).
    keep_losses
        ``on_frame_loss: record``: a chunk with losses is returned on its full frame grid with
        NaN samples at the lost frames; otherwise only the frames before the first loss are.
    sample_rate_hz
        The logger's nominal rate (time stamps of lost frames at a chunk's ends).
    """

    decode: Decode
    chunk_frames: int
    keep_losses: bool
    sample_rate_hz: float
    #: record frame index of the next chunk's first frame
    accounted: int = 0
    #: frames the logger reports sent up to its last mark
    sent: int = 0
    #: most frames held at once (payloads waiting for their chunk)
    peak_frames: int = 0
    pending: list[bytes] = field(default_factory=list)

    def add(self, sent: int, payloads: list[bytes]) -> None:
        """The frames received up to a mark of the logger that reports ``sent`` so far."""
        if sent < self.sent:
            raise ValueError(f"the logger's frame count went back from {self.sent} to {sent}")
        self.pending.extend(payloads)
        self.sent = sent
        self.peak_frames = max(self.peak_frames, len(self.pending))

    def due(self) -> bool:
        """Whether a whole chunk has been marked, or a loss shows in the frame count (then the
        marked frames are accounted for now, not a chunk later)."""
        marked = self.sent - self.accounted
        return marked >= self.chunk_frames or len(self.pending) != marked

    def take(self) -> Chunk:
        """Decode and account for every frame marked so far (one chunk)."""
        payloads, self.pending = self.pending, []
        expected = self.sent - self.accounted
        start, self.accounted = self.accounted, self.sent
        decoded = self.decode(payloads)
        index = cf.frame_index(decoded.seq, start) - start
        if index.size and (index[-1] >= expected or len(payloads) > expected):
            raise ValueError(f"{len(payloads)} frames received up to frame {start + expected}, "
                             f"{expected} sent in this chunk (a frame of another record?)")
        gaps = cf.find_gaps(index, expected)
        absolute = [cf.Gap(start + g.first, g.lost) for g in gaps]
        if not gaps or not payloads:
            return Chunk(decoded if payloads else None, absolute, expected)
        if self.keep_losses:
            filled = cf.fill_gaps(decoded, index, expected, self.sample_rate_hz)
            return Chunk(filled, absolute, expected)
        kept = gaps[0].first  # the frames before the first loss are whole: kept, then fault
        return Chunk(_head(decoded, kept) if kept else None, absolute, expected)


def _head(decoded: cf.DecodedSamples, n: int) -> cf.DecodedSamples:
    """The first ``n`` samples."""
    return cf.DecodedSamples(decoded.seq[:n], decoded.time_s[:n], decoded.volts[:n],
                             decoded.sync_pulse[:n], decoded.trigger[:n],
                             decoded.temperature_c[:n])


def loss_message(where: str, gaps: list[cf.Gap], sent: int) -> str:
    """One line naming how many frames of the record were lost, and where."""
    lost = sum(g.lost for g in gaps)
    at = ", ".join(f"{g.lost} from frame {g.first}" for g in gaps[:3])
    return f"{where}: lost {lost} sample frames of the timed record ({at}; {sent} sent so far)"
