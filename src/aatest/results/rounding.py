"""Rounding of a measured value and its expanded uncertainty for a person (GUM 7.2.6).

JCGM 100 §7.2.6: U is stated to at most two significant digits and the value is rounded to
the same decimal place, so no digit is printed that the uncertainty makes meaningless. A value
whose magnitude lies below the resolution of that statement (it would round to zero, e.g. a
nonlinearity of 4.9e-15 % FR that is the arithmetic's noise) is printed as ``< x`` with ``x``
the resolution, never as rounding noise. One pure function serves the terminal, ``aatest
history``, ``records list`` and the certificate templates (as a Jinja filter), so they can
never disagree on a number.

>>> measurement_text(0.0040139, 4.67599e-06)
'4.0139e-03 ± 4.7e-06'
>>> measurement_text(2.49872, 0.0123, "V")
'2.499 ± 0.012 V'
>>> measurement_text(4.92e-15, 0.0021, "% FR")
'< 0.0001 ± 0.0021 % FR'
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal

from aatest.results._fields import finite
from aatest.results.digits import U_DIGITS, significant

__all__ = ["U_DIGITS", "Rounded", "measurement_text", "round_measurement"]

#: decimal places written in fixed notation; a finer last place switches to scientific
FIXED_MAX_DECIMALS = 6
#: magnitudes at or above this are written in scientific notation
FIXED_MAX_MAGNITUDE = 1e6
#: significant digits of a value stated without an uncertainty, unless the caller says
DEFAULT_DIGITS = 6


@dataclass(frozen=True)
class Rounded:
    """A value (and U) as printed: ``value`` may read ``< x``; ``uncertainty`` is None
    without a stated U; ``below_resolution`` says the value was replaced by ``< x``."""

    value: str
    uncertainty: str | None = None
    below_resolution: bool = False

    def text(self, unit: str = "") -> str:
        """``value ± U unit`` (``value unit`` without a U)."""
        body = self.value if self.uncertainty is None else f"{self.value} ± {self.uncertainty}"
        return f"{body} {unit}".rstrip()


def _decimal(x: float) -> Decimal:
    """The shortest decimal that reads back as ``x`` (no binary-expansion tail)."""
    return Decimal(repr(float(x)))


def _place(x: Decimal) -> int:
    """Exponent of the leading digit of a non-zero ``x``: 0.0047 → -3."""
    return x.adjusted()


def _quantize(x: Decimal, place: int) -> Decimal:
    rounded = x.quantize(Decimal(1).scaleb(place), rounding=ROUND_HALF_UP)
    return abs(rounded) if rounded == 0 else rounded  # never "-0.000"


def _fixed(place: int, magnitude: Decimal) -> bool:
    """Fixed notation when the last place and the size stay short, else scientific."""
    return place >= -FIXED_MAX_DECIMALS and abs(magnitude) < Decimal(FIXED_MAX_MAGNITUDE)


def _fmt(x: Decimal, place: int, magnitude: Decimal, fixed: bool | None = None) -> str:
    """``x`` with its last digit at 10**place: fixed when short, else scientific."""
    if _fixed(place, magnitude) if fixed is None else fixed:
        return format(x, "f")
    lead = _place(magnitude) if magnitude != 0 else place
    return f"{float(x):.{max(lead - place, 0)}e}"


def _rounded_u(u: float) -> tuple[Decimal, int]:
    """U to two significant digits and the decimal place of its last digit."""
    d = _decimal(u)
    place = _place(d) - (U_DIGITS - 1)
    rounded = _quantize(d, place)
    if _place(rounded) - (U_DIGITS - 1) != place:  # 0.0996 → 0.10: still two digits
        place = _place(rounded) - (U_DIGITS - 1)
        rounded = _quantize(d, place)
    return rounded, place


def _resolution_text(resolution: float) -> str:
    d = _decimal(resolution)
    exponent = d.as_tuple().exponent
    return _fmt(d, min(exponent, 0) if isinstance(exponent, int) else 0, d)


def round_measurement(value: float | None, u: float | None = None, *,
                      digits: int = DEFAULT_DIGITS,
                      resolution: float | None = None) -> Rounded:
    """``value`` (and ``u``) rounded for a person.

    Parameters
    ----------
    value : the estimate; ``None``/NaN/inf read ``—``.
    u : expanded uncertainty U in the value's unit; without a finite positive U the value keeps
        ``digits`` significant digits (there is no statement to round it to).
    digits : significant digits of a value without U (the quantity registry's ``digits``).
    resolution : an explicit resolution (e.g. of the instrument); a value whose magnitude is
        below it reads ``< resolution``. Without one, with a U, the resolution is one unit in
        the last decimal place kept, and a non-zero value that rounds to zero reads ``< 10^p``.
    """
    v = finite(value)
    if v is None:
        return Rounded("—", _u_only(u))
    if resolution is not None and abs(v) < resolution:
        return Rounded(f"< {_resolution_text(resolution)}", _u_only(u), below_resolution=True)
    u_f = finite(u)
    if u_f is None or u_f <= 0:
        return Rounded(significant(v, digits))
    u_rounded, place = _rounded_u(u_f)
    v_rounded = _quantize(_decimal(v), place)
    fixed = _fixed(place, max(abs(v_rounded), u_rounded))  # one notation for value and U
    u_text = _fmt(u_rounded, place, u_rounded, fixed)
    if v_rounded == 0 and v != 0:
        step = Decimal(1).scaleb(place)
        return Rounded(f"< {_fmt(step, place, step, fixed)}", u_text, below_resolution=True)
    return Rounded(_fmt(v_rounded, place, v_rounded if v_rounded != 0 else u_rounded, fixed),
                   u_text)


def _u_only(u: float | None) -> str | None:
    """U alone (two significant digits) when there is no value to round to it."""
    u_f = finite(u)
    if u_f is None or u_f <= 0:
        return None
    rounded, place = _rounded_u(u_f)
    return _fmt(rounded, place, rounded)


def measurement_text(value: float | None, u: float | None = None, unit: str = "", *,
                     digits: int = DEFAULT_DIGITS, resolution: float | None = None) -> str:
    """``value ± U unit`` per GUM 7.2.6 (see :func:`round_measurement`); a Jinja filter too."""
    return round_measurement(value, u, digits=digits, resolution=resolution).text(unit)

