"""Gas through a porous medium as a pressure field (McNamara & Flekkøy 2000; Strauß, McNamara &
Herrmann, eq. 5): ∂P′/∂t = (P0/(ηφ)) ∇·(κ(φ)∇P′) − (P0/φ) ∇·u on a structured tube grid.

Takes porosity and grain-velocity fields on the grid; knows nothing of grains.

- ``darcy.permeability``: Carman–Kozeny κ(φ) with a cap;
- ``darcy.solver``: :class:`TubeGrid` (cells of a circular tube on an nx × ny × ny grid) and
  :class:`DarcySolver` (finite volumes, θ-scheme, Crank–Nicolson by default, scipy.sparse).
"""

from .permeability import carman_kozeny, poiseuille_tube_permeability
from .solver import DarcySolver, TubeGrid

__all__ = ["carman_kozeny", "poiseuille_tube_permeability", "DarcySolver", "TubeGrid"]
