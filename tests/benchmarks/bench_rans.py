"""Speed of the gas solver (prints figures; not a timed test).

    python tests/benchmarks/bench_rans.py

Developing 4 m pipe (D = 30.5 mm, U0 = 10 m/s) at 400 axial x 20 x 20 = 160,000 cells and at
400 x 20 x 40 = 320,000 cells, and the fully developed (periodic) mode on the same
cross-sections.  The first call of each configuration is reported apart (imports, numba
compile of locate(), caches); the figures after it are warm.  Each run also checks a physical
property (friction factor within 7 % of Colebrook), so a fast wrong answer does not pass.
"""

import os
import platform
import time

import numpy as np
from fluids.friction import Colebrook

from rans import GasProperties, PipeMesh, solve

RHO, MU, D, U = 1.205, 1.81e-5, 0.0305, 10.0
GAS = GasProperties(RHO, MU)


def run(mode, nx, nr, nt, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        m = PipeMesh.build(D, 4.0, mode, axial_cells=nx, radial_cells=nr, azimuthal_cells=nt,
                           bulk_velocity=U, density=RHO, viscosity=MU)
        f = solve(m, GAS, U, inlet_k=1.0)
        times.append(time.perf_counter() - t0)
    fd = f.friction_factor[-1] / Colebrook(RHO * U * D / MU, 0.0) - 1.0
    assert abs(fd) < 0.07 and f.converged
    cells = m.nx * m.nr * m.nt
    print(f"{mode:10s} {m.nx:4d} x {nr:3d} x {nt:3d} = {cells:7d} cells: first {times[0]:6.2f} s, "
          f"warm best {min(times[1:]):6.2f} s; iterations {f.iterations}, f_D/Colebrook - 1 = {fd:+.3f}, "
          f"wall y+ {f.wall_yplus.mean():.1f}")


def block_lu(nr=20, nt=40, solves=20000, factors=2000):
    """CPU time per solve and per factorisation of rans.linalg.BlockLU on an nr x nt section
    (a diagonally dominant periodic-tridiagonal ring block, random ring couplings); checks the
    solve against numpy's dense one."""
    from rans import linalg

    rng = np.random.default_rng(1)
    ring = 6.0 * np.eye(nt) - np.eye(nt, k=1) - np.eye(nt, k=-1)
    ring[0, -1] = ring[-1, 0] = -1.0
    D = np.repeat(ring[None], nr, axis=0)
    L, U = -rng.random((nr, nt)), -rng.random((nr, nt))
    lu = linalg.BlockLU(D, L, U)
    b = rng.random(nr * nt)
    A = np.zeros((nr * nt, nr * nt))
    for j in range(nr):
        A[j * nt:(j + 1) * nt, j * nt:(j + 1) * nt] = D[j]
        if j > 0:
            A[j * nt:(j + 1) * nt, (j - 1) * nt:j * nt] = np.diag(L[j])
        if j < nr - 1:
            A[j * nt:(j + 1) * nt, (j + 1) * nt:(j + 2) * nt] = np.diag(U[j])
    err = np.abs(lu.solve(b) - np.linalg.solve(A, b)).max() / np.abs(b).max()
    if not err < 1e-12:  # not an assert: the check must also run under python -O
        raise SystemExit(f"block LU solve differs from the dense solve by {err:.1e} of max |b|")
    t = time.process_time()
    for _ in range(solves):
        lu.solve(b)
    ts = (time.process_time() - t) / solves
    t = time.process_time()
    for _ in range(factors):
        linalg.BlockLU(D, L, U)
    tf = (time.process_time() - t) / factors
    print(f"block LU, {nr} x {nt} section: solve {ts * 1e6:.1f} us, factorisation {tf * 1e6:.0f} us "
          f"(CPU time per call; max |x - dense| / max |b| = {err:.1e})")


if __name__ == "__main__":
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    t0 = time.perf_counter()
    import rans.mesh as _m  # noqa: F401  (numba compile of locate() counted here)

    m = PipeMesh.build(D, 4.0, "periodic", radial_cells=4, azimuthal_cells=8)
    m.locate(0.1, 0.0, 0.0)
    print(f"cold start (import + compile/cache load of locate): {time.perf_counter() - t0:.2f} s")
    block_lu()
    for nr, nt in ((20, 20), (20, 40)):
        run("periodic", 1, nr, nt, repeats=4)
        run("developing", 400, nr, nt)
