"""Lagrangian particle phase: parcels, forces, Langevin dispersion, collisions and sampling (numba).

- ``particles.track(mesh, gas, spec, physics, parcels=..., seed=..., pass_index=...)`` runs one
  Lagrangian pass through a converged ``rans.GasField`` and returns a :class:`Sample`
  (sources for the gas, cell statistics, wall impacts, parcel bookkeeping, standard errors).
- ``particles.forces``: drag, lift and torque correlations (one function per correlation).
- ``particles.fields``: the gas fields seen by a particle (interpolation, log-law wall cell).
- ``particles.kernel``: the compiled step (``make_tracker(PhysicsOptions(...))``).
- ``particles.stream``: a pass tracked window by window beside the gas march that feeds it
  (:class:`StreamedPass`; the numbers of ``track`` in the finished field).
"""

from .fields import FieldTable
from .kernel import PhysicsOptions, make_motion, make_tracker
from .tracking import ParticleSpec, Sample, TrackSettings, batch_plan, cell_stokes, track
from .stream import StreamedPass

__all__ = ["FieldTable", "PhysicsOptions", "make_motion", "make_tracker", "ParticleSpec", "Sample",
           "StreamedPass", "TrackSettings", "batch_plan", "cell_stokes", "track"]
