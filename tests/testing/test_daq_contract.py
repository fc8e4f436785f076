"""The DAQ checks of the conformance kit on synthetic logs: a log that keeps the contract
passes, and each single defect fails with the message that names it."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, TABLE, SampledLog
from aatest.testing import daq_conformance as d

RATE_HZ = 2000.0
N = 3000
DECLARED = ["v_sz", *DAQ_AUX_CHANNELS]


def daq_log(**change: np.ndarray) -> SampledLog:
    """3000 samples at 2 kHz: trigger from sample 700, a 10 ms freeze pulse (seeded jitter)."""
    rng = np.random.default_rng(7)
    time_s = np.arange(N) / RATE_HZ + rng.normal(0.0, 2e-6, N)  # 2 µs ≪ the 500 µs interval
    channels = {"v_sz": 2.5 + rng.normal(0.0, 1e-3, N),
                "sync_pulse": (np.arange(N) // 10 % 2).astype(float),
                "trigger": (np.arange(N) >= 700).astype(float),
                "temperature_c": np.full(N, 23.0)}
    time_s = change.pop("time_s", time_s)
    return SampledLog(DAQ, RATE_HZ, time_s, channels | change, {"v_sz": "V"} | DAQ_AUX_CHANNELS)


def table_log(latch: np.ndarray | None = None, samples: int = 1000) -> SampledLog:
    """The table's log of the same pulse: edges every 20 samples, latched 0.2 ms late."""
    pulse = (np.arange(samples) // 10 % 2).astype(float)
    if latch is None:
        latch = np.where(np.diff(pulse, prepend=0.0) > 0, 2e-4, np.nan)
    return SampledLog(TABLE, RATE_HZ, np.arange(samples) / RATE_HZ,
                      {"sync_pulse": pulse, "fp_latch_s": latch})


def check_all(log: SampledLog, table: SampledLog | None = None, latch: bool = True) -> None:
    d.check_log_channels(log, DECLARED)
    d.check_clock(log, table)
    d.check_trigger(log)
    d.check_freeze_pulse(log, table, latch)


def test_a_log_that_keeps_the_contract_passes() -> None:
    check_all(daq_log(), table_log())
    check_all(daq_log(), table_log(np.full(1000, np.nan)), latch=False)


def _swap(values: np.ndarray, i: int) -> np.ndarray:
    out = values.copy()
    out[[i, i + 1]] = out[[i + 1, i]]
    return out


Defect = Callable[[], tuple[SampledLog, SampledLog | None, bool]]
DEFECTS: dict[str, tuple[Defect, str]] = {
    "time goes back": (lambda: (daq_log(time_s=_swap(np.arange(N) / RATE_HZ, 100)), None, True),
                       "time stamps are not strictly increasing"),
    "rate 2 % off": (lambda: (daq_log(time_s=np.arange(N) / (0.98 * RATE_HZ)), None, True),
                     "median sample interval"),
    "shorter than the table": (lambda: (daq_log(), table_log(samples=N + 10), True),
                               "does not cover the table log"),
    "trigger high at start": (lambda: (daq_log(trigger=np.ones(N)), None, True),
                              "the trigger is high when logging starts"),
    "trigger falls": (lambda: (daq_log(trigger=((np.arange(N) >= 700) & (np.arange(N) < 2000))
                                       .astype(float)), None, True),
                      "the trigger falls during the record"),
    "no pulse": (lambda: (daq_log(sync_pulse=np.zeros(N)), None, True),
                 "fewer than three rising edges"),
    "pulse not binary": (lambda: (daq_log(sync_pulse=np.full(N, 0.5)), None, True),
                         "sync_pulse is not 0/1"),
    "table sees another period": (
        lambda: (daq_log(sync_pulse=(np.arange(N) // 14 % 2).astype(float)), table_log(), True),
        "the table sees a pulse period of 10 ms"),
    "edges not latched": (lambda: (daq_log(), table_log(np.full(1000, np.nan)), True),
                          "edges are not latched"),
    "latch beyond half a period": (lambda: (daq_log(), table_log(np.full(1000, 6e-3)), True),
                                   "not within half a pulse period"),
    "latch without a latch": (lambda: (daq_log(), table_log(), False),
                              "a table without a pulse latch reports latch times"),
}


@pytest.mark.parametrize("defect", list(DEFECTS))
def test_each_defect_fails_naming_it(defect: str) -> None:
    make, message = DEFECTS[defect]
    log, table, latch = make()
    with pytest.raises(AssertionError, match=message):
        check_all(log, table, latch)


def test_undeclared_channels_and_wrong_units_fail() -> None:
    with pytest.raises(AssertionError, match="are not the declared"):
        d.check_log_channels(daq_log(), ["v_sz", "v_sy", *DAQ_AUX_CHANNELS])
    wrong = daq_log()
    wrong = SampledLog(DAQ, RATE_HZ, wrong.time_s, wrong.channels,
                       {"v_sz": "mV"} | DAQ_AUX_CHANNELS)
    with pytest.raises(AssertionError, match="channel units"):
        d.check_log_channels(wrong, DECLARED)


class Declares:
    def __init__(self, names: list[str]) -> None:
        self.names = names

    def channels(self) -> list[str]:
        return self.names


@pytest.mark.parametrize(("names", "message"), [
    (["sync_pulse", "trigger", "temperature_c"], "must start with the sensor volts"),
    (["v_sz", "trigger", "sync_pulse", "temperature_c"], "must end with"),
    (["v_sz", "v_sz", *DAQ_AUX_CHANNELS], "repeats a name"),
])
def test_declared_channels_follow_the_contract(names: list[str], message: str) -> None:
    assert d.check_declared_channels(Declares(DECLARED)) == DECLARED
    with pytest.raises(AssertionError, match=message):
        d.check_declared_channels(Declares(names))
