"""Dense phase: soft-sphere grains (DEM) in a tube, for the slug-conveying model of Strauß,
McNamara & Herrmann (plug conveying in a horizontal tube).

- ``dem.contacts``: Hooke + dashpot normal force from the restitution, tangential force the
  smaller of Coulomb and viscous, the same laws at the wall (numba);
- ``dem.engine``: grain state (structure of arrays), cell lists, contact forces, integrator;
- ``dem.feed``: the inlet feed (a relaxed random packing pushed in at constant speed);
- ``dem.transfer``: tent-function transfer between grains and the gas grid (eqs. 7–9).

Imports from the project: ``collisions.random`` only (counter-based random numbers).
"""

from .contacts import contact_time, damping_ratio, dashpot_coefficient, max_overlap
from .engine import FEED, FREE, GONE, CellGrid, ContactModel, Grains, dem_step
from .transfer import TentTransfer, node_volumes

__all__ = ["contact_time", "damping_ratio", "dashpot_coefficient", "max_overlap", "FREE", "FEED", "GONE",
           "CellGrid", "ContactModel", "Grains", "dem_step", "TentTransfer", "node_volumes"]
