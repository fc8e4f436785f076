"""Transfer-function fits made while the run records: taken only for the same inputs."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aatest.early.child import _Later
from aatest.early.made import LaterMade
from aatest.plugins.analysis.tf_early import fit_digest
from aatest.plugins.analysis.tf_models import (
    TransferFunctionOptions,
    estimate,
    estimate_in_pieces,
    run_through,
)

F_HZ = np.array([1.0, 2.0, 4.0, 8.0, 16.0, 32.0])
XCORR = ({"delay_samples": 3, "delay_s": 0.0015, "strength": 0.97, "accepted": True}, 2000.0)


def _h(f_hz: np.ndarray) -> np.ndarray:
    """A second-order response (fn 60 Hz, ζ 0.6) with a 1.5 ms delay."""
    s = 2j * np.pi * f_hz
    wn = 2 * np.pi * 60.0
    return 0.004 * wn**2 / (s**2 + 1.2 * wn * s + wn**2) * np.exp(-s * 0.0015)


def _digest(**changed: Any) -> str:
    args = {"kind": "estimate", "f_hz": F_HZ, "h": _h(F_HZ), "xcorr": XCORR, "channel": "v_sz",
            "options": TransferFunctionOptions(), "antialias_hz": 400.0} | changed
    return fit_digest(**args)


def test_the_digest_names_the_inputs_to_the_last_bit() -> None:
    assert _digest() == _digest(h=_h(F_HZ.copy()))  # equal values: equal digest
    h = _h(F_HZ)
    h[2] = complex(np.nextafter(h[2].real, 1.0), h[2].imag)  # one bit of one response
    others = [_digest(h=h), _digest(f_hz=F_HZ * (1 + 2**-52)), _digest(kind="physical"),
              _digest(xcorr=({**XCORR[0], "delay_samples": 4}, XCORR[1])),
              _digest(xcorr=(XCORR[0], 1000.0)), _digest(channel="v_sx"),
              _digest(options=TransferFunctionOptions(max_poles=4)), _digest(antialias_hz=None),
              _digest(f_hz=F_HZ.astype(np.float32))]
    assert len({_digest(), *others}) == len(others) + 1


def test_the_pieces_make_what_the_estimate_makes() -> None:
    h = _h(F_HZ)
    pieces = estimate_in_pieces(F_HZ, h, 1 / 2000.0, XCORR[0])
    count = 0
    with pytest.raises(StopIteration) as done:
        while True:
            next(pieces)
            count += 1
    model, rows, k = done.value.value
    whole_model, whole_rows, whole_k = estimate(F_HZ, h, 1 / 2000.0, XCORR[0])
    assert count == len(rows)  # one pause after each candidate model
    assert k == whole_k and rows == whole_rows
    assert np.array_equal(model.num, whole_model.num) and np.array_equal(model.den,
                                                                           whole_model.den)
    assert run_through(estimate_in_pieces(F_HZ, h, 1 / 2000.0, XCORR[0]))[2] == k


def test_an_item_that_raises_is_not_sent_and_the_next_is_made() -> None:
    sent: list[LaterMade] = []
    later = _Later(lambda message: sent.append(message) is None)

    def failing() -> Any:
        yield
        raise ValueError("no fit")

    def fine() -> Any:
        yield
        yield
        return {"a": 1}

    later.put("transfer_function", "v_sz:g1", failing, "ctx")
    later.put("transfer_function", "v_sz:g2", fine, "ctx")
    steps = 0
    while later.pending:
        assert later.advance()
        steps += 1
    assert [(m.key, m.value, m.context) for m in sent] == [("v_sz:g2", {"a": 1}, "ctx")]
    assert steps == 5  # 2 pieces of the failing item, 3 of the fine one


def test_a_gone_run_process_ends_the_work() -> None:
    later = _Later(lambda message: False)  # the send failed: the pipe is closed

    def one() -> Any:
        return 1
        yield  # a generator

    later.put("transfer_function", "v_sz:g1", one, "ctx")
    assert later.advance() is False
