"""The twin behind real protocols, for testing the real drivers without hardware.

- ``modbus_controller``  a turntable controller speaking the Modbus register map, backed by the twin
- ``modbus_server``      ``aatest sim-server modbus``: that controller on a TCP port
- ``can_sim``            the simulated CAN logger: DAQ samples as CAN FD frames on a bus
"""
