"""Field types the result models share: JSON-safe reals, complex pairs, per-channel maps.

JSON has no NaN or infinity, yet a fit can legitimately produce one (a model that does not
converge has no finite fit percentage). :data:`Real` keeps such a value as a float in memory,
writes it as ``null`` and reads ``null`` back as NaN, so results.json stays valid JSON and a
re-read result compares equal to what was written.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Annotated, Any, Generic, TypeVar

from pydantic import BeforeValidator, PlainSerializer, RootModel, WithJsonSchema


def _none_to_nan(value: Any) -> Any:
    return math.nan if value is None else value


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


#: a float that is written as ``null`` when it is NaN or infinite (and read back as NaN)
Real = Annotated[
    float,
    BeforeValidator(_none_to_nan),
    PlainSerializer(_finite_or_none, return_type=float | None, when_used="json"),
    WithJsonSchema({"anyOf": [{"type": "number"}, {"type": "null"}]}),
]
#: a complex number as ``[real, imaginary]``
ComplexPair = list[Real]

T = TypeVar("T")


class PerChannel(RootModel[dict[str, T]], Generic[T]):
    """A result per sensor channel (``v_sz``, …): a mapping that reads like one."""

    def __getitem__(self, channel: str) -> T:
        return self.root[channel]

    def __contains__(self, channel: object) -> bool:
        return channel in self.root

    def __iter__(self) -> Iterator[str]:  # type: ignore[override]
        return iter(self.root)

    def __len__(self) -> int:
        return len(self.root)

    def get(self, channel: str, default: T | None = None) -> T | None:
        """The channel's result, or ``default`` when the channel has none."""
        return self.root.get(channel, default)

    def items(self) -> Any:
        """(channel, result) pairs."""
        return self.root.items()


def finite(value: float | None) -> float | None:
    """The value when it is a finite number; None for a missing, NaN or infinite one."""
    return value if value is not None and math.isfinite(value) else None
