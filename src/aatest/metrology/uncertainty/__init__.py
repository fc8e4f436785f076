"""The uncertainty stage: GUM budgets of every certified result, decided by the engine.

Runs after the analyses, before the verdicts and the report; reads the typed results
(:class:`aatest.results.RunResults`) by attribute and writes each certified result's
expanded uncertainty, coverage factor and probability, and budget into them
(:class:`aatest.results.base.Certified`). Reports only render what is written here.

- ``gum``         GUM (JCGM 100) propagation of a measurement model; a JCGM 101 Monte Carlo check
- ``measurands``  measurement models of the static results: scale factor, bias, g-sensitivity,
                  temperature coefficients; the rig's stated accuracies (``RigConstants``)
- ``dynamic``     measurement models of FRF gain/phase points and pivoted misalignment angles
- ``statistics``  finite numbers, 95 % intervals and the Type A of a mean, for the budgets
- ``budgets``     the stage itself: :func:`apply_uncertainty`
"""

from aatest.metrology.uncertainty.budgets import apply_uncertainty
from aatest.metrology.uncertainty.measurands import RigConstants

__all__ = ["RigConstants", "apply_uncertainty"]
