"""The ``instruments`` block of ``--rig``: strict, located errors, traceability text."""

from __future__ import annotations

from pathlib import Path

import pytest

from aatest.engine.errors import ProcedureError
from aatest.engine.procedure.loader import load_rig
from aatest.engine.rig_description import Instruments


def test_unknown_instrument_key_is_located(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: sim}\ninstruments:\n  logger:\n    gain_acuracy_pct: 0.1\n",
                   encoding="utf-8")
    with pytest.raises(ProcedureError) as err:
        load_rig(rig)
    text = str(err.value)
    assert f"{rig}:4:" in text and "gain_acuracy_pct" in text
    assert "gain_accuracy_pct" in text  # the "did you mean" hint


def test_logger_range_must_be_ordered(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("instruments:\n  logger: {range_v: [10, -10]}\n", encoding="utf-8")
    with pytest.raises(ProcedureError, match="range_v"):
        load_rig(rig)


def test_traceability_names_missing_certificates() -> None:
    trace = Instruments.model_validate(
        {"encoder": {"cert_id": "ENC-1", "cert_date": "2026-01-12"}}).traceability()
    assert trace["encoder"] == {"cert_id": "ENC-1", "cert_date": "2026-01-12",
                                "lab": "not stated", "accuracy": "±1″, 129600000 counts/rev"}
    assert trace["logger"]["cert_id"] == "not stated"
