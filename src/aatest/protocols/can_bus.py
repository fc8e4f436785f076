"""Opening a python-can bus and sending one frame, shared by the CAN logger's two peers.

The DAQ plugin (:mod:`aatest.plugins.daq.can`) and the simulated logger
(:mod:`aatest.twin.servers.can_sim`) open their buses and send frames the same way, so a bus
that cannot be opened, or a send that fails (bus-off, no buffer), is a
:class:`~aatest.engine.errors.RigFault` with the same one-line reason on either side.
"""

from __future__ import annotations

import logging
import socket
import sys
from typing import Any

import can
import numpy as np
import numpy.typing as npt

from aatest.engine.errors import RigFault
from aatest.engine.logs import SampledLog
from aatest.protocols import can_frames as cf

log = logging.getLogger("aatest.daq.can")
#: socket receive buffer asked for on udp_multicast buses (the kernel caps it at rmem_max)
UDP_RECEIVE_BUFFER_BYTES = 8 * 1024 * 1024
#: Linux socket options (linux/in.h, linux/in6.h) absent from Python's socket module before 3.12
IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)
IPV6_MULTICAST_ALL = getattr(socket, "IPV6_MULTICAST_ALL", 29)


def open_bus(interface: str, channel: str, fd: bool = True,
             bitrate: int | None = None) -> can.BusABC:
    """A python-can bus; errors become RigFault naming the interface and channel."""
    kwargs: dict[str, Any] = {"interface": interface, "channel": channel, "fd": fd}
    if bitrate is not None and interface not in ("virtual", "udp_multicast", "socketcan"):
        kwargs["bitrate"] = bitrate
    try:
        bus = can.Bus(**kwargs)
    except (can.CanError, OSError, ImportError, ValueError) as exc:
        raise RigFault(f"CAN {interface} {channel}: cannot open the bus ({exc})") from exc
    if interface == "udp_multicast":
        _only_own_group(bus, interface, channel)
        _enlarge_receive_buffer(bus)
    return bus


def _udp_socket(bus: can.BusABC) -> socket.socket | None:
    """The UDP socket under a python-can udp_multicast bus (python-can internals)."""
    return getattr(getattr(bus, "_multicast", None), "_socket", None)


def _only_own_group(bus: can.BusABC, interface: str, channel: str) -> None:
    """Deliver to this bus only the datagrams of its own multicast group.

    python-can binds the group's port on every address, and Linux then hands the socket every
    multicast datagram to that port of any group some socket on the host joined
    (``IP_MULTICAST_ALL`` defaults to 1): two runs on two groups would hear each other's
    commands and samples. With the option off, the kernel delivers only the groups this socket
    joined. Where the option does not exist (not Linux) the frames' session tag still keeps
    a run to its own logger (:mod:`aatest.protocols.can_frames`).
    """
    sock = _udp_socket(bus)
    if sock is None or sys.platform != "linux":
        return
    level, option = ((socket.IPPROTO_IPV6, IPV6_MULTICAST_ALL) if sock.family == socket.AF_INET6
                     else (socket.IPPROTO_IP, IP_MULTICAST_ALL))
    try:
        sock.setsockopt(level, option, 0)
    except OSError as exc:
        bus.shutdown()
        raise RigFault(f"CAN {interface} {channel}: cannot restrict the socket to its own "
                       f"multicast group ({exc})") from exc


def _enlarge_receive_buffer(bus: can.BusABC, size_bytes: int = UDP_RECEIVE_BUFFER_BYTES) -> None:
    """Give a udp_multicast bus a deep socket buffer (best effort, python-can internals).

    A UDP "bus" drops datagrams when the receiving thread is descheduled; the kernel buffer
    (capped by net.core.rmem_max) rides out such stalls. Loss is still detected, never silent.
    """
    sock = _udp_socket(bus)
    if sock is None:
        return
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size_bytes)
    except OSError as exc:
        log.debug("cannot enlarge the udp_multicast receive buffer: %s", exc)


def send(bus: can.BusABC, arbitration_id: int, payload: bytes, fd: bool, where: str) -> None:
    """Send one frame; a send failure (bus-off, no buffer) becomes RigFault."""
    msg = can.Message(arbitration_id=arbitration_id, data=payload, is_extended_id=False,
                      is_fd=fd and len(payload) > cf.CLASSIC_PAYLOAD_BYTES)
    try:
        bus.send(msg, timeout=1.0)
    except (can.CanError, OSError) as exc:
        raise RigFault(f"{where}: CAN send failed ({exc}); bus-off or disconnected") from exc


def volts_matrix(log_: SampledLog) -> npt.NDArray[np.float64]:
    """The sensor channels of a DAQ log as an (n, channels) array, in log order."""
    return np.column_stack([log_[c] for c in log_.sensor_channels()])
