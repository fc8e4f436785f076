"""Preflight checks of what a run needs beside the procedure: the run directory, the lab
profile, the signing key (and its passphrase) and the records store.

Each returns ``(problems, message)`` or raises the error a run would meet later: the lab
profile's own ``FILE:LINE:COLUMN`` problems from the model loader, a
:class:`~aatest.bundle.signing.SigningError` naming the key file, a
:class:`~aatest.records.errors.RecordsError` naming the database (without its password).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from aatest.engine.errors import Problem

Outcome = tuple[list[Problem], str]


def lab_check(lab: Path | None) -> Outcome:
    """The lab profile (``--lab``, ``AATEST_LAB``) loads; none given is the defaults."""
    from aatest.records.lab import lab_path, load_lab

    chosen = lab_path(lab)
    profile = load_lab(lab)
    if chosen is None:
        return [], f"no lab profile given: the defaults (prefix {profile.certificate_prefix})"
    return [], f"{chosen}: {profile.name}, certificate prefix {profile.certificate_prefix}"


def key_check(key: Path | None, proc: Any) -> Outcome:
    """The signing key opens with ``AATEST_SIGNING_PASSPHRASE``; none leaves the report
    unsigned, which fails when the procedure ``proc`` (None: it did not load) asks for a
    signed report (:func:`aatest.bundle.signing_key.signing_problems`)."""
    from aatest.bundle.signing import key_fingerprint, load_private_key
    from aatest.bundle.signing_key import (
        PASSPHRASE_ENV,
        SIGNING_KEY_ENV,
        signing_key,
        signing_problems,
    )

    path = signing_key(key)
    if path is None:
        problems = signing_problems(proc, None) if proc is not None else []
        if problems:
            return problems, "the procedure asks for a signed report: no signing key"
        return [], f"no signing key (--sign-key or {SIGNING_KEY_ENV}): the report is unsigned"
    private = load_private_key(path, os.environ.get(PASSPHRASE_ENV))
    return [], f"{path}: opens, fingerprint {key_fingerprint(private.public_key())}"


def records_check(records: str | None, migrate: bool) -> Outcome:
    """The records store is reachable and at the schema head (``run`` migrates it now;
    ``validate`` changes nothing and says it will be migrated). A store written by a newer
    aatest (a revision this one does not know) is refused."""
    from aatest.records import schema
    from aatest.records.engine import open_engine
    from aatest.records.errors import RecordsError
    from aatest.records.url import is_default_missing, redacted, resolve_url

    url = resolve_url(records)
    name = redacted(url)
    if is_default_missing(url):
        folder = Path(str(url.database)).absolute().parent
        if not _creatable(folder):
            raise RecordsError(f"records store {name} cannot be created: {folder} is not "
                               "writable")
        return [], f"{name}: created and migrated at the first registration"
    engine = open_engine(url)  # RecordsUnavailable when it cannot be reached
    try:
        current, head = schema.current_revision(engine), schema.head_revision()
        if current == head:
            return [], f"{name}: reachable, schema at head ({head})"
        if not schema.known_revision(current):
            raise RecordsError(f"records store {name}: schema revision {current!r} is unknown "
                               f"to this aatest (head {head}): written by a newer version")
        if migrate:
            schema.upgrade(engine)
            return [], f"{name}: reachable, migrated from {current or 'empty'} to {head}"
        return [], f"{name}: reachable, at {current or 'empty'}; migrated to {head} by the run"
    finally:
        engine.dispose()


def _creatable(folder: Path) -> bool:
    """``folder`` (or its nearest existing ancestor, created on demand) is writable."""
    for candidate in (folder, *folder.parents):
        if candidate.exists():
            return os.access(candidate, os.W_OK)
    return False


#: files of a run's directory listed when it is refused (the rest are counted)
_SHOWN_FILES = 5


def run_directory_check(out_dir: Path | None) -> Outcome:
    """``--out`` is new, empty, or a run's own directory (its ``run_state.json``: ``run``
    refuses it without ``--resume``). Why: a run writes its bundle into the directory and
    signs every file in it, so a run into the directory of an earlier ``analyze`` replaced
    that bundle's signed report and ``results.json``, and unrelated files there were signed
    as part of the calibration. Raises InputError naming the directory and its files."""
    from aatest.engine.errors import InputError
    from aatest.engine.run.run_state import LOCK_FILE, STATE_FILE

    if out_dir is None:
        return [], "a new run directory is made"
    if not out_dir.exists():
        return [], f"{out_dir}: made by the run"
    if not out_dir.is_dir():
        raise InputError(f"{out_dir}: not a directory; choose a new or empty --out")
    if (out_dir / STATE_FILE).is_file():
        return [], f"{out_dir}: holds a run (continued with --resume)"
    others = sorted(p.name for p in out_dir.iterdir() if p.name != LOCK_FILE)
    if not others:
        return [], f"{out_dir}: empty"
    shown = ", ".join(others[:_SHOWN_FILES]) + (
        f", … ({len(others)} entries)" if len(others) > _SHOWN_FILES else "")
    raise InputError(f"{out_dir} holds files that are not a run ({shown}): a run writes its "
                     "bundle there and signs every file in it; choose a new or empty --out")
