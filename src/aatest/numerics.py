"""Numbers with a meaning, named once: the 95 % normal factors and the guard against zero.

Two different 95 % factors are in use and must not be mixed up:

- :data:`Z95`, the two-sided 95 % quantile of the normal distribution (1.959963984540054):
  what a large-sample 95 % confidence interval's half-width is in standard uncertainties, so
  a ``ci95`` converts to a standard uncertainty by dividing by it.
- :data:`K95`, the coverage factor 1.96 that states an interval ``x ± k·u`` of about 95 %
  coverage for a normal distribution (JCGM 100 G.1.3, Table G.1, rounded as the GUM states
  it), for a plugin that states its intervals that way. aatest's own ``ci95`` intervals are
  built with :data:`Z95`, the factor ``ci_std`` divides by, so the standard uncertainty read
  back from an interval is the one it was built from (1.96 would return it ×1.00002).

:data:`TINY` stands in for zero before a division or a logarithm (a ratio of two sums of
squares that may be exactly zero, the log of a spectrum floor): far below any physical value,
so it never changes a result that has one, and the arithmetic never meets 0/0 or log 0.
A leaf module (it imports nothing), so every layer can read it.
"""

from __future__ import annotations

#: two-sided 95 % quantile of the standard normal distribution, Φ⁻¹(0.975)
Z95 = 1.959963984540054
#: coverage factor of a ≈95 % interval for a normal distribution, as the GUM rounds it
K95 = 1.96
#: the smallest value used in place of zero before a division or a logarithm
TINY = 1e-300
