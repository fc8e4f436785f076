"""Encoder rows of the budget: from the rig description, else the table plugin's declaration,
else a stated default that names the missing declaration (never a silent default)."""

from __future__ import annotations

import math
from typing import Any

import pytest

from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.measurands import RigConstants
from aatest.results import RunResults

A_ARCSEC = 3600.0


def _results(declared: dict[str, Any] | None, instruments: dict[str, Any] | None = None,
             plugin: str | None = "acme") -> RunResults:
    rig: dict[str, Any] = {}
    if plugin is not None:
        rig["capabilities"] = {"turntable": {"plugin": plugin, "distribution": "acme-kit 1.0",
                                             "declared": declared}}
    if instruments is not None:
        rig["instruments"] = instruments
    return RunResults.model_validate({"procedure": "declared", "metadata": {"rig": rig}})


def test_a_declared_encoder_replaces_the_default() -> None:
    c = RigConstants.from_results(_results({"encoder_resolution_counts_per_rev": 2**24,
                                            "encoder_accuracy_arcsec": 3.0}))
    row = comp.encoder_resolution(c, A_ARCSEC)
    q = 360 * 3600 / 2**24  # 0.0772″
    assert row.standard_uncertainty() == pytest.approx(q / math.sqrt(12) / A_ARCSEC, rel=1e-12)
    assert row.note.startswith("declared by the turntable plugin 'acme' (acme-kit 1.0): encoder "
                               "resolution 16777216 counts/rev (q = 0.0772″)")
    assert c.position_accuracy_arcsec == 3.0  # the declared accuracy reaches the positions too
    assert comp.encoder_accuracy(c, A_ARCSEC).note.startswith("declared by the turntable")


def test_a_default_names_the_missing_declaration() -> None:
    c = RigConstants.from_results(_results({"encoder_resolution_counts_per_rev": None}))
    note = comp.encoder_resolution(c, A_ARCSEC).note
    assert note.startswith("stated default: encoder resolution 129600000 counts/rev (q = 0.01″)")
    assert ("missing declaration: the turntable plugin 'acme' (acme-kit 1.0) declares no "
            "encoder resolution, and the rig description states no encoder resolution") in note
    imported = RigConstants.from_results(_results(None, plugin=None))
    assert "no turntable plugin declared it" in comp.encoder_accuracy(imported, A_ARCSEC).note


def test_the_rig_description_wins_field_by_field() -> None:
    c = RigConstants.from_results(_results(
        {"encoder_resolution_counts_per_rev": 2**24, "encoder_accuracy_arcsec": 3.0},
        instruments={"encoder": {"accuracy_arcsec": 0.5, "cert_id": "ENC-1"}}))
    assert comp.encoder_accuracy(c, A_ARCSEC).note.startswith(
        "rig description: encoder accuracy ±0.5″ (cert ENC-1)")
    assert comp.encoder_resolution(c, A_ARCSEC).note.startswith("declared by the turntable")
