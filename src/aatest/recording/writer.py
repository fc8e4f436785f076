"""Crash-safe recording of a run: one atomic MCAP file per step, merged at the end.

Why per-step files: a run lasts hours and may be killed (``kill -9``, power loss) at any moment.
Each step is written to a temporary file, flushed, ``fsync``-ed and atomically renamed to
``steps/<NNN>-<step_id>.mcap``, so a step file either exists complete or not at all; completed
steps can never be corrupted by a later crash. :meth:`RunRecorder.finalize` then merges the run
metadata and every step file, in plan order and in one streaming pass that copies the
compressed chunks verbatim (:mod:`aatest.recording.mcap_io`), into ``recording.mcap``
(again via a temporary file and an atomic rename). The step files are kept: they are what
``--resume`` counts as done, and what :func:`~aatest.recording.read_dataset` reads if
steps were completed after the last merge. The file layout is described in
:mod:`aatest.recording.format`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema

import aatest
from aatest.engine.errors import RecordingError, StorageFault
from aatest.engine.logs import DAQ, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import codec, extremes, preview
from aatest.recording import format as fmt
from aatest.recording.channels import CHUNK_BYTES, register_channels
from aatest.recording.mcap_io import ChunkedWriter
from aatest.recording.stream import DaqSpool, spool_path

RECORDING_NAME = "recording.mcap"
STEPS_DIR = "steps"
RUN_META_NAME = "run.json"
#: the step index is a uint32 in every block
MAX_STEP_INDEX = 2**32 - 1
_STEP_FILE = re.compile(r"^(\d{3,})-(.+)\.mcap$")
_TEMP_MARK = ".tmp-"


def _safe_name(step_id: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", step_id) or "step"


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:  # directories cannot be opened on some platforms; rename is still atomic
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write(path: Path, write: Callable[[IO[bytes]], object]) -> Path:
    """Write ``path`` through a temporary sibling, fsync it, then rename it into place.

    Raises
    ------
    StorageFault
        The file system refused the write (disk full, quota, I/O error). Nothing of ``path`` is
        left half-written and earlier files are untouched, so ``--resume`` completes the run
        once there is space again (exit 3, like a rig fault: the station, not the input, failed).
    """
    tmp = path.with_name(f".{path.name}{_TEMP_MARK}{os.getpid()}")
    try:
        with open(tmp, "wb") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise StorageFault(
            f"{path}: cannot write ({exc.strerror or exc}); completed steps are kept — free "
            "space and continue with `aatest run --resume --out RUN_DIR`"
        ) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)
    return path


def new_writer(stream: IO[bytes]) -> ChunkedWriter:
    """An MCAP writer with the aatest header profile."""
    return ChunkedWriter(stream, profile=fmt.PROFILE, library=f"aatest {aatest.__version__}")


def _check_index(index: int) -> None:
    if not 1 <= index <= MAX_STEP_INDEX:
        raise ValueError(f"step index {index} outside 1..{MAX_STEP_INDEX}")


def _write_log(
    writer: ChunkedWriter, header: dict[str, Any], log: SampledLog, times_ns: list[int],
    coded: dict[str, list[bool]] | None = None,
) -> None:
    """Add one logger's sample blocks of a step, in chunks of about :data:`CHUNK_BYTES`
    (``coded``: see :func:`~aatest.recording.codec.encode_block_pieces`)."""
    cid = fmt.CHANNEL_IDS[log.source]
    pending: list[tuple[int, int, list[Any], int]] = []
    size = 0
    blocks = codec.encode_block_pieces(log, {**header, "source": log.source,
                                             "sample_rate_hz": float(log.sample_rate_hz)},
                                       fmt.BLOCK_SAMPLES, times_ns, coded=coded)
    for seq, (t_ns, (pieces, length)) in enumerate(zip(times_ns, blocks, strict=True)):
        pending.append((t_ns, seq, pieces, length))
        size += length
        if size >= CHUNK_BYTES:
            writer.add_message_pieces(cid, pending)
            pending, size = [], 0
    writer.add_message_pieces(cid, pending)


#: schema ids of the preview messages in a step file (the merger renumbers schemas anyway)
PREVIEW_SCHEMA_IDS = {"table": 2, "daq": 3}


class PreviewChunks:
    """Puts preview records into chunks of :func:`preview.records_per_chunk` records each,
    however they arrive (whole log, streamed pieces, the spool's side file), so a streamed
    step's file is byte for byte the one-shot file."""

    def __init__(self, writer: ChunkedWriter) -> None:
        self._writer = writer
        self._layout: preview.Layout | None = None
        self._pending = bytearray()

    def __call__(self, layout: preview.Layout, records: bytes, _times_ns: Any = None) -> None:
        if self._layout is not None and layout != self._layout:
            self.flush()
        if self._layout != layout:
            schema_id = PREVIEW_SCHEMA_IDS[layout.source]
            self._writer.add_schema(layout.mcap_schema(schema_id))
            self._writer.add_channel(layout.mcap_channel(schema_id))
        self._layout = layout
        self._pending += records
        size = layout.record_dtype().itemsize * preview.records_per_chunk(layout)
        while len(self._pending) >= size:
            self._add(bytes(self._pending[:size]))
            del self._pending[:size]

    def _add(self, data: bytes) -> None:
        assert self._layout is not None
        times = np.frombuffer(data, dtype=self._layout.record_dtype())["log_time"]
        self._writer.add_record_chunk(self._layout.channel_id, data, times)

    def flush(self) -> None:
        """Write the last, partly filled chunk."""
        if self._pending:
            self._add(bytes(self._pending))
        self._pending = bytearray()


def _write_preview(writer: ChunkedWriter, log: SampledLog, index: int, origin_ns: int) -> None:
    """The ``/preview/<source>`` windows of one logger's whole log."""
    chunks = PreviewChunks(writer)
    stream = preview.PreviewStream(index, origin_ns + fmt.STEP_MARGIN_S * 1_000_000_000,
                                   origin_ns, chunks)
    stream.add(log, last=True)
    chunks.flush()


def step_record(
    step: PlannedStep, index: int, logs: dict[str, tuple[SampledLog, list[int]]],
    extra: dict[str, Any] | None,
) -> dict[str, Any]:
    """The ``step`` metadata record of one step (before JSON encoding of its values).

    ``logs`` maps each logger (``table``, ``daq``) to its log and its blocks' log times in ns.
    """
    record: dict[str, Any] = {"step": step.model_dump(mode="json"), "index": index,
                              "extra": extra or {}}
    for source, (log, times_ns) in logs.items():
        record |= {
            f"{source}_topic": fmt.topic(log.source),
            f"{source}_sample_rate_hz": float(log.sample_rate_hz),
            f"{source}_samples": len(log),
            f"{source}_log_time_ns": [times_ns[0], times_ns[-1]] if times_ns else [],
            f"{source}_quantisation": {k: list(v) for k, v in log.quantisation.items()},
        }
        if source == DAQ:
            record["daq_extremes"] = extremes.of_log(log)
    return record


def write_step_file(
    stream: IO[bytes],
    run_meta: dict[str, Any],
    step: PlannedStep,
    index: int,
    logs: tuple[SampledLog, SampledLog],
    extra: dict[str, Any] | None = None,
    run_values: dict[str, str] | None = None,
    coded: dict[str, dict[str, list[bool]]] | None = None,
) -> None:
    """Write one self-contained step recording (run metadata, step metadata, both logs).

    ``run_values``: ``fmt.json_values(run_meta)`` if the caller has it already (the run
    metadata holds the whole plan: encoding it for every step costs ≈ 1 ms a step).
    ``coded``: filled by logger (``table``, ``daq``) with which blocks of each channel are
    stored as codes (:func:`~aatest.recording.codec.encode_block_pieces`).
    """
    _check_index(index)
    for log, source in zip(logs, fmt.CHANNEL_IDS, strict=True):
        if log.source != source:
            raise ValueError(f"step {step.id!r}: expected a {source} log, got {log.source!r}")
        codec.check_dtypes(log)
    origin_ns = fmt.step_start_ns(run_meta, index)
    timed = {log.source: (log, fmt.block_log_times_ns(log.time_s, origin_ns, fmt.BLOCK_SAMPLES))
             for log in logs}
    writer = new_writer(stream)
    writer.add_metadata(fmt.RUN_RECORD, run_values or fmt.json_values(run_meta))
    record = fmt.json_values(step_record(step, index, timed, extra))
    writer.add_metadata(fmt.STEP_RECORD, record)
    register_channels(writer)
    header = {"step_id": step.id, "step_index": index,
              "step_record_sha256": fmt.record_digest(record)}
    for log, times_ns in timed.values():
        _write_log(writer, header, log, times_ns,
                   None if coded is None else coded.setdefault(log.source, {}))
    for log in logs:
        _write_preview(writer, log, index, origin_ns)
    writer.finish()


def write_streamed_step(
    stream: IO[bytes],
    run_meta: dict[str, Any],
    step: PlannedStep,
    index: int,
    table: SampledLog,
    spool: DaqSpool,
    extra: dict[str, Any] | None = None,
) -> None:
    """Write one step file from its table log and the closed spool of its streamed DAQ log.

    The result is the file :func:`write_step_file` writes for the same logs (same records,
    blocks and chunks), built one block at a time: memory is one chunk, not the record.
    """
    _check_index(index)
    if table.source != "table":
        raise ValueError(f"step {step.id!r}: expected a table log, got {table.source!r}")
    codec.check_dtypes(table)
    origin_ns = fmt.step_start_ns(run_meta, index)
    table_times = fmt.block_log_times_ns(table.time_s, origin_ns, fmt.BLOCK_SAMPLES)
    record = step_record(step, index, {"table": (table, table_times)}, extra) | spool.daq_record()
    values = fmt.json_values(record)
    digest = fmt.record_digest(values)
    writer = new_writer(stream)
    writer.add_metadata(fmt.RUN_RECORD, fmt.json_values(run_meta))
    writer.add_metadata(fmt.STEP_RECORD, values)
    register_channels(writer)
    _write_log(writer, {"step_id": step.id, "step_index": index, "step_record_sha256": digest},
               table, table_times)
    pending: list[Message] = []
    size = 0
    for message in spool.blocks_with_digest(digest):
        pending.append(message)
        size += len(message.data)
        if size >= CHUNK_BYTES:
            writer.add_chunk(pending)
            pending, size = [], 0
    writer.add_chunk(pending)
    _write_preview(writer, table, index, origin_ns)
    chunks = PreviewChunks(writer)
    for layout, records in spool.preview_chunks():
        chunks(layout, records)
    chunks.flush()
    writer.finish()


class StreamedStep:
    """One step whose DAQ log arrives in chunks (:meth:`RunRecorder.stream_step`).

    ``add`` each chunk as it arrives (it is encoded and written to the spool at once), then
    ``finish`` with the table log: the step file is written atomically and the spool deleted.
    After a fault, ``abandon`` closes the spool so every sample received stays on disk.
    """

    def __init__(self, recorder: RunRecorder, step: PlannedStep, index: int, path: Path,
                 meta: dict[str, Any]) -> None:
        self._recorder, self.step, self.index, self.path = recorder, step, index, path
        self._meta = meta
        origin_ns = fmt.step_start_ns(meta, index)
        self.spool = DaqSpool(spool_path(path), meta, step.id, index, origin_ns, new_writer)

    def add(self, chunk: SampledLog) -> None:
        """Encode and spool one chunk of the DAQ log."""
        self.spool.add(chunk)

    def finish(self, table: SampledLog, extra: dict[str, Any] | None = None) -> Path:
        """Write the complete step file from the table log and the spool; delete the spool."""
        self.spool.close()
        spool = self.spool
        atomic_write(self.path, lambda s: write_streamed_step(s, self._meta, self.step,
                                                              self.index, table, spool, extra))
        spool.remove()
        self._recorder._completed(self.step.id, self.path, self.index)
        return self.path

    def abandon(self) -> Path:
        """Close the spool after a fault; return its path (it keeps the samples recorded)."""
        self.spool.abandon()
        return self.spool.path


def scan_step_file(path: Path) -> tuple[str, int] | None:
    """(step id, plan index) of a complete step file, or None if it is not a valid one."""
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            if reader.get_summary() is None:
                return None
            for record in reader.iter_metadata():
                if record.name == fmt.STEP_RECORD:
                    return str(json.loads(record.metadata["step"])["id"]), int(
                        json.loads(record.metadata["index"])
                    )
    except Exception:  # noqa: BLE001 - any failure to parse means "not a complete step file"
        return None
    return None


class RunRecorder:
    """Records a run into ``run_dir``: atomic per-step files, then one merged recording.

    Parameters
    ----------
    run_dir
        The run directory; step files go to ``run_dir/steps``. An existing directory is
        continued (``--resume``): its run metadata and completed steps are kept.
    """

    def __init__(self, run_dir: str | Path) -> None:
        self.run_dir = Path(run_dir)
        self.steps_dir = self.run_dir / STEPS_DIR
        self.steps_dir.mkdir(parents=True, exist_ok=True)
        self._run_meta: dict[str, Any] = load_run_metadata(self.steps_dir)
        self._files: dict[str, tuple[Path, int]] | None = None
        self._values_of: dict[str, Any] | None = None
        self._values: dict[str, str] = {}

    def _run_values(self, meta: dict[str, Any]) -> dict[str, str]:
        """``fmt.json_values(meta)``, encoded once per run metadata (it is replaced, never
        changed in place, by :meth:`write_run_metadata`)."""
        if self._values_of is not meta:
            self._values_of, self._values = meta, fmt.json_values(meta)
        return self._values

    def write_run_metadata(self, meta: dict[str, Any]) -> None:
        """Store the run's metadata (procedure, rig, versions, seed, sensors, plan ...)."""
        record = {**meta, "format": fmt.FORMAT}
        record.setdefault("aatest_version", aatest.__version__)
        text = json.dumps(record, sort_keys=True, default=fmt._json_default).encode("utf-8")
        atomic_write(self.steps_dir / RUN_META_NAME, lambda stream: stream.write(text))
        self._run_meta = json.loads(text)

    @property
    def run_metadata(self) -> dict[str, Any]:
        """The run metadata stored so far (a copy)."""
        return dict(self._run_meta)

    def amend_run_metadata(self, updates: dict[str, Any]) -> None:
        """Add ``updates`` to the stored run metadata (what is known only once the rig runs)."""
        self.write_run_metadata({**self._run_meta, **updates})

    def write_step(
        self,
        step: PlannedStep,
        table: SampledLog,
        daq: SampledLog,
        extra: dict[str, Any] | None = None,
        index: int | None = None,
        coded: dict[str, dict[str, list[bool]]] | None = None,
    ) -> Path:
        """Write one completed step atomically; return its file.

        ``index`` (1-based plan position) defaults to the step's position in the run
        metadata's ``plan``, else to the next free number. Re-writing a step replaces it.
        ``coded``: see :func:`write_step_file`.
        """
        path, index = self._step_path(step, index)
        meta = self._run_meta or {"format": fmt.FORMAT, "aatest_version": aatest.__version__}
        values = self._run_values(meta)
        atomic_write(path, lambda s: write_step_file(s, meta, step, index, (table, daq), extra,
                                                     values, coded))
        self._completed(step.id, path, index)
        return path

    def stream_step(self, step: PlannedStep, index: int | None = None) -> StreamedStep:
        """Start a step whose DAQ log is streamed in chunks (a long static record).

        The chunks go to a spool ``steps/<NNN>-<id>.mcap.partial`` as they arrive; the step
        file appears atomically when :meth:`StreamedStep.finish` is called, as with
        :meth:`write_step`.
        """
        path, index = self._step_path(step, index)
        meta = self._run_meta or {"format": fmt.FORMAT, "aatest_version": aatest.__version__}
        return StreamedStep(self, step, index, path, meta)

    def _step_path(self, step: PlannedStep, index: int | None) -> tuple[Path, int]:
        existing = self._known_step_files()
        index = index or self._plan_index(step.id) or existing.get(step.id, (None, 0))[1] or (
            max((i for _, i in existing.values()), default=0) + 1
        )
        return self.steps_dir / f"{index:03d}-{_safe_name(step.id)}.mcap", index

    def _completed(self, step_id: str, path: Path, index: int) -> None:
        """Note a step file just written (replacing an older file of the same step)."""
        existing = self._known_step_files()
        old = existing.pop(step_id, None)
        if old is not None and old[0] != path:
            old[0].unlink(missing_ok=True)
        existing[step_id] = (path, index)
        self._files = dict(sorted(existing.items(), key=lambda item: (item[1][1], item[1][0].name)))

    def completed_step_ids(self) -> list[str]:
        """Ids of completed steps in plan order; leftovers of interrupted writes are removed."""
        return list(self._step_files())

    def step_files(self) -> list[Path]:
        """Complete step files in plan order."""
        return [path for path, _ in self._step_files().values()]

    def finalize(self) -> Path:
        """Merge run metadata and all step files, in plan order, into ``recording.mcap``."""
        target = self.run_dir / RECORDING_NAME
        paths = self.step_files()
        return atomic_write(target, lambda stream: merge_step_files(stream, self._run_meta, paths))

    def prune_step_files(self) -> int:
        """Delete the step files already inside ``recording.mcap``; return how many went.

        Only ids read back from the merged recording are deleted, so a failed or partial merge
        never costs a step. The run metadata file stays (it names the run for ``--resume``).
        The step files are those this recorder knows (:meth:`_known_step_files`: after
        :meth:`finalize`, the ones it merged; scanning the stepped sine's 136 again took
        ≈ 0.1 s).
        """
        merged = merged_step_ids(self.run_dir / RECORDING_NAME)
        pruned = 0
        files = self._known_step_files()
        for step_id, (path, _) in files.items():
            if step_id in merged:
                path.unlink(missing_ok=True)
                pruned += 1
        self._files = None
        return pruned

    def _plan_index(self, step_id: str) -> int | None:
        plan = self._run_meta.get("plan")
        if isinstance(plan, list):
            for i, entry in enumerate(plan, start=1):
                if isinstance(entry, dict) and entry.get("id") == step_id:
                    return i
        return None

    def _known_step_files(self) -> dict[str, tuple[Path, int]]:
        """The step files as this recorder last scanned them and its writes since (the
        directory is scanned at the first ask)."""
        return self._files if self._files is not None else self._step_files()

    def _step_files(self) -> dict[str, tuple[Path, int]]:
        """Scan the step directory once (cleaning leftovers); later writes update the cache."""
        self._files = complete_step_files(self.steps_dir, clean=True)
        return dict(self._files)


def merged_step_ids(recording: Path) -> set[str]:
    """Ids of the steps a merged recording holds (read from its step records)."""
    try:
        with open(recording, "rb") as stream:
            return {
                json.loads(record.metadata["step"])["id"]
                for record in make_reader(stream).iter_metadata()
                if record.name == fmt.STEP_RECORD
            }
    except FileNotFoundError:
        return set()
    except RecordingError:
        raise
    except fmt.DECODE_ERRORS as exc:
        raise RecordingError(f"{recording}: corrupt or truncated recording ({exc})") from exc


def complete_step_files(steps_dir: Path, clean: bool = False) -> dict[str, tuple[Path, int]]:
    """Step id → (file, plan index) of every complete step file, sorted by plan index.

    With ``clean``, temporary files of interrupted writes are deleted and invalid step files
    are renamed ``*.corrupt`` so they are never read again.
    """
    found: dict[str, tuple[Path, int]] = {}
    corrupt: list[Path] = []
    for path in sorted(steps_dir.glob("*.mcap*")):
        if _TEMP_MARK in path.name:
            if clean:
                path.unlink(missing_ok=True)
            continue
        if not _STEP_FILE.match(path.name):
            continue
        scanned = scan_step_file(path)
        if scanned is None:
            corrupt.append(path)
            continue
        step_id, index = scanned
        if step_id not in found or found[step_id][1] < index:
            found[step_id] = (path, index)
    if clean and corrupt:
        _set_aside(corrupt, len(found))
    return dict(sorted(found.items(), key=lambda item: (item[1][1], item[1][0].name)))


def _set_aside(corrupt: list[Path], kept: int) -> None:
    """Rename damaged step files ``*.corrupt`` and say so: writes are atomic, so a damaged
    file with a final name means the disk or a person changed it, which must not go unnoticed."""
    for path in corrupt:
        path.replace(path.with_name(path.name + ".corrupt"))
    names = ", ".join(str(p) for p in corrupt)
    raise RecordingError(
        f"{names}: corrupt step file (no valid MCAP summary or step record); renamed *.corrupt, "
        f"the {kept} other completed step(s) are kept — run `aatest run --resume` again to "
        "record the step anew"
    )


def load_run_metadata(steps_dir: Path) -> dict[str, Any]:
    """The run metadata stored by :meth:`RunRecorder.write_run_metadata` ({} if none)."""
    path = steps_dir / RUN_META_NAME
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{path}: unreadable run metadata: {exc}") from exc
    if not isinstance(data, dict):
        raise RecordingError(f"{path}: run metadata is not a JSON object")
    return data


class _Merger:
    """Copies step files into one writer: chunks verbatim, identical schemas stored once."""

    def __init__(self, writer: ChunkedWriter) -> None:
        self.writer = writer
        self.schema_ids: dict[tuple[str, str, bytes], int] = {}

    def copy(self, path: Path) -> None:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            if summary is None or summary.statistics is None:
                raise RecordingError(f"{path}: step file has no summary (incomplete)")
            for record in reader.iter_metadata():
                if record.name == fmt.STEP_RECORD:
                    self.writer.add_metadata(record.name, dict(record.metadata))
            for channel in summary.channels.values():
                self._add_channel(channel, summary.schemas[channel.schema_id], path)
            self.writer.copy_chunks(stream, summary)

    def _add_channel(self, channel: Channel, schema: Schema, path: Path) -> None:
        key = (schema.name, schema.encoding, bytes(schema.data))
        if key not in self.schema_ids:
            self.schema_ids[key] = len(self.schema_ids) + 1
            self.writer.add_schema(dataclasses.replace(schema, id=self.schema_ids[key]))
        try:
            self.writer.add_channel(dataclasses.replace(channel, schema_id=self.schema_ids[key]))
        except ValueError as exc:
            raise RecordingError(f"{path}: channel {channel.topic!r} clashes: {exc}") from exc


def merge_step_files(stream: IO[bytes], run_meta: dict[str, Any], paths: Iterable[Path]) -> None:
    """One pass: run metadata, then each step's metadata and messages, into ``stream``."""
    paths = list(paths)
    if not run_meta and paths:
        run_meta = _embedded_run_meta(paths[0])
    writer = new_writer(stream)
    writer.add_metadata(fmt.RUN_RECORD, fmt.json_values(run_meta or {"format": fmt.FORMAT}))
    merger = _Merger(writer)
    for path in paths:
        merger.copy(path)
    writer.finish()


def _embedded_run_meta(path: Path) -> dict[str, Any]:
    with open(path, "rb") as stream:
        for record in make_reader(stream).iter_metadata():
            if record.name == fmt.RUN_RECORD:
                return fmt.from_json_values(dict(record.metadata))
    return {}
