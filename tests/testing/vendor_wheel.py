"""A tiny vendor distribution (one DAQ plugin and its conformance rig), built as a wheel and
installed by pip into a directory of its own — the way a lab installs a vendor's package,
offline and without a build backend. ``defect`` breaks one rule of the contract on purpose."""

from __future__ import annotations

import base64
import hashlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

VERSION = "0.3.1"
MODULE = '''\
"""ACME USB logger: records aatest's twin (wraps the ``sim`` DAQ); its own layer can lose the
USB link ("dies")."""

import threading

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine import registry
from aatest.engine.errors import RigFault
from aatest.engine.logs import SampledLog
from aatest.testing.conformance import ConformanceRig, twin_daq_rig

DEFECT = {defect!r}
UNPLUGGED = threading.Event()


class AcmeLogger:
    simulated = True

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
        gain: float = Field(1.0, gt=0)

    def __init__(self, config, context):
        info = registry.load("daq", "sim")
        self._logger = info.target(registry.configure(info, {{}}), context)

    def channels(self):
        return self._logger.channels()

    def _plugged(self):
        if UNPLUGGED.is_set() and DEFECT != "swallows-faults":
            raise RigFault("ACME logger: no answer on USB")

    def start(self):
        self._plugged()
        self._logger.start()

    def start_logging(self, step):
        self._plugged()
        self._logger.start_logging(step)

    def stop_logging(self):
        self._plugged()
        log = self._logger.stop_logging()
        if DEFECT != "time-goes-back":
            return log
        time_s = log.time_s.copy()
        time_s[[100, 101]] = time_s[[101, 100]]
        return SampledLog(log.source, log.sample_rate_hz, time_s, log.channels, log.units)

    def close(self):
        pass


def rig() -> ConformanceRig:
    UNPLUGGED.clear()
    return twin_daq_rig({{}}, faults={{"dies": UNPLUGGED.set}}, recover=UNPLUGGED.clear)
'''


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}\n"


def build_wheel(where: Path, dist: str, defect: str | None, groups: dict[str, dict[str, str]],
                ) -> Path:
    """A pure-Python wheel of ``dist`` with module ``acme_logger`` and ``groups``' entry points."""
    stem = dist.replace("-", "_")
    info = f"{stem}-{VERSION}.dist-info"
    files = {
        "acme_logger.py": MODULE.format(defect=defect).encode(),
        f"{info}/METADATA": f"Metadata-Version: 2.1\nName: {dist}\nVersion: {VERSION}\n"
                            "Requires-Dist: aatest\n".encode(),
        f"{info}/WHEEL": b"Wheel-Version: 1.0\nGenerator: aatest-tests\nRoot-Is-Purelib: true\n"
                         b"Tag: py3-none-any\n",
        f"{info}/entry_points.txt": "".join(
            f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n"
            for group, eps in groups.items()).encode(),
    }
    record = "".join(_record_line(name, data) for name, data in files.items())
    wheel = where / f"{stem}-{VERSION}-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as archive:
        for name, data in files.items():
            archive.writestr(name, data)
        archive.writestr(f"{info}/RECORD", record + f"{info}/RECORD,,\n")
    return wheel


def pip_install(wheel: Path, target: Path) -> None:
    """``pip install --target`` offline (the wheel needs nothing that is not installed)."""
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--disable-pip-version-check",
                           "--no-deps", "--no-index", "--target", str(target), str(wheel)],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr


def env_with(target: Path) -> dict[str, str]:
    """This environment with ``target`` first on the import path (where pip installed)."""
    path = os.pathsep.join(p for p in (str(target), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}
