"""The digital twin of the rig, shared by the simulated turntable, DAQ and chamber plugins.

Where each part lives (data flows top to bottom):

- ``model``       the rig/sensor model YAML: every contract effect by name (docs/interfaces.md §4)
- ``profiles``    commanded motion: hold, constant rate, sine synthesis, coordinated rates;
                  controller-side limit refusal
- ``table``       servo tracking, encoder ripple (1 and 2 cycles/°), motor band, motor-off
                  drift; the estimator (position estimate, rate/accel as its differences)
- ``kinematics``  two-axis frames, sensor seats, angular acceleration of the top, gravity,
                  orthogonality and wobble
- ``sensor``      the accelerometer: projection, cross-axis, g, hysteresis (vectorised play
                  operator), dynamics, saturation, resolution, cubic, temperature, jerk
- ``daq``         100 Hz pre-sample filter, white noise, slip ring, ADC
- ``clocks``      DAQ crystal (drift, lead/lag, jitter), sync pulse, trigger, freeze-pulse
                  registration one cycle late with ``fp_latch_s``
- ``chamber``     set-point steps, first-order sensor lag, stabilisation
- ``grid`` / ``fastmath``  uniform-grid phasors, fast trig and noise (the benchmark's budget)
- ``step_setup``  one step's record: what the World knows when the DAQ starts, what synthesis
                  returns (its truth computed on first access)
- ``rigid_motion`` the table top's motion on a grid: every term that draws nothing at random
- ``synthesis``   one step's DAQ log and truth, in generation blocks, all vectorised
- ``table_log``   one step's table controller log (estimates, sync pulse) and its truth
- ``step_synthesis`` / ``drawn_ahead``  a step's pieces on two threads, every number drawn
                  in the serial order (uniforms drawn ahead onto tapes)
- ``world``       the rig state in virtual lab time, shared by the simulated plugins
- ``session``     ``TwinSession``: the one World of a rig, shared through ``RigContext.resources``
- ``defaults``    the realistic rig: sensor error terms built from a datasheet, table, logger
- ``servers/``    the twin behind Modbus TCP and CAN (for the real drivers)
- ``api``         ``simulate_step``, ``simulate_dataset``, ``realistic_rig_model``,
                  ``nominal_rig_model``

The twin imports no sensor plugin: it gets the sensor's datasheet explicitly.
"""
