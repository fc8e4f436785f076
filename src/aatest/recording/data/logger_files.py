"""Reading NI TDMS (npTDMS) and ASAM MDF4 (asammdf) files behind one small interface.

The importer (:mod:`aatest.recording.data.logger_import`) asks a file for a group, a group for its
channels (sample count, number type, the unit the file states) and for one channel's numbers or
its time base; it never sees the libraries. Every failure of a library on a file — a damaged
header, a truncated segment, a block pointing past the end — becomes an
:class:`~aatest.engine.errors.ImportDataError` naming the file (exit 2).

Truncation. npTDMS reads a TDMS file whose last segment is cut short and only *logs* a warning
(it then returns fewer samples than were written). A calibration must not analyse part of a
record as if it were whole, so those warnings are errors here: the reader's ``nptdms`` log
records at WARNING or above while the file's metadata is read end the import. asammdf raises
on a truncated MF4 file itself.
"""

from __future__ import annotations

import gc
import logging
import struct
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from aatest.engine.errors import AatestError, ImportDataError, InputError

#: the bytes a TDMS file starts with (the lead-in tag of its first segment)
_TDMS_TAG = b"TDSm"
#: the bytes an MDF file starts with (its identification block)
_MDF_TAG = b"MDF     "
#: ... and those of one its writer never finished (a logger that crashed or lost power)
_MDF_UNFINISHED = b"UnFinMF "


class AmbiguousGroupError(InputError):
    """Several groups answer to the name a mapping gives (MF4 acquisition names repeat)."""


@dataclass(frozen=True)
class ChannelInfo:
    """What a file says about one channel before its numbers are read."""

    samples: int
    dtype: np.dtype[Any]
    #: the unit as the file states it ("" when it states none)
    unit: str


class LoggerGroup(Protocol):
    """One group of a logger file (a TDMS group, an MF4 channel group)."""

    def channels(self) -> dict[str, ChannelInfo]:
        """Every channel of the group by name."""

    def read(self, channel: str, start: int = 0, length: int | None = None) -> np.ndarray:
        """The numbers of ``channel`` as stored (after the file's own scaling, if any), from
        sample ``start`` on, ``length`` of them (all when None)."""

    def has_time_base(self, channel: str) -> bool:
        """Whether the file states the time of ``channel``'s samples itself."""

    def time_base(self, channel: str, start: int = 0, length: int | None = None
                  ) -> np.ndarray:
        """The time of samples ``start`` … ``start + length`` of ``channel`` by the file's
        own time base, s."""


class LoggerFile(Protocol):
    """An open logger file."""

    path: Path

    def group(self, key: str | int) -> LoggerGroup | None:
        """The group named ``key`` (or at index ``key``); None when there is none.

        Raises
        ------
        AmbiguousGroupError
            More than one group has that name.
        """

    def group_names(self) -> list[str]:
        """The names of the groups, in file order (for messages)."""


@contextmanager
def open_logger_file(path: Path, kind: str) -> Iterator[LoggerFile]:
    """Open a ``tdms`` or ``mf4`` file for reading; every library error names the file."""
    what = "TDMS" if kind == "tdms" else "MF4"
    try:
        with _open(path, kind) as opened:
            yield opened
    except AatestError:
        raise
    except _decode_errors(kind) as exc:  # what a damaged file makes the library throw
        detail = " ".join(str(exc).split()) or "no detail"
        raise ImportDataError(path, f"corrupt or unreadable {what} file "
                              f"({type(exc).__name__}: {detail})") from None


def _decode_errors(kind: str) -> tuple[type[BaseException], ...]:
    """The exceptions a library raises on a damaged file (anything else is a bug: exit 4)."""
    errors: tuple[type[BaseException], ...] = (ValueError, KeyError, IndexError, EOFError,
                                               OSError, struct.error)
    if kind == "mf4":
        from asammdf.blocks.utils import MdfException

        errors += (MdfException,)
    return errors


@contextmanager
def _open(path: Path, kind: str) -> Iterator[LoggerFile]:
    if not path.is_file():
        raise ImportDataError(path, "file not found")
    with open(path, "rb") as stream:
        head = stream.read(8)
    if kind == "tdms":
        if not head.startswith(_TDMS_TAG):
            raise ImportDataError(path, f"not a TDMS file (starts with {head[:4]!r})")
        with _tdms(path) as tdms:
            yield tdms
    else:
        if head == _MDF_UNFINISHED:
            raise ImportDataError(path, "unfinalised MDF file: the logger never closed it, "
                                  "so its record may be incomplete")
        if head != _MDF_TAG:
            raise ImportDataError(path, f"not an MDF file (starts with {head!r})")
        with _mdf(path) as mdf:
            yield mdf


class _LogWarnings(logging.Handler):
    """Collects the messages a library logs at WARNING or above."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextmanager
def _tdms_warnings() -> Iterator[list[str]]:
    """npTDMS's warnings while a file's metadata is read, collected instead of printed (they
    become the error that names the file)."""
    from nptdms.log import log_manager

    collected = _LogWarnings()
    logger = logging.getLogger("nptdms")
    console = log_manager.console_handler
    level, propagate = console.level, logger.propagate
    logger.addHandler(collected)
    console.setLevel(logging.CRITICAL + 1)
    logger.propagate = False
    try:
        yield collected.messages
    finally:
        logger.removeHandler(collected)
        console.setLevel(level)
        logger.propagate = propagate


@contextmanager
def _tdms(path: Path) -> Iterator[LoggerFile]:
    from nptdms import TdmsFile

    with _tdms_warnings() as warnings:
        tdms = TdmsFile.open(str(path))
    try:
        if warnings:
            raise ImportDataError(path, f"truncated or damaged TDMS file: {warnings[0]}")
        yield _TdmsFile(path, tdms)
    finally:
        tdms.close()


class _TdmsFile:
    def __init__(self, path: Path, tdms: Any) -> None:
        self.path = path
        self._tdms = tdms

    def group(self, key: str | int) -> LoggerGroup | None:
        if not isinstance(key, str):
            return None  # TDMS groups are named
        with suppress(KeyError):
            return _TdmsGroup(self._tdms[key])
        return None

    def group_names(self) -> list[str]:
        return [g.name for g in self._tdms.groups()]


class _TdmsGroup:
    def __init__(self, group: Any) -> None:
        self._group = group

    def channels(self) -> dict[str, ChannelInfo]:
        return {c.name: ChannelInfo(len(c), np.dtype(c.dtype),
                                    str(c.properties.get("unit_string", "")))
                for c in self._group.channels()}

    def read(self, channel: str, start: int = 0, length: int | None = None) -> np.ndarray:
        return np.asarray(self._group[channel].read_data(start, length))

    def has_time_base(self, channel: str) -> bool:
        return "wf_increment" in self._group[channel].properties

    def time_base(self, channel: str, start: int = 0, length: int | None = None
                  ) -> np.ndarray:
        """``wf_start_offset + k·wf_increment`` for the samples k asked for (computed here,
        not by npTDMS's whole-channel ``time_track``, so a piece costs its own length and the
        pieces of a log join to the whole read exactly)."""
        found = self._group[channel]
        stop = len(found) if length is None else start + length
        k = np.arange(start, stop, dtype=np.float64)
        return float(found.properties.get("wf_start_offset", 0.0)) + k * float(
            found.properties["wf_increment"])


@contextmanager
def _quiet_unraisable() -> Iterator[None]:
    """asammdf's half-built reader complains from ``__del__`` when its constructor failed on a
    damaged file; the failure itself is reported, so that echo is not printed."""
    previous = sys.unraisablehook
    sys.unraisablehook = lambda _: None
    try:
        yield
    finally:
        sys.unraisablehook = previous


@contextmanager
def _mdf(path: Path) -> Iterator[LoggerFile]:
    from asammdf import MDF

    message = None
    with _quiet_unraisable():
        try:
            mdf = MDF(str(path))
        except _decode_errors("mf4") as exc:
            message = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        if message is not None:
            gc.collect()  # the half-built reader sits in a reference cycle: collect it here
    if message is not None:  # raised here, outside the handler, so the reader is collected
        raise ImportDataError(path, f"corrupt or unreadable MF4 file ({message})")
    try:
        yield _MdfFile(path, mdf)
    finally:
        mdf.close()


class _MdfFile:
    def __init__(self, path: Path, mdf: Any) -> None:
        self.path = path
        self._mdf = mdf

    def group(self, key: str | int) -> LoggerGroup | None:
        groups = self._mdf.groups
        if isinstance(key, int):
            return _MdfGroup(self._mdf, key) if 0 <= key < len(groups) else None
        found = [i for i, g in enumerate(groups) if g.channel_group.acq_name == key]
        if len(found) > 1:
            raise AmbiguousGroupError(f"{len(found)} channel groups of {self.path} are named "
                                 f"{key!r} (indices {found}): give the group's index instead")
        return _MdfGroup(self._mdf, found[0]) if found else None

    def group_names(self) -> list[str]:
        return [f"{i}: {g.channel_group.acq_name or '(no name)'}"
                for i, g in enumerate(self._mdf.groups)]


class _MdfGroup:
    def __init__(self, mdf: Any, index: int) -> None:
        self._mdf = mdf
        self._index = index

    def channels(self) -> dict[str, ChannelInfo]:
        group = self._mdf.groups[self._index]
        samples = int(group.channel_group.cycles_nr)
        infos = {}
        for channel in group.channels:
            first = self._mdf.get(channel.name, group=self._index, record_offset=0,
                                  record_count=1)
            infos[channel.name] = ChannelInfo(samples, np.dtype(first.samples.dtype),
                                              str(channel.unit or ""))
        return infos

    def read(self, channel: str, start: int = 0, length: int | None = None) -> np.ndarray:
        return np.asarray(self._mdf.get(channel, group=self._index, record_offset=start,
                                        record_count=length).samples)

    def has_time_base(self, channel: str) -> bool:
        return self._index in self._mdf.masters_db

    def time_base(self, channel: str, start: int = 0, length: int | None = None
                  ) -> np.ndarray:
        return np.asarray(self._mdf.get_master(self._index, record_offset=start,
                                               record_count=length), dtype=np.float64)
