"""eulag: steady Euler-Lagrange RANS for turbulent gas-particle flow in horizontal pipes."""

__version__ = "0.1.0"
