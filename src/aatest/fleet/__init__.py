"""What a lab learns from its own history (docs/fleet.md).

Per unit and quantity, the drift from the as-found/as-left data and a recommended calibration
interval (:mod:`.interval`, Castrup's variables-data method); across units, individuals /
moving-range control charts per model and rig (:mod:`.control`); and which discrepancy effects
recur on one rig's units rather than on one unit (:mod:`.recurrence`). ``aatest fleet …``
(:mod:`.cli`) and the station's ``/fleet`` page render them (:mod:`.pages`).
"""
