"""Errors of the records store, all in the one :class:`~aatest.engine.errors.AatestError` tree."""

from __future__ import annotations

from aatest.engine.errors import InputError


class RecordsError(InputError):
    """The records store cannot do what was asked (bad URL, unknown record, bad query)."""


class RecordsUnavailable(RecordsError, ConnectionError):
    """The records database cannot be reached or opened (exit 2); the message names the URL."""
