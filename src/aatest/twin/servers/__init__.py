"""The twin behind real protocols, for testing the real drivers without hardware.

- ``modbus_controller``  a turntable controller speaking the Modbus register map, backed by the twin
- ``modbus_server``      ``aatest sim-server modbus``: that controller on a TCP port
- ``can_sim``            the simulated CAN logger: DAQ samples as CAN FD frames on a bus
- ``line_server``        an asyncio TCP server for line-oriented ASCII instruments
- ``acutrol_server``     ``aatest sim-server acutrol``: an ACUTROL-class controller on the
  twin (``acutrol_parse``, ``acutrol_controller``), optionally with a chamber on that twin
- ``chamber_sim``        ESPEC and SIMSERV chambers on the twin (``sim-server espec|simserv``)
"""
