"""Significant figures: the one number format of reports, station and terminal.

Both the quantity registry (:mod:`aatest.results.quantities`, a quantity's digits) and the GUM
rounding of a value with its uncertainty (:mod:`aatest.results.rounding`) build on
:func:`significant`; it lives apart from both so that the registry can round with the
rounding module without either importing the other.
"""

from __future__ import annotations

from aatest.results._fields import finite

__all__ = ["COUNT", "SCIENTIFIC_ABOVE", "SCIENTIFIC_BELOW", "U_DIGITS", "significant"]

#: significant digits of an expanded uncertainty (GUM 7.2.6: at most two)
U_DIGITS = 2
#: the digits of a count (a number of samples): written whole, never rounded
COUNT = 0
#: magnitudes written in scientific notation: at or above the first, below the second
SCIENTIFIC_ABOVE, SCIENTIFIC_BELOW = 1e6, 1e-3


def significant(value: float | None, digits: int) -> str:
    """``value`` to ``digits`` significant figures, scientific outside 1e-3…1e6; ``—`` when
    there is no finite value. The one number format of reports, station and terminal.
    ``digits`` 0 marks a count (:data:`COUNT`): the whole number, every digit.

    >>> significant(0.0040139, 5), significant(2.4987, 6), significant(None, 3)
    ('4.0139e-03', '2.49870', '—')
    >>> significant(1234567.0, COUNT), significant(0.0, COUNT)
    ('1234567', '0')
    """
    f = finite(value)
    if f is None:
        return "—"
    if digits == COUNT:
        return f"{f:.0f}"
    if f != 0 and (abs(f) >= SCIENTIFIC_ABOVE or abs(f) < SCIENTIFIC_BELOW):
        return f"{f:.{max(digits - 1, 0)}e}"
    return f"{f:.{digits}g}" if abs(f) >= 10 ** digits else f"{f:#.{digits}g}".rstrip(".")
