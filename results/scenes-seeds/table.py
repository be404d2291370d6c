"""The seed table of results/scenes-seeds/README.md: the pattern of each run at x = 3.56 m.

    python results/scenes-seeds/table.py "a, seed 1, 9707e30=RUN.nc" "b, seed 1, scenes=RUN.record.json" ...

Each argument is LABEL=PATH, PATH a run's dataset (the metrics are computed from it with
``eulag.studies.scenes.scene_metrics``, as the scene study does) or a run record
(``<run>.record.json``, whose ``metrics`` the scene study wrote from its dataset).  Prints one
markdown row per run: cell count on the mirror-symmetrised field with the replicas that agree,
the main pair's sense on the vertical axis, the four-cell index (sin 2θ against cos θ content
of the stream function, replica error), the strength (largest in-plane gas speed, % of U0),
the interior maximum (% of U0, replica error), −dp/dx at the station, the passes and the wall
time.
"""

import json
import sys
from pathlib import Path

import xarray as xr

from eulag.studies.scenes import scene_metrics

X = 3.56


def metrics(path: Path) -> tuple[dict, str, str]:
    if path.suffix == ".json":
        rec = json.loads(path.read_text())
        return rec["metrics"], str(rec.get("passes", "—")), f"{rec['time']:.0f}"
    ds = xr.open_dataset(path)
    m = scene_metrics(ds, X)
    passes = ds.attrs.get("coupling_passes", "—")
    wall = ds.attrs.get("time_total")
    return m, str(passes), (f"{float(wall):.0f}" if wall is not None else "—")


def main(argv):
    print("| run | cells (symmetrised; replicas) | main pair | four-cell index | strength [% U0] "
          "| interior maximum [% U0] | −dp/dx at 3.555 m [Pa/m] | passes | wall time [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for arg in argv:
        label, _, path = arg.rpartition("=")
        m, passes, wall = metrics(Path(path))
        print(f"| {label} | {m['cells_sym']} | {m['sense']} | {m['index']} | {m['strength']:.3g} "
              f"| {m['interior']} | {m['dpdx']:.2f} | {passes} | {wall} |")


if __name__ == "__main__":
    main(sys.argv[1:])
