"""Read aatest recordings (and, through the importer, import directories) into a Dataset.

:func:`read_dataset` accepts a run directory (its ``recording.mcap``; the completed step files
of ``steps/`` when the run was interrupted or resumed after the last merge), a recording file,
or a measured-data import directory (``dataset.yaml`` present, docs/interfaces.md §3; or
``mapping.yaml`` and the TDMS/MF4 files it names, or that mapping file itself). Anything that
is not a complete aatest recording raises :class:`~aatest.engine.errors.RecordingError` naming
the file and what is wrong. The layout is described in :mod:`aatest.recording.format`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Container, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message

from aatest.engine.errors import RecordingError
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import codec, legacy_v1, proto
from aatest.recording import format as fmt
from aatest.recording.chunk_records import chunk_messages
from aatest.recording.dataset import Dataset, LazySteps, SensorInfo
from aatest.recording.writer import (
    RECORDING_NAME,
    STEPS_DIR,
    complete_step_files,
    load_run_metadata,
    merged_step_ids,
)
from aatest.rig_defaults import LOG_RATE_HZ
from aatest.storage import RemotePath, StorageError, Where, locate

IMPORT_MANIFEST = "dataset.yaml"
#: the mapping file of a logger's TDMS/MF4 files (docs/interfaces.md §3)
LOGGER_MAPPING = "mapping.yaml"
_DECODE_ERRORS = fmt.DECODE_ERRORS


@dataclass(frozen=True)
class _StepEntry:
    """One step of a file, as its metadata record gives it: nothing of its logs is decoded."""

    index: int
    step: PlannedStep
    path: Where
    record: dict[str, Any]
    values: dict[str, str]
    chunks: _StepChunks

    @property
    def samples(self) -> dict[str, int]:
        """Sample count of each log, from the record (absent in old records: decoded later)."""
        return {source: int(self.record[f"{source}_samples"]) for source in ("table", "daq")
                if self.record.get(f"{source}_samples") is not None}


@dataclass
class _FileContents:
    """What one MCAP file holds: run metadata and its step records (logs not yet decoded)."""

    chunks: _StepChunks
    run_meta: dict[str, Any] = field(default_factory=dict)
    steps: list[_StepEntry] = field(default_factory=list)


def read_dataset(path: str | Where) -> Dataset:
    """Load a run directory, a recording file or an import directory as a :class:`Dataset`.

    A recording's steps are a :class:`~aatest.recording.dataset.LazySteps`: reading the file
    checks its header, summary and step records; each step's logs are decoded (and their
    chunk CRCs checked) when that step is read, so memory holds one step, not the run. A
    corrupt chunk is then a :class:`RecordingError` naming the file and the step.

    Parameters
    ----------
    path
        Run directory, ``recording.mcap`` (or a single step file), or import directory; a
        URL (``s3://…``) names a finished run or a recording on object storage, read in
        ranged reads as the steps are asked for (docs/storage.md).

    Raises
    ------
    RecordingError
        The recording is missing, truncated, corrupt or not an aatest recording.
    ImportDataError
        The import directory is malformed (see :mod:`aatest.recording.data.importer`).
    """
    where = locate(path)
    if isinstance(where, RemotePath):
        return _read_remote(where)
    path = where
    if path.is_dir():
        if (path / IMPORT_MANIFEST).exists():
            from aatest.recording.data.importer import import_dataset

            return import_dataset(path)
        if (path / LOGGER_MAPPING).exists():
            return _import_logger_files(path / LOGGER_MAPPING)
        return _read_run_dir(path)
    if path.is_file() and path.suffix in (".yaml", ".yml"):
        return _import_logger_files(path)
    if path.is_file():
        contents = _read_file(path)
        return _build_dataset(contents.run_meta, contents.steps, path, complete=True)
    raise RecordingError(f"{path}: no such file or directory")


def _read_remote(where: RemotePath) -> Dataset:
    """A finished run directory or a recording file on object storage.

    Runs reach object storage finished (:mod:`aatest.storage.staging`), so only their
    merged ``recording.mcap`` is read; import directories are read from local disk.
    """
    recording = where / RECORDING_NAME if where.is_dir() else where
    if not recording.is_file():
        raise RecordingError(
            f"{where}: no {RECORDING_NAME} here: on object storage aatest reads finished runs "
            "and recording files (an import directory or an unfinished run is read locally)")
    contents = _read_file(recording)
    return _build_dataset(contents.run_meta, contents.steps, recording, complete=True)


def _import_logger_files(mapping: Path) -> Dataset:
    from aatest.recording.data.logger_import import import_logger_files

    return import_logger_files(mapping)


def _read_run_dir(run_dir: Path) -> Dataset:
    recording = run_dir / RECORDING_NAME
    steps_dir = run_dir / STEPS_DIR
    files = complete_step_files(steps_dir) if steps_dir.is_dir() else {}
    if recording.is_file() and not _is_stale(recording, set(files)):
        contents = _read_file(recording)
        return _build_dataset(contents.run_meta, contents.steps, recording, complete=True)
    if not files:
        raise RecordingError(
            f"{run_dir}: no {RECORDING_NAME}, no completed step in {STEPS_DIR}/ and no "
            f"{IMPORT_MANIFEST} or {LOGGER_MAPPING}: not a run or import directory"
        )
    run_meta = load_run_metadata(steps_dir)
    steps: list[_StepEntry] = []
    for path, _ in files.values():
        contents = _read_file(path)
        run_meta = run_meta or contents.run_meta
        steps.extend(contents.steps)
    return _build_dataset(run_meta, steps, run_dir, complete=False)


def _is_stale(recording: Path, step_ids: set[str]) -> bool:
    """True when a step was completed after the last merge (the run was resumed since).

    Compares step ids, not modification times, so copying a run directory cannot fool it.
    """
    return not step_ids <= merged_step_ids(recording)


def _read_file(path: Where) -> _FileContents:
    """Read one aatest MCAP file's header, summary and records (no log is decoded)."""
    with _translated(path), path.open("rb") as stream:
        return _contents(make_reader(stream, validate_crcs=True), path)


@contextmanager
def _translated(path: Where) -> Iterator[None]:
    """Every low-level decoding failure becomes a RecordingError naming the file; storage
    that fails while the file is read says so itself (it is no damage of the file)."""
    try:
        yield
    except (RecordingError, StorageError):
        raise
    except FileNotFoundError as exc:  # gone since the run's files were listed
        raise RecordingError(f"{path}: not found ({exc})") from exc
    except _DECODE_ERRORS as exc:
        raise RecordingError(
            f"{path}: corrupt or truncated recording ({type(exc).__name__}: {exc})"
        ) from exc


def _checked_summary(reader: Any, path: Where) -> Any:
    header = reader.get_header()
    if header.profile != fmt.PROFILE:
        raise RecordingError(f"{path}: not an aatest recording (MCAP profile {header.profile!r})")
    summary = reader.get_summary()
    if summary is None:
        raise RecordingError(f"{path}: recording has no summary section (unfinished write)")
    return summary


def _contents(reader: Any, path: Where) -> _FileContents:
    summary = _checked_summary(reader, path)
    contents = _FileContents(chunks=_StepChunks(path, summary))
    step_records = []
    for index, record in zip(summary.metadata_indexes, reader.iter_metadata(), strict=True):
        if record.name != index.name:  # a damaged name: its record (a step?) would be lost
            raise RecordingError(f"{path}: the metadata record at byte {index.offset} is "
                                 f"named {record.name!r}, its index {index.name!r} (damaged)")
        if record.name == fmt.RUN_RECORD:
            contents.run_meta = fmt.from_json_values(dict(record.metadata))
        elif record.name == fmt.STEP_RECORD:
            step_records.append(dict(record.metadata))
    _check_format(contents.run_meta, path)
    for values in step_records:
        step_record = fmt.from_json_values(values)
        step = PlannedStep.model_validate(step_record["step"])
        contents.steps.append(_StepEntry(int(step_record["index"]), step, path, step_record,
                                         values, contents.chunks))
    return contents


class _StepChunks:
    """Reads the messages of one topic and time range from the chunks that can hold them.

    The summary (chunk indexes, channels, schemas) is read once per file and kept, so reading
    a step costs only its own chunks (each CRC-checked), not the file's index again.
    """

    def __init__(self, path: Where, summary: Any) -> None:
        self.path, self.summary = path, summary
        self.channels_by_topic = {ch.topic: ch for ch in summary.channels.values()}

    def iter_messages(self, topics: list[str], starting_at: int | None = None,
                      ending_at: int | None = None, log_time_order: bool = False
                      ) -> Iterator[tuple[Any, Any, Message]]:
        """``(None, channel, message)`` of ``topics`` with ``starting_at ≤ log_time ≤
        ending_at`` (ns), in file order (``log_time_order`` is accepted for the mcap API)."""
        ids = {self.channels_by_topic[t].id for t in topics if t in self.channels_by_topic}
        low = -1 if starting_at is None else starting_at
        high = 2**64 if ending_at is None else ending_at
        with self.path.open("rb") as stream:
            for index in chunks_overlapping(self.summary, ids, low, high):
                for record in self.read_chunk(stream, index):
                    if (isinstance(record, Message) and record.channel_id in ids
                            and low <= record.log_time <= high):
                        yield None, self.summary.channels[record.channel_id], record

    @staticmethod
    def read_chunk(stream: Any, index: Any) -> list[Any]:
        """The message records of one chunk, its CRC checked (flipped bits must not pass);
        their ``data`` are views into the decompressed chunk (:mod:`.chunk_records`)."""
        stream.seek(index.chunk_start_offset + 1 + 8)  # opcode and record length
        return chunk_messages(Chunk.read(ReadDataStream(stream)))


def chunks_overlapping(summary: Any, channel_ids: Collection[int], low_ns: int, high_ns: int
                       ) -> list[Any]:
    """The chunk indexes of ``summary`` holding messages of ``channel_ids`` that may lie in
    ``[low_ns, high_ns]`` (ns, log time), in file order: the chunks a decode of one step's
    log reads (and :mod:`aatest.recording.step_chunks` digests)."""
    ids = set(channel_ids)
    return sorted((ix for ix in summary.chunk_indexes
                   if ix.message_end_time >= low_ns and ix.message_start_time <= high_ns
                   and ids & set(ix.message_index_offsets)),
                  key=lambda ix: ix.chunk_start_offset)


def _load_log(entry: _StepEntry, source: str, chunks: _StepChunks,
              channels: Container[str] | None = None) -> SampledLog:
    """Decode one log of one step (only ``channels`` when given, v2): only the chunks holding
    that step's blocks are read."""
    with _translated(entry.path):
        return _step_log(chunks, chunks.summary, entry.record, entry.values, source, entry.path,
                         channels)


def _load_pieces(entry: _StepEntry, source: str, chunks: _StepChunks,
                 channels: Container[str] | None = None) -> Iterator[SampledLog]:
    """One log of one step as consecutive pieces, one per block (v2; a v1 log as one piece).

    A generator: the step's chunks are read as the pieces are asked for, and a damaged block
    is a :class:`RecordingError` naming the file and the step when it is reached.
    """
    record = entry.record
    topic = record[f"{source}_topic"]
    channel = chunks.channels_by_topic.get(topic)
    schema = chunks.summary.schemas.get(channel.schema_id) if channel is not None else None
    if schema is None or (schema.encoding, schema.name) != (fmt.ENCODING, proto.BLOCK_MESSAGE):
        yield _load_log(entry, source, chunks, channels)  # v1, or the error it explains
        return
    where = f"{entry.path}: topic {topic!r} of step {record['step']['id']!r}"
    quanta = {k: (q, o) for k, (q, o) in record[f"{source}_quantisation"].items()}
    with _translated(entry.path):
        try:
            yield from codec.blocks_to_pieces(
                _step_blocks(chunks, record, entry.values, source, where), source,
                float(record[f"{source}_sample_rate_hz"]), int(record[f"{source}_samples"]),
                quanta, channels)
        except RecordingError:
            raise
        except ValueError as exc:
            raise RecordingError(f"{where}: {exc}") from exc


def _check_format(run_meta: dict[str, Any], path: Where) -> None:
    if not run_meta:
        raise RecordingError(f"{path}: not an aatest recording (no 'run' metadata record)")
    version = run_meta.get("format", fmt.FORMAT)
    if version not in (fmt.FORMAT, fmt.FORMAT_V2, legacy_v1.FORMAT_V1):
        raise RecordingError(
            f"{path}: unsupported recording format {version!r} "
            f"(need {fmt.FORMAT}, {fmt.FORMAT_V2} or {legacy_v1.FORMAT_V1})"
        )


def _step_log(
    reader: Any, summary: Any, record: dict[str, Any], values: dict[str, str], source: str,
    path: Where, channels: Container[str] | None = None,
) -> SampledLog:
    """One logger's log of one step, decoded by the format its schema encoding names."""
    step_id = str(record["step"]["id"])
    topic = record[f"{source}_topic"]
    channel = next((ch for ch in summary.channels.values() if ch.topic == topic), None)
    if channel is None:
        raise RecordingError(f"{path}: step topic {topic!r} has no channel")
    schema = summary.schemas.get(channel.schema_id)
    where = f"{path}: topic {topic!r} of step {step_id!r}"
    try:
        if schema is not None and schema.encoding == legacy_v1.ENCODING_V1:
            return _decode_v1(reader, channel, schema, step_id, values, where)
        if schema is not None and (schema.encoding, schema.name) == (fmt.ENCODING,
                                                                     proto.BLOCK_MESSAGE):
            return _decode_v2(reader, record, values, source, where, channels)
    except RecordingError:
        raise
    except ValueError as exc:
        raise RecordingError(f"{where}: {exc}") from exc
    raise RecordingError(f"{path}: topic {topic!r} uses no known aatest schema")


def _decode_v1(
    reader: Any, channel: Any, schema: Any, step_id: str, values: dict[str, str], where: str
) -> SampledLog:
    """A v1 log: per-step topic, JSON schema, packed NumPy records."""
    meta = channel.metadata
    expected = meta.get("step_record_sha256")
    if meta.get("step_id") != step_id or (expected and expected != fmt.record_digest(values)):
        raise RecordingError(f"{where}: step record does not match its channel (corrupt metadata)")
    expected = meta.get("schema_sha256")
    if expected and expected != hashlib.sha256(schema.data).hexdigest():
        raise RecordingError(f"{where}: schema is corrupt (checksum mismatch)")
    parts = sorted(
        (message.sequence, bytes(message.data))
        for _, _, message in reader.iter_messages(topics=[channel.topic], log_time_order=False)
    )
    samples = meta.get("samples")
    return legacy_v1.decode_log([data for _, data in parts], schema.data,
                                int(samples) if samples is not None else None)


def _decode_v2(
    reader: Any, record: dict[str, Any], values: dict[str, str], source: str, where: str,
    channels: Container[str] | None = None,
) -> SampledLog:
    """A v2 log: the step's protobuf blocks on the stable topic, found by their log times.

    The blocks are parsed one at a time as the codec places them (:func:`_step_blocks`), so
    decoding an hours-long record holds its columns and one block, not every block.
    """
    quanta = {k: (q, o) for k, (q, o) in record[f"{source}_quantisation"].items()}
    return codec.blocks_to_log(_step_blocks(reader, record, values, source, where), source,
                               float(record[f"{source}_sample_rate_hz"]),
                               int(record[f"{source}_samples"]), quanta, channels)


def _step_blocks(reader: Any, record: dict[str, Any], values: dict[str, str], source: str,
                 where: str) -> Iterator[Any]:
    """The ``SampleBlock`` messages of one step's log, in file order, each checked against
    the step record's digest (a generator: nothing is kept after it is yielded)."""
    digest = fmt.record_digest(values)
    span = record[f"{source}_log_time_ns"]
    if not span:
        return
    for _, _, message in reader.iter_messages(
        topics=[record[f"{source}_topic"]], starting_at=span[0], ending_at=span[1],
        log_time_order=False,
    ):
        block = proto.block_class().FromString(message.data)
        if block.step_id != record["step"]["id"] or block.source != source:
            continue  # a neighbouring step's block in the same time range
        if block.step_record_sha256 != digest:
            raise RecordingError(f"{where}: step record does not match its blocks "
                                 "(corrupt metadata)")
        yield block


def _sensors(run_meta: dict[str, Any], steps: LazySteps) -> tuple[SensorInfo, ...]:
    """Sensors from the run metadata, else nominal defaults for every DAQ voltage channel."""
    entries = run_meta.get("sensors")
    if isinstance(entries, list) and entries:
        return tuple(
            SensorInfo.from_metadata(entry)
            for entry in entries
            if isinstance(entry, dict)
        )
    channels = steps[0].daq.sensor_channels() if steps else []
    return tuple(SensorInfo(channel=ch) for ch in channels)


def _check_recorded(sensors: tuple[SensorInfo, ...], entries: list[_StepEntry],
                    source: Where) -> None:
    """Every sensor the metadata names was logged in every step, as far as the step records
    say: the writer notes each logged sensor channel's extremes (``daq_extremes``; older
    recordings note none and are not checked here).

    Why: a recording of a three-axis unit whose logger logged one channel (a rig since
    refused by the preflight's "sensor channels" check) ended every analysis of the missing
    channels in ``KeyError: 'v_sy'`` (exit 4); it is a recording that does not hold what its
    metadata states, exit 2 naming the step and the channels.
    """
    for entry in entries:
        noted = entry.record.get("daq_extremes")
        if not isinstance(noted, dict):
            continue
        missing = [s.channel for s in sensors if s.channel not in noted]
        if missing:
            raise RecordingError(
                f"{source}: step {entry.step.id} logged the sensor channel(s) "
                f"{', '.join(noted) or 'none'}, not {', '.join(missing)}, which the run "
                f"metadata names (sensors of {', '.join(s.channel for s in sensors)}): the "
                "DAQ did not record every channel of the sensor under test")


def _build_dataset(
    run_meta: dict[str, Any], entries: list[_StepEntry], source: Where, complete: bool
) -> Dataset:
    ordered = sorted(entries, key=lambda entry: entry.index)

    def load(index: int, log_source: str, channels: Container[str] | None) -> SampledLog:
        entry = ordered[index]
        return _load_log(entry, log_source, entry.chunks, channels)

    def pieces(index: int, log_source: str, channels: Container[str] | None
               ) -> Iterator[SampledLog]:
        entry = ordered[index]
        return _load_pieces(entry, log_source, entry.chunks, channels)

    steps = LazySteps([e.step for e in ordered], load, [e.samples for e in ordered], pieces,
                      [e.record.get("daq_extremes") for e in ordered])
    rate = run_meta.get("sample_rate_hz") or (
        ordered[0].step.sample_rate_hz if ordered else LOG_RATE_HZ
    )
    procedure = run_meta.get("procedure")
    metadata = {
        **run_meta,
        "source_format": fmt.FORMAT,
        "complete": complete,
        "recording": str(source),
    }
    sensors = _sensors(run_meta, steps)
    _check_recorded(sensors, ordered, source)
    return Dataset(
        procedure=procedure if isinstance(procedure, str) else "unknown",
        sample_rate_hz=float(rate),
        sensors=sensors,
        steps=steps,
        source=source,
        metadata=metadata,
    )
