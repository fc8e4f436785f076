"""The template number filters never raise, whatever a result holds (hypothesis)."""

from __future__ import annotations

import math
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from aatest.plugins.report.sandbox import _fixed, _num


@given(st.floats(allow_nan=True, allow_infinity=True) | st.none() | st.text(max_size=5))
def test_number_filters_never_raise(value: Any) -> None:
    for text in (_num(value), _fixed(value)):
        assert isinstance(text, str)
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        assert _num(value) == "—" and _fixed(value) == "—"
