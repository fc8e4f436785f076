"""GUM 7.2.6 rounding: U to two significant digits, the value to U's last decimal place.

Every expected string is worked out by hand from the rule (comments show the steps), so the
test fails if the module rounds to a different place, drops a significant zero, lets a
binary-expansion tail through, or prints rounding noise instead of ``< x``.
"""

from __future__ import annotations

import math

import pytest

from aatest.results.quantities import QUANTITIES
from aatest.results.rounding import measurement_text, round_measurement


@pytest.mark.parametrize(("value", "u", "expected"), [
    # U 0.0123 → 0.012 (last place 1e-3); 2.49872 → 2.499
    (2.49872, 0.0123, "2.499 ± 0.012"),
    # U 4.67599e-6 → 4.7e-6 (place 1e-7); 0.0040139 → 0.0040139 → scientific (7 decimals)
    (0.0040139, 4.67599e-06, "4.0139e-03 ± 4.7e-06"),
    # U 0.0996 → 0.10 (still two digits: place 1e-2); 1.0 → 1.00, the zero is significant
    (1.0, 0.0996, "1.00 ± 0.10"),
    # half rounds up: U 0.125 → 0.13, value 2.5 → 2.50
    (2.5, 0.125, "2.50 ± 0.13"),
    # U 96.4 → 96 (place 1); 12345.678 → 12346
    (12345.678, 96.4, "12346 ± 96"),
    # U 1234 → 1.2e3 (place 100); 1234567.8 → 1234600 → scientific with U in the same form
    (1234567.8, 1234.0, "1.2346e+06 ± 1.2e+03"),
    # a negative value keeps its sign; place 1e-4
    (-0.01234, 0.0012, "-0.0123 ± 0.0012"),
    # exactly zero is a value, not below resolution
    (0.0, 0.0012, "0.0000 ± 0.0012"),
    # 0.1 + 0.2 = 0.30000000000000004: no binary tail survives
    (0.1 + 0.2, 0.011, "0.300 ± 0.011"),
])
def test_value_rounds_to_the_last_place_of_u(value: float, u: float, expected: str) -> None:
    assert measurement_text(value, u) == expected


def test_rounding_noise_reads_below_resolution() -> None:
    # the nonlinearity: 4.920e-15 % FR with U 0.0021 % FR → place 1e-4 → rounds to 0
    rounded = round_measurement(4.92e-15, 0.0021)
    assert rounded.below_resolution and rounded.text("% FR") == "< 0.0001 ± 0.0021 % FR"
    # a small negative value also reads < x (|value| below the resolution)
    assert measurement_text(-2e-5, 0.0012) == "< 0.0001 ± 0.0012"
    # at half a unit it rounds away from zero: a value, not noise
    assert measurement_text(5e-5, 0.0012) == "0.0001 ± 0.0012"


def test_explicit_resolution() -> None:
    assert measurement_text(3e-5, None, "V", resolution=1e-4) == "< 0.0001 V"
    assert measurement_text(3e-4, None, "V", resolution=1e-4, digits=3) == "3.00e-04 V"
    assert measurement_text(2e-12, None, resolution=1e-9) == "< 1e-09"


def test_without_u_the_registry_digits_apply() -> None:
    assert measurement_text(123.456, None, digits=4) == "123.5"
    assert measurement_text(5e-7, None, digits=3) == "5.00e-07"
    assert measurement_text(2.0, 0.0, digits=3) == "2.00"  # a U of 0 is no statement


@pytest.mark.parametrize("missing", [None, math.nan, math.inf])
def test_missing_values_read_as_a_dash(missing: float | None) -> None:
    assert measurement_text(missing) == "—"
    assert measurement_text(missing, 0.31) == "— ± 0.31"


def test_quantity_show_uses_the_rule() -> None:
    scale = QUANTITIES["scale_factor"]
    assert scale.show(0.0040139, 4.67599e-6) == "4.0139e-03 ± 4.7e-06 V/(°/s²)"
    nonlinearity = QUANTITIES["nonlinearity_pct_fr"]
    assert nonlinearity.show(4.92e-15, 0.0021) == "< 0.0001 ± 0.0021 % FR"


def test_report_templates_have_the_rule_as_a_filter() -> None:
    from aatest.plugins.report.sandbox import make_environment

    template = make_environment().from_string(
        "{{ r.v | measurement(r.u, 'V', 4) }}|{{ r.missing | measurement }}")
    assert template.render(r={"v": 2.49872, "u": 0.0123}) == "2.499 ± 0.012 V|—"
