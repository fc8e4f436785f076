"""Shipped procedures (short variants) end to end through the ``acutrol`` table, the ``can``
logger and the ``espec``/``simserv`` chambers against ``aatest sim-server acutrol`` running in
its own process, compared with the same procedure on the in-process twin."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.testing.sim_process import SimServerProcess, free_port

SEED = 7
#: one f32 ulp of a CAN logger's volts between 2 and 4 V: twice the largest rounding of a sample
F32_VOLTS_V = 2.4e-7


@dataclass
class RigProcess:
    """``aatest sim-server acutrol --chamber KIND`` in its own process, CAN on udp_multicast."""

    chamber: str
    group: str
    #: the sensor model the simulator serves (``--sensor``; None: the reference sensor)
    sensor: str | None = None
    server: SimServerProcess | None = None
    chamber_port: int = 0

    def start(self) -> RigProcess:
        self.chamber_port = free_port()
        sensor = ("--sensor", self.sensor) if self.sensor else ()
        self.server = SimServerProcess("acutrol", args=(
            "--chamber", self.chamber, "--chamber-port", str(self.chamber_port), "--seed",
            str(SEED), "--can-interface", "udp_multicast", "--can-channel", self.group, *sensor))
        assert f"127.0.0.1:{self.server.start().port}" in self.server.banner
        return self

    @property
    def table_port(self) -> int:
        assert self.server is not None
        return self.server.port

    def kill(self) -> None:
        """``kill -9``: the OS closes the sockets, the controller's state is lost."""
        assert self.server is not None
        self.server.kill()

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()

    def rig_file(self, path: Path, table_port: int | None = None,
                 chamber_port: int | None = None, timeout_s: float = 5.0) -> Path:
        path.write_text(
            f"turntable: {{plugin: acutrol, port: {table_port or self.table_port}, "
            f"timeout_s: {timeout_s}}}\n"
            f"daq: {{plugin: can, interface: udp_multicast, channel: '{self.group}', "
            "response_timeout_s: 2.0, frame_timeout_s: 2.0}\n"
            f"chamber: {{plugin: {self.chamber}, port: {chamber_port or self.chamber_port}, "
            f"poll_interval_s: 1.0, timeout_s: {timeout_s}}}\n")
        return path


def multicast_group() -> str:
    return f"239.74.165.{10 + os.getpid() % 240}"


@pytest.fixture(params=["espec", "simserv"])
def rig_process(request: pytest.FixtureRequest) -> Iterator[RigProcess]:
    rig = RigProcess(request.param, multicast_group()).start()
    yield rig
    rig.stop()


def shipped(name: str, **replace: str) -> str:
    """A shipped procedure, shortened by regex replacements (pattern → text)."""
    text = (resources.files("aatest.procedures") / f"{name}.yaml").read_text()
    for pattern, new in replace.items():
        text, count = re.subn(pattern, new, text)
        assert count, pattern
    return text


def run(procedure: Path, out: Path, *extra: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["run", str(procedure), "--out", str(out), "--seed",
                                      str(SEED), "--no-progress", "--confirm-prompts", "auto",
                                      *extra])
    return result.exit_code, result.output


def analyses(tmp_path: Path, rig: RigProcess, text: str) -> tuple[dict, dict]:
    procedure = tmp_path / "procedure.yaml"
    procedure.write_text(text)
    rig_yaml = rig.rig_file(tmp_path / "rig.yaml")
    code, output = run(procedure, tmp_path / "wire", "--rig", str(rig_yaml))
    assert code == 0, output
    code, output = run(procedure, tmp_path / "twin")
    assert code == 0, output
    return tuple(json.loads((tmp_path / name / "results.json").read_text())["analysis"]
                 for name in ("wire", "twin"))  # type: ignore[return-value]


def test_temperature_steps_match_the_in_process_twin(rig_process: RigProcess,
                                                     tmp_path: Path) -> None:
    """Three set points (22, 28.5, 35 °C), 15 min soak, 2 s records: the chamber's soak ends within
    one poll (1 s) and the PV resolution of the twin's, so the sensor temperature — and with it
    bias and scale factor — differ only by a fraction of their uncertainty."""
    text = shipped("temperature-steps", **{
        # three set-points: the temperature analysis needs ≥ 3 spanning ≥ 5 °C
        r"setpoints_c: \[[^\]]*\]": "setpoints_c: [22, 28.5, 35]",
        r"samples: 131072": "samples: 4000", r"settle_s: 5": "settle_s: 2"})
    wire, twin = analyses(tmp_path, rig_process, text)
    k_wire, k_twin = (a["scale_factor"]["v_sz"] for a in (wire, twin))
    u = (k_wire["scale_u_v_per_dps2"] ** 2 + k_twin["scale_u_v_per_dps2"] ** 2) ** 0.5
    assert abs(k_wire["scale_v_per_dps2"] - k_twin["scale_v_per_dps2"]) <= 2 * u
    bias_wire, bias_twin = (a["temperature"]["v_sz"] for a in (wire, twin))
    # each set-point's static bias: its noise (≈2 mV rms over 4000 samples) bounds the mean's
    # scatter, 4σ/√n ≈ 1.3e-4 V
    for b_wire, b_twin, noise in zip(bias_wire["bias_v"], bias_twin["bias_v"],
                                     bias_twin["noise_rms_v"], strict=True):
        assert abs(b_wire - b_twin) <= 4 * noise / 4000 ** 0.5


def test_scale_factor_matches_the_in_process_twin(tmp_path: Path) -> None:
    """Without a chamber the call sequence is the in-process one and the log travels as
    17-digit decimals: the same numbers up to the CAN logger's f32 volts."""
    rig = RigProcess("espec", multicast_group()).start()
    try:
        text = shipped("scale-factor", **{r"samples: 140000": "samples: 20000",
                                          r"settle_s: 5": "settle_s: 2"})
        wire, twin = analyses(tmp_path, rig, text)
    finally:
        rig.stop()
    k_wire, k_twin = (a["scale_factor"]["v_sz"] for a in (wire, twin))
    # measured the Modbus path at 2e-9 relative (f32 volts on CAN); its 95 % interval is ±4e-5
    assert k_wire["scale_v_per_dps2"] == pytest.approx(k_twin["scale_v_per_dps2"], rel=1e-6)
    assert wire["sync"]["drift_ppm"] == pytest.approx(twin["sync"]["drift_ppm"], abs=1e-3)


def test_stepped_sine_matches_the_in_process_twin(tmp_path: Path) -> None:
    """A shortened sweep (1–8 Hz, 100 °/s²) through the ACUTROL oscillation demand: gain and
    phase of each point match the in-process twin within the points' stated uncertainty."""
    rig = RigProcess("espec", multicast_group()).start()
    try:
        text = shipped("stepped-sine-frequency-response", **{
            r"samples: 131072": "samples: 16384", r"settle_s: 5": "settle_s: 1",
            r"(?s)      frequencies:.*?skip_outside_envelope: true\n": (
                "      frequencies: {start_hz: 1, ratio: 2, stop_hz: 8, snap: coherent}\n"
                "      accelerations_dps2: [100]\n"),
            r"analysis: \[[^\]]*\]": "analysis: [sync, frf]"})
        wire, twin = analyses(tmp_path, rig, text)
    finally:
        rig.stop()
    points_wire, points_twin = wire["frf"]["v_sz"], twin["frf"]["v_sz"]
    assert len(points_wire) == len(points_twin) == 4
    for p_wire, p_twin in zip(points_wire, points_twin, strict=True):
        assert p_wire["gain_db"] == pytest.approx(p_twin["gain_db"], abs=0.05)
        assert p_wire["phase_deg"] == pytest.approx(p_twin["phase_deg"], abs=0.5)


def three_sensor_run(tmp_path: Path, text: str) -> tuple[dict, dict]:
    """``text`` on ``sim-server acutrol --sensor sr207-aamu`` (espec) and in-process."""
    rig = RigProcess("espec", multicast_group(), sensor="sr207-aamu").start()
    try:
        return analyses(tmp_path, rig, text)
    finally:
        rig.stop()


@pytest.mark.slow
def test_static_multi_position_matches_the_in_process_twin(tmp_path: Path) -> None:
    """The six ±1 g positions, original and pivoted, two repetitions of 2 s (shortened from
    three of 67.5 s): every sensor of the unit crosses the CAN logger, the pivot reaches the
    simulated unit through ``:XLOG:MOUNTING``, and bias and g-sensitivity of each sensor match
    the in-process twin."""
    text = shipped("static-multi-position", **{
        r"samples: 135000": "samples: 4000", r"settle_s: 5": "settle_s: 1",
        r"repetitions: 3": "repetitions: 2"})
    wire, twin = three_sensor_run(tmp_path, text)
    assert set(wire["bias"]) == set(twin["bias"]) == {"v_sz", "v_sy", "v_sx"}
    for channel, b_twin in twin["bias"].items():
        b_wire = wire["bias"][channel]
        # "within the noise": the noise gives K0 a Type A u of 20–55 µV and g-sensitivity a U of
        # 0.016–0.034 (°/s²)/g. The seeded twin draws the same samples in both runs, so they
        # differ only by the CAN logger's f32 volts: ≤ half an ulp (0.12 µV at 2–4 V) per sample,
        # so ≤ 0.24 µV on K0 and on (A+ − A−)/2 ≤ 0.24 µV / 0.004 V/(°/s²) = 6e-5 (°/s²)/g —
        # ≥ 80× inside the noise, and the pivoted mounting's shift (≥ 8 µV, 0.006 (°/s²)/g on
        # v_sz) would show
        assert b_twin["bias_u_v"] > 0
        assert abs(b_wire["bias_v"] - b_twin["bias_v"]) <= F32_VOLTS_V
        for mount in ("original", "pivoted"):
            m_wire, m_twin = b_wire["mountings"][mount], b_twin["mountings"][mount]
            assert abs(m_wire["bias_v"] - m_twin["bias_v"]) <= F32_VOLTS_V, mount
        assert b_twin["g_sensitivity_expanded_uncertainty_dps2_per_g"] > 1e-2
        assert b_wire["g_sensitivity_dps2_per_g"] == pytest.approx(
            b_twin["g_sensitivity_dps2_per_g"], abs=F32_VOLTS_V / 0.004)


@pytest.mark.slow
def test_pivoted_misalignment_matches_the_in_process_twin(tmp_path: Path) -> None:
    """Sets A/B (sequential) and C/D (sensors re-mounted) with one repetition of 4 s at the
    snapped ≈1 Hz (shortened from A–H, three of 65.5 s): the pivot and the re-mount reach the
    simulated unit, and each sensor's misalignment δ and cross ratios match the twin."""
    text = shipped("pivoted-misalignment", **{
        r"samples: 131072": "samples: 8192", r"settle_s: 5": "settle_s: 1",
        r"scenarios: \[[^\]]*\]": "scenarios: [A, B, C, D]",
        r"repetitions: 3": "repetitions: 1"})
    wire, twin = three_sensor_run(tmp_path, text)
    # "within the noise": each scenario's δ has a stated U ≈ 0.0095°. Both runs draw the same
    # seeded samples and differ only by f32 volts (relative 6e-8 on each fundamental): ≤ 1e-6°
    # on an angle, ≤ 1e-6 on a ratio — while sets A and B (pivot) differ by 0.2° in δ_e
    m_wire, m_twin = wire["misalignment"], twin["misalignment"]
    assert set(m_wire["sets"]) == set(m_twin["sets"]) == {"A", "B", "C", "D"}
    for set_name, sensors in m_twin["sets"].items():
        assert set(sensors) == {"SZ", "SY", "SX"}
        for sensor, s_twin in sensors.items():
            s_wire = m_wire["sets"][set_name][sensor]
            for key in ("delta_e_deg", "cross_ratio_x", "cross_ratio_y"):
                assert s_wire[key] == pytest.approx(s_twin[key], abs=1e-6), (set_name, key)
    assert set(m_wire["scenarios"]) == set(m_twin["scenarios"])
    for scenario, sensors in m_twin["scenarios"].items():
        for sensor, s_twin in sensors.items():
            s_wire = m_wire["scenarios"][scenario][sensor]
            assert s_twin["expanded_uncertainty"] > 1e-3
            assert abs(s_wire["delta_deg"] - s_twin["delta_deg"]) <= 1e-6


@pytest.mark.slow
def test_study_transfer_function_matches_the_in_process_twin(tmp_path: Path) -> None:
    """`study-transfer-function` (400 °/s², identified on 1, 2, 3, 5, 7 and 9 Hz) on its whole
    frequencies 1–9 Hz only, with records of 7 s instead of 65.5 s (14 000 samples, still whole
    cycles: c = 7·f), through the ACUTROL oscillation demand and the CAN logger: every FRF
    point, the chosen discrete model and its continuous equivalent match the in-process twin."""
    rig = RigProcess("espec", multicast_group()).start()
    try:
        text = shipped("study-transfer-function", **{
            r"samples: 131072": "samples: 14000", r"settle_s: 5": "settle_s: 1",
            r"frequencies:\n(?: {8,}.*\n)+":
                "frequencies: {include: [1, 2, 3, 4, 5, 6, 7, 8, 9], snap: coherent}\n"})
        wire, twin = analyses(tmp_path, rig, text)
    finally:
        rig.stop()
    # The runs draw the same seeded samples and differ only by the CAN logger's f32 volts:
    # ≤ 6e-8 relative on each fundamental, i.e. ≤ 5.2e-7 dB and 3.4e-6° per FRF point
    # (measured: 7e-15 dB, 5e-12°). The models are least-squares fits of these 9 points:
    # 1e-5 relative allows their parameters a condition number of ~100 (measured: 4e-11 on the
    # natural frequency, 3e-12 on the DC gain), 1e-3 % the fit (measured 3e-9 %), while a
    # changed structure or delay would show.
    points_wire, points_twin = wire["frf"]["v_sz"], twin["frf"]["v_sz"]
    assert len(points_wire) == len(points_twin) == 9
    for p_wire, p_twin in zip(points_wire, points_twin, strict=True):
        assert p_wire["gain_db"] == pytest.approx(p_twin["gain_db"], abs=1e-6)
        assert p_wire["phase_deg"] == pytest.approx(p_twin["phase_deg"], abs=1e-5)
    tf_wire, tf_twin = wire["transfer_function"]["v_sz"], twin["transfer_function"]["v_sz"]
    for key in ("n", "m", "delay_samples", "delay_source"):
        assert tf_wire[key] == tf_twin[key], key
    assert tf_wire["fit_pct"] == pytest.approx(tf_twin["fit_pct"], abs=1e-3)
    c_wire, c_twin = tf_wire["continuous"], tf_twin["continuous"]
    for key in ("natural_frequencies_hz", "damping"):
        assert c_wire[key] == pytest.approx(c_twin[key], rel=1e-5), key
    assert c_wire["dc_gain"] == pytest.approx(c_twin["dc_gain"], rel=1e-5)
