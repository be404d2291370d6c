"""Gas fields for the particle tests: analytic (uniform, shear) and solved single-phase pipe flow."""

from functools import lru_cache

import numpy as np

from rans import GasField, GasProperties, PipeMesh, solve
from rans import kepsilon as ke

AIR = GasProperties(1.205, 1.81e-5)
D_PIPE = 0.0305  # m, Tsuji & Morikawa pipe
U0 = 10.0  # m/s


def uniform_field(mesh, ux=0.0, k=1.0, epsilon=1.0, gas=AIR):
    """GasField with uniform (ux, 0, 0), k [m2 s-2] and epsilon [m2 s-3] on ``mesh``."""
    shape = mesh.shape
    full = lambda v: np.full(shape, float(v))  # noqa: E731
    return GasField(mesh=mesh, gas=gas, bulk_velocity=float(ux) if ux else 1.0, ux=full(ux),
                    uy=full(0.0), uz=full(0.0), p=full(0.0), k=full(k), epsilon=full(epsilon),
                    pressure_gradient=np.zeros(mesh.nx), wall_shear=np.zeros((mesh.nx, mesh.nt)),
                    residuals=np.zeros(1), station_iterations=np.ones(mesh.nx, dtype=int),
                    converged=True)


@lru_cache(maxsize=None)
def periodic_pipe(radial_cells=20, azimuthal_cells=40, length=1.0):
    """Fully developed single-phase flow in the 30.5 mm pipe at U0 = 10 m/s: (mesh, GasField)."""
    mesh = PipeMesh.build(D_PIPE, length, mode="periodic", radial_cells=radial_cells,
                          azimuthal_cells=azimuthal_cells, bulk_velocity=U0)
    gas = solve(mesh, AIR, U0, 1.0, ke.inlet_epsilon(1.0, D_PIPE))
    assert gas.converged
    return mesh, gas


@lru_cache(maxsize=None)
def developing_pipe(axial_cells=100, radial_cells=20, azimuthal_cells=40, length=4.0):
    """Developing single-phase flow from a uniform inlet (U0, k = 1): (mesh, GasField)."""
    mesh = PipeMesh.build(D_PIPE, length, mode="developing", axial_cells=axial_cells,
                          radial_cells=radial_cells, azimuthal_cells=azimuthal_cells,
                          bulk_velocity=U0)
    gas = solve(mesh, AIR, U0, 1.0, ke.inlet_epsilon(1.0, D_PIPE))
    assert gas.converged
    return mesh, gas
