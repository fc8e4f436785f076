"""The errors of a report template: broken, or refused by the sandbox or its limits.

Both the sandbox (:mod:`.sandbox`, in the parent and in the render child) and the confined
render (:mod:`.confined`, the parent's side of the child process) raise them, so they live
apart from either; :mod:`.sandbox` re-exports them.
"""

from __future__ import annotations

from aatest.engine.errors import InputError


class TemplateError(InputError):
    """A report template is missing or broken (the message names the file and line)."""


class TemplateSecurityError(TemplateError):
    """A report template tried to leave the sandbox and was refused."""
