"""Wire protocols spoken between aatest and a rig, shared by both ends of each link.

A driver plugin and the twin's server that stands in for the hardware must agree on every
address, bit and byte; keeping that agreement in one neutral package lets both import it
without the twin depending on a plugin (or a plugin on the twin's servers).

- ``modbus_map``  the Modbus TCP register map of the two-axis turntable controller
  (``docs/modbus-register-map.md``): used by ``plugins.turntable.modbus`` and
  ``twin.servers.modbus_controller``
- ``can_frames``  the CAN (FD) frame layout of the on-table sensor logger
  (``docs/can-logger-frames.md``): used by ``plugins.daq.can`` and ``twin.servers.can_sim``
- ``can_bus``     opening a python-can bus and sending one frame, with failures as ``RigFault``

Depends only on ``aatest.engine`` (errors, logs) and third-party libraries.
"""
