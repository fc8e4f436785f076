"""A number written with its unit is an error that says the unit and gives an example."""

from __future__ import annotations

import pytest

from aatest.engine.errors import ProcedureError
from aatest.engine.procedure.loader import parse_procedure

TEXT = """\
procedure: t
sensor: {model: sr207}
steps:
  - sine: {axis: inner, frequency_hz: 1 kHz, accel_dps2: 400}
  - static: {duration_s: "10 s"}
acceptance: {limits: {bias_deviation_v: 10 mV}}
"""


def test_unit_in_a_number_field_names_the_unit() -> None:
    with pytest.raises(ProcedureError) as caught:
        parse_procedure(TEXT, "p.yaml")
    found = {p.field: (p.line, p.message) for p in caught.value.problems}
    assert found["steps.0.sine.frequency_hz"] == (4, "Input should be a valid number (got "
                                                  "'1 kHz'; expected a number in Hz, e.g. 1000)")
    assert "expected a number in seconds, e.g. 60" in found["steps.1.static.duration_s"][1]
    assert "expected a number in volts" in found["acceptance.limits.bias_deviation_v"][1]
