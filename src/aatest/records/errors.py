"""Errors of the records store, all in the one :class:`~aatest.engine.errors.AatestError` tree."""

from __future__ import annotations

from aatest.engine.errors import InputError


class RecordsError(InputError):
    """The records store cannot do what was asked (bad URL, unknown record, bad query)."""


# The name is public (docs/interfaces.md, raised to callers of aatest.records); "Error" is in
# its base classes, so the N818 suffix rule is waived here rather than renaming the API.
class RecordsUnavailable(RecordsError, ConnectionError):  # noqa: N818
    """The records database cannot be reached or opened (exit 2); the message names the URL."""
