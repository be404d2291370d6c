"""Steady k-epsilon RANS gas solver on a pipe mesh (knows nothing about particles: it takes source arrays)."""

from .mesh import PipeMesh, locate_cell
from .solver import GasField, GasProperties, SolverDivergence, Sources, solve

__all__ = ["PipeMesh", "locate_cell", "GasField", "GasProperties", "SolverDivergence", "Sources", "solve"]
