"""The numbers the ablation READMEs quote for one run, from its dataset:

    python results/scenes-ablation/section_metrics.py RUN.nc [...]

The scene table's columns (``eulag.studies.scenes.scene_metrics``: pattern metrics with replica
error bars, strength, cells, wall impacts, -dp/dx) at the section x = 3.56 m, and the particle
distribution there: the share of the particle mass in the upper half (y > 0), the concentration
maximum over the section mean, and the upper / lower wall-impact ratio. Printed as JSON.
"""

import json
import sys

import numpy as np
import xarray as xr

from eulag import analysis as an
from eulag.studies.scenes import scene_metrics

X = 3.56


def particle_distribution(ds, x=X) -> dict:
    geo = an.polar_section(ds)
    c = an._field(ds, "particle_concentration", x)
    mass = c * geo.area
    rates = an.wall_impact_rates(ds, x)
    return {"particles_upper_half": float(mass[geo.y > 0].sum() / mass.sum()),
            "concentration_max_over_mean": float(c.max() / (mass.sum() / geo.area.sum())),
            "impacts_upper_over_lower": rates["upper"] / rates["lower"]}


def main():
    for path in sys.argv[1:]:
        ds = xr.open_dataset(path)
        out = {k: v for k, v in scene_metrics(ds, X).items() if k != "figures"}
        out.update(particle_distribution(ds))
        print(json.dumps({"dataset": path, **out}, indent=1, default=lambda v: float(v) if np.isscalar(v) else str(v)))


if __name__ == "__main__":
    main()
