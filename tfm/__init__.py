"""Two-fluid (Euler–Euler) model of dense-phase gas–solid pipe flow.

Closures are pure functions, one per correlation (``drag``, ``kinetic``, ``friction``,
``wall``, ``inlet``), after Ding, Zhou, Tang, Xiao & Zhou (2024), Appl. Sci. 14, 2031.
Solvers: ``column`` (1-D vertical settled bed, a closure test) and ``section`` (fully
developed pipe cross-section).  The package may use ``rans`` (mesh, operators, linear
algebra, k-ε); it knows nothing of parcels.
"""

from .parameters import SolidsParameters

__all__ = ["SolidsParameters"]
