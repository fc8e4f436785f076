"""Procedures uploaded from the browser: checked, validated like a file on disk, then kept.

The browser sends the file's text and its name, never a path. The name is reduced to a plain
file name (``[A-Za-z0-9._-]``, ``.yaml``/``.yml``) used only for messages and the listing; the
file is stored in the station's own upload directory under that name plus a hash of its text
(``scale-factor.3f9a2c1e.yaml``), so two uploads never overwrite each other and a stopped run
finds the exact text it was started with when resumed. The upload is validated by the same
loader, planner and envelope check as ``aatest validate`` (:func:`catalogue.validation`), and
its FILE:LINE:COLUMN problems name the uploaded file; only a valid procedure is kept (and so
listed and startable), an invalid one is deleted after its problems are reported.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aatest.engine.errors import InputError
from aatest.station.catalogue import UPLOAD_PREFIX, validation

#: the largest procedure accepted (the shipped ones are 1–3 kB)
MAX_UPLOAD_BYTES = 256 * 1024
#: uploads kept before the station refuses more (each is a small YAML file)
MAX_STORED_UPLOADS = 500
#: characters kept in an uploaded file's name; anything else becomes "-"
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
_SUFFIXES = (".yaml", ".yml")
_MAX_NAME_CHARS = 80
_HASH_CHARS = 8


class UploadError(InputError):
    """An upload refused before validation (name, size, encoding, store full); HTTP ``status``."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def clean_name(name: str) -> str:
    """The plain file name of an upload: last path component, safe characters, YAML suffix.

    Raises :class:`UploadError` when nothing usable is left or the suffix is not YAML.
    """
    base = re.split(r"[/\\]", name.strip())[-1]
    safe = _UNSAFE.sub("-", base).strip(".-")[:_MAX_NAME_CHARS]
    if not safe.lower().endswith(_SUFFIXES) or len(safe) <= len(".yml"):
        raise UploadError(f"{name!r}: upload a procedure file named *.yaml or *.yml")
    stem, dot, suffix = safe.rpartition(".")
    return f"{stem}{dot}{suffix.lower()}"  # X.YAML is kept, listed and counted as X.yaml


def decode(body: bytes, name: str) -> str:
    """The upload's text; size and encoding are checked before any YAML is parsed."""
    if len(body) > MAX_UPLOAD_BYTES:
        raise UploadError(
            f"{name}: {len(body)} bytes; a procedure may have at most {MAX_UPLOAD_BYTES} bytes",
            status=413)
    if not body.strip():
        raise UploadError(f"{name}: the file is empty")
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UploadError(f"{name}: not UTF-8 text (byte {exc.start})") from exc


def stored_name(name: str, text: str) -> str:
    """``<stem>.<first 8 hex of SHA-256 of the text><suffix>``: distinct texts, distinct files."""
    stem, dot, suffix = name.rpartition(".")
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()[:_HASH_CHARS]
    return f"{stem}.{digest}{dot}{suffix}"


def stored_count(directory: Path) -> int:
    """Files kept in the upload directory, whatever their name or case (pending ones aside)."""
    return sum(1 for p in directory.iterdir() if not p.name.startswith(".pending-"))


@dataclass(frozen=True)
class Uploads:
    """The station's upload directory and what it accepts."""

    directory: Path

    def accept(self, name: str, body: bytes, rig_file: Path | None) -> dict[str, Any]:
        """Validate an upload; keep it when valid. Returns the validation with ``id``/``name``.

        The problems name the uploaded file (``NAME:LINE:COLUMN: field: message``), exactly as
        ``aatest validate NAME`` would print them for the same file on disk.
        """
        clean = clean_name(name)
        text = decode(body, clean)
        target = self.directory / stored_name(clean, text)
        self.directory.mkdir(parents=True, exist_ok=True)
        if not target.is_file() and stored_count(self.directory) >= MAX_STORED_UPLOADS:
            raise UploadError(f"the station keeps at most {MAX_STORED_UPLOADS} uploads; "
                                 f"remove old ones from {self.directory}", status=507)
        with tempfile.TemporaryDirectory(dir=self.directory, prefix=".pending-") as pending:
            candidate = Path(pending) / clean  # the uploaded name, as the loader reports it
            candidate.write_text(text, encoding="utf-8")
            result = validation(candidate, rig_file)
            result["problems"] = [p.replace(str(candidate), clean)
                                  for p in result.get("problems", [])]
            if result["ok"]:
                os.replace(candidate, target)
        result.update(name=clean, id=f"{UPLOAD_PREFIX}{target.name}" if result["ok"] else None)
        return result
