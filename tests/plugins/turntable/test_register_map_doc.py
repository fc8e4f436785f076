"""docs/modbus-register-map.md lists every register of the code's map at the same address."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from aatest.protocols import modbus_map as mm

DOC = Path(__file__).parents[3] / "docs" / "modbus-register-map.md"


@pytest.fixture(scope="module")
def documented() -> dict[str, int]:
    rows = re.findall(r"^\| (\d+) \| ([A-Z0-9_]+) \|", DOC.read_text(), flags=re.MULTILINE)
    return {name: int(address) for address, name in rows if name in mm.Reg.__members__}


def test_every_register_is_documented_at_its_address(documented: dict[str, int]) -> None:
    assert documented == {r.name: int(r) for r in mm.Reg}


def test_every_log_channel_is_documented() -> None:
    text = DOC.read_text()
    for channel in mm.LOG_CHANNELS:
        assert f"| {channel.code} | {channel.name} | {channel.encoding} |" in text
