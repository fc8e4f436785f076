"""``aatest diagnose``: what the simulation gets wrong, why, a better model, and the gain.

Flow (docs/interfaces.md §4, issue 5)::

    read_dataset ─ replay (sync, commanded motion aligned on the table log)
      ─ nominal fit (bias, K, logger filter, ±1-sample alignment) ─ residual views
      ─ candidates (candidates/: linear by least squares, shape by bounded optimisation)
      ─ forward selection (held-out ΔBIC, materiality, physics vetoes) ─ findings
      ─ generic extensions for what remains (α², |α|, lines, trend, step) ─ unexplained
      ─ backward pass on the joint model (withdraw what it does not need, marginal evidence)
      ─ model_out (extended RigModel YAML) ─ JSON + report

Rules a user should know, because the data alone cannot decide them:

* **Nominal chain.** One clock, ideal sensor, bias and scale factor calibrated on the data,
  white noise — plus the logger's pre-sample filter when the data's model states one, or when
  the residual noise visibly rolls off like the rig's documented 100 Hz filter (docs/method.md
  §1.3); with white noise the replay that fits the signal better decides.
* **Converter.** The logger's converter is the one the data state (rig description, else the
  data's rig model, else the stated default ±10 V / 16 bit): a hysteresis dead band within one
  of its steps is not attributed to the sensor, and its q/√12 bounds the excess-noise floor.
* **Alignment.** Without ``fp_latch_s`` the sync pulse aligns the loggers to about one sample:
  the nominal model may shift the sensor by up to 1.5 samples (±½ for the edge estimate, one
  for the rule), and a delay, lead (jerk term) or dynamics whose lag is within that is never
  evidence by itself. With ``fp_latch_s`` (and sync edges) the alignment is resolved below one
  sample: no nuisance shift, and sub-sample delays and leads are evidence (docs/interfaces.md §4).
* **Unexplained.** Structure left after selection that the vocabulary cannot name is fitted
  with a generic extension and reported under ``unexplained`` with its kind and gain; a named
  effect that the joint model no longer needs is withdrawn (its candidate row says why).
* **Look-alikes.** Time-family effects (delay, jerk, dynamics) compete on held-out score; a
  jerk term that lags is refused (that is a delay), dynamics must show droop/peaking or
  frequency-dependent lag beyond a delay; ``amplitude_damping`` (the dynamics' damping
  varying with amplitude) is tested only on top of accepted dynamics, against hysteresis
  (which also lags more at small amplitude) on held-out score. Table effects are attributed
  to the table only when the table's own position log shows them.
* **Cross-axis vs misalignment.** In one mounting a tilt of the input axis by δ towards
  azimuth a and cross-axis ratios (rx, ry) = (tan δ·cos a, tan δ·sin a) give identical data
  (the cos δ change of the main response is absorbed by the calibrated scale factor), and the
  twin turns both with a 180° pivot. Diagnose therefore reports the measured quantity,
  ``cross_axis`` (ratio_x, ratio_y), and gives the equivalent ``misalignment`` angle and
  azimuth in the finding's ``look_alike`` key; the ``misalignment`` candidate row carries the
  same evidence with the reason.
* **Clock drift** comes from the sync edges and is a finding only beyond the rig's clock
  tolerance (``clock_tolerance_ppm`` in the data's metadata, default 20 ppm).
"""
