"""A seeded archive of twin runs with known truth, for the batch tests and ``bench/batch.py``.

Each :class:`TwinUnit` is one simulated run of a unit whose true scale factor deviates from
the datasheet nominal by ``scale_deviation_pct``, recorded on a rig whose sensor logger reads
``logger_gain_error_ppm`` high, with the rig naming its reference standards; the run is
registered in the records store like any ``aatest run``. Every number that matters is stated
here, so a test knows which certificates used which reference and what the correct value is.

The runs are simulations (and registered as such): they test the machinery, never a unit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import date, timedelta
from pathlib import Path

from aatest.engine.datasheet import REFERENCE_SCALE_V_PER_DPS2

#: the smallest scale-factor procedure (3 coherent 1 Hz cycles), shipped with the bench
TINY_PROCEDURE = """\
procedure: tiny-scale-factor
standard: IEEE-671-style
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 6000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""


@dataclass(frozen=True)
class TwinUnit:
    """One run of the archive: the unit, its true deviation, and the rig it ran on."""

    serial: str
    scale_deviation_pct: float
    rig: str
    references: tuple[str, ...]
    logger_gain_error_ppm: float = 0.0
    seed: int = 0

    @property
    def true_scale_v_per_dps2(self) -> float:
        """The simulated unit's true scale factor, V/(°/s²)."""
        return REFERENCE_SCALE_V_PER_DPS2 * (1.0 + self.scale_deviation_pct / 100.0)


def register_references(records_url: str, encoders: Sequence[str],
                        loggers: Sequence[str]) -> None:
    """Register the references the archive's rigs name (valid for a year from today)."""
    from aatest.records import references
    from aatest.records.store import RecordStore

    today = date.today()
    with RecordStore.open(records_url) as store:
        for identifier, kind in [(e, "encoder") for e in encoders] + \
                                [(g, "data-logger") for g in loggers]:
            references.add(store, references.ReferenceStandard(
                identifier=identifier, kind=kind, certificate_number=f"C-{identifier}",
                issuing_lab="National Lab", calibrated_on=today - timedelta(days=30),
                due_on=today + timedelta(days=335), accuracy="as stated"))


def _rig_file(unit: TwinUnit, folder: Path) -> Path:
    model = folder / f"{unit.rig}-{unit.serial}-model.yaml"
    model.write_text(
        f"sensors:\n  - {{channel: v_sz, scale_v_per_dps2: {unit.true_scale_v_per_dps2!r}}}\n"
        f"daq:\n  logger_error: {{gain_error: {unit.logger_gain_error_ppm * 1e-6!r}}}\n",
        encoding="utf-8")
    rig = folder / f"{unit.rig}-{unit.serial}-rig.yaml"
    rig.write_text(f"turntable: {{plugin: sim, model: {model}}}\n"
                   f"daq: {{plugin: sim, model: {model}}}\nchamber: {{plugin: none}}\n"
                   f"references: [{', '.join(unit.references)}]\n", encoding="utf-8")
    return rig


def record_run(unit: TwinUnit, root: Path, records_url: str) -> Path:
    """Run ``unit`` on the twin into ``root/<rig>/<serial>-<seed>`` and register it, as
    ``aatest run --rig … --serial … --records …`` does (the rig's references checked against
    the register first); the run directory."""
    from aatest.engine.procedure.loader import load_rig
    from aatest.engine.run import session
    from aatest.records import references
    from aatest.records.hook import registering
    from aatest.records.lab import LabProfile

    folder = root / unit.rig
    folder.mkdir(parents=True, exist_ok=True)
    procedure = root / "tiny-scale-factor.yaml"
    if not procedure.exists():
        procedure.write_text(TINY_PROCEDURE, encoding="utf-8")
    out = folder / f"{unit.serial}-{unit.seed}"
    rig = _rig_file(unit, folder)
    with registering(records_url, LabProfile(), "run") as registrar:
        registrar.preflight = references.check(
            registrar.store(), load_rig(rig).references, date.today(), None).metadata()
        session.run(procedure, rig, out, False, unit.seed, None, False,
                    confirm_prompts="auto", unit=session.UnitName(unit.serial, None))
    return out
