"""``aatest sim-server modbus``: the twin's controller served over Modbus TCP (pymodbus).

:class:`SimModbusServer` runs a pymodbus TCP server in a background thread with its own event
loop, answering from a :class:`~aatest.twin.servers.modbus_controller.SimController`. It
can also host the simulated CAN logger fed by the same twin
(:class:`aatest.twin.servers.can_sim.SimCanLogger`), so one process holds the whole simulated
rig: the table on Modbus, the sensors on CAN. Tests start it in-process on port 0 (the OS picks
a free port) with the ``virtual`` CAN bus; the CLI serves it with ``udp_multicast`` so a
separate ``aatest run`` process can reach both.

The controller's datastore is plugged in through pymodbus' ``ModbusServerContext`` hooks
(``async_getValues``/``async_setValues``), which every 3.x server calls per request.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
from typing import Any, cast

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.server import ModbusTcpServer

from aatest.twin.model import RigModel
from aatest.twin.servers.background import BackgroundServer, serve_until_interrupted
from aatest.twin.servers.modbus_controller import FaultInjection, SimController

log = logging.getLogger("aatest.sim.modbus")

#: environment overrides for the CAN side of ``aatest sim-server modbus``
CAN_INTERFACE_ENV = "AATEST_SIM_CAN_INTERFACE"
CAN_CHANNEL_ENV = "AATEST_SIM_CAN_CHANNEL"
DEFAULT_CAN_INTERFACE = "udp_multicast"
DEFAULT_CAN_CHANNEL = "239.74.163.2"
_FC_HOLDING = (3, 6, 16, 22, 23)


class _ControllerContext(ModbusServerContext):
    """Routes every holding-register request of any unit id to one controller."""

    def __init__(self, controller: SimController, release: asyncio.Event) -> None:
        # deliberately no super().__init__: no pymodbus datastore, the controller is the store
        self.controller = controller
        self.old_simulator = True
        self.simdevices: list[Any] = []
        self._release = release

    def device_ids(self) -> list[int]:
        return [0]

    async def _gate(self) -> bool:
        """Apply injected delays/hangs; ``False`` when the controller must not answer."""
        faults = self.controller.faults
        if faults.response_delay_s:
            await asyncio.sleep(faults.response_delay_s)
        if self.controller.hanging:
            with contextlib.suppress(TimeoutError):  # the hang simply ends after hang_s
                await asyncio.wait_for(self._release.wait(), faults.hang_s)
            return False
        return True

    # pymodbus calls its datastore methods by these camelCase names (the overridden API)
    async def async_getValues(self, device_id: int, func_code: int, address: int,  # noqa: N802
                              count: int = 1) -> list[int] | ExcCodes:
        if func_code not in _FC_HOLDING:
            return ExcCodes.ILLEGAL_FUNCTION
        if not await self._gate():
            return ExcCodes.DEVICE_FAILURE
        values = self.controller.read(address, count)
        return ExcCodes.ILLEGAL_ADDRESS if values is None else values

    async def async_setValues(self, device_id: int, func_code: int, address: int,  # noqa: N802
                              values: Any) -> ExcCodes | None:
        if func_code not in _FC_HOLDING:
            return ExcCodes.ILLEGAL_FUNCTION
        if not await self._gate():
            return ExcCodes.DEVICE_FAILURE
        ok = self.controller.write(address, [int(v) for v in values])
        return None if ok else ExcCodes.ILLEGAL_ADDRESS


class SimModbusServer(BackgroundServer):
    """A simulated controller served on ``host:port`` from a background thread.

    Parameters
    ----------
    host, port
        Where to listen; port 0 lets the OS choose (read :attr:`port` after :meth:`start`).
    seed
        Seed of the twin.
    model
        Twin model; default the realistic rig with the reference sensor.
    faults
        Fault injection for tests.
    lifetime_s
        Stop by itself after this many wall seconds (``None``: run until :meth:`stop`).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, seed: int = 0,
                 model: RigModel | None = None, faults: FaultInjection | None = None,
                 lifetime_s: float | None = None) -> None:
        if model is None:
            from aatest.twin.defaults import realistic_rig_model

            model = realistic_rig_model()
        super().__init__("Modbus", host, port, lifetime_s)
        self.controller = SimController(model, seed, faults)
        self._server: ModbusTcpServer | None = None
        self._release: asyncio.Event | None = None
        self._closing: asyncio.Future[None] | None = None
        self._extras: list[Any] = []

    def attach(self, part: Any) -> None:
        """Stop ``part`` (e.g. the simulated CAN logger) together with the server."""
        self._extras.append(part)

    async def _serve(self) -> None:
        self._release = asyncio.Event()
        context = _ControllerContext(self.controller, self._release)
        self._server = ModbusTcpServer(context, address=(self.host, self.port))
        task = asyncio.create_task(self._server.serve_forever())
        while self._server.transport is None and not task.done():
            await asyncio.sleep(0.005)
        if task.done():
            task.result()
        # pymodbus keeps the asyncio.Server of create_server() in `transport` (typed loosely)
        listening = cast("asyncio.Server", self._server.transport)
        self._listening(listening.sockets[0].getsockname()[1])
        await task

    def _end(self) -> None:
        self._closing = asyncio.ensure_future(self._shutdown())

    async def _shutdown(self) -> None:
        if self._release is not None:
            self._release.set()
        if self._server is not None:
            await self._server.shutdown()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Shut the server (and attached parts) down; idempotent."""
        for part in self._extras:
            part.stop()
        super().stop(timeout_s)


def serve_forever(host: str, port: int, seed: int, *, can_interface: str | None = None,
                  can_channel: str | None = None, sensor: str | None = None) -> None:
    """Serve the simulated table on Modbus TCP and the simulated CAN logger until Ctrl-C.

    The CAN side uses ``can_interface``/``can_channel``, else the environment variables
    ``AATEST_SIM_CAN_INTERFACE``/``AATEST_SIM_CAN_CHANNEL``, else ``udp_multicast`` on group
    239.74.163.2 (needs python-can's ``msgpack`` extra); ``none`` serves the table only. The
    twin carries the sensors of the sensor plugin ``sensor`` (:func:`sensor_rig_model`: one
    channel per datasheet channel, as the in-process twin builds them; None: the reference
    sensor), and the banner names the channels the CAN logger serves.
    """
    from aatest.twin.servers.sensor_models import sensor_rig_model

    interface = can_interface or os.environ.get(CAN_INTERFACE_ENV, DEFAULT_CAN_INTERFACE)
    channel = can_channel or os.environ.get(CAN_CHANNEL_ENV, DEFAULT_CAN_CHANNEL)
    server = SimModbusServer(host, port, seed, model=sensor_rig_model(sensor))
    extras = []
    can = "CAN none"
    if interface != "none":
        from aatest.twin.servers.can_sim import SimCanLogger

        extras.append(SimCanLogger(server.controller, interface, channel).start())
        channels = ",".join(s.channel for s in server.controller.world.model.sensors)
        can = f"CAN {interface} {channel} (sensors {channels})"
    serve_until_interrupted([server], f"aatest simulated controller: Modbus TCP {host}:{{0}}, "
                                      f"{can} (Ctrl-C stops)", extras)
