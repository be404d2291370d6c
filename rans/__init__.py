"""Steady k-epsilon RANS gas solver on a pipe mesh (knows nothing about particles: it takes source arrays)."""

import os

# Single-threaded BLAS/LAPACK unless the user chose otherwise; it must be set before numpy and
# scipy load OpenBLAS.  The march inverts one dense nt x nt block per ring (rans/linalg.py);
# from nt ~ 80 OpenBLAS spreads each inversion over threads, which on oversubscribed cores wait
# on each other.  On 2 cores busy with two study runs and benchmarks, the 0.3 m
# single-phase march of a 40 x 80 section took 29.6 s with OpenBLAS's threads and 8.1 s with one,
# run back to back, to the same bits (one 40 x 80 block-LU factorisation, minutes apart: 113 ms
# and 7.2 ms); with only the two study runs beside it the two were alike (7-11 s, 8.8-9.7 ms,
# noisy).  The parallelism is numba's.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from jitcache import guard_numba_cache

guard_numba_cache()  # numba's on-disk cache: no stale kernels, no clashing writers (jitcache)

from .mesh import PipeMesh, locate_cell
from .solver import GasField, GasProperties, SolverDivergence, Sources, solve

__all__ = ["PipeMesh", "locate_cell", "GasField", "GasProperties", "SolverDivergence", "Sources", "solve"]
