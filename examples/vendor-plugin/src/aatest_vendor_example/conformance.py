"""The SR-1's conformance rig for aatest's kit (``pytest --aatest-plugin
turntable:acme-single-axis``). The table is simulated by aatest's twin, so the kit's twin rig
fits: the twin shared through the rig context, one fault (a servo trip). A driver for real
hardware would start its simulator here and declare the faults the simulator can produce."""

from __future__ import annotations

from aatest.testing.conformance import ConformanceRig, twin_rig


def rig() -> ConformanceRig:
    """The SR-1 with its datasheet options, on the twin."""
    return twin_rig({})
