"""Windowed numbers of a slug run continued from the filled tube (the long μ runs of README.md,
the runs of boundary-6bae946/):

    python results/strauss-filled/windows.py RUN.nc [...]

For each run: the regime numbers (``eulag.studies.strauss.classify_regime``) of every 2-s window
from the state's time (13.25 s), and over the run after its first 2 s (the state was made at
v_s = 1 m/s and μ = 0.5) the means with the standard deviation of the 2-s window means of Δp and the slug
statistics (``eulag.slug.summarize``). Printed, and written into extra_runs.json beside this
script under the run's name, with the case file of that name beside this script, or else the
run as a run of ``eulag study strauss`` (its record and the study's command are in the README
of the folder that holds it).
"""

import json
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from eulag.slug import summarize
from eulag.studies.strauss import classify_regime

START, WINDOW, SETTLE = 13.25, 2.0, 2.0
KEYS = ("pressure_drop_Pa", "grains_in_tube_window", "outflow_per_feed", "dense_share", "moving_share_all", "regime")
SLUG_KEYS = ("slug_velocity_m_s", "slug_grains", "slug_min_porosity", "slug_length_m", "slug_records")


def windows(path):
    ds = xr.open_dataset(path)
    t_end = float(ds.time.values[-1])
    rows = []
    for i in range(int(round((t_end - START) / WINDOW))):
        a, b = START + i * WINDOW, START + (i + 1) * WINDOW
        r = classify_regime(ds, a + 1e-9, b + 1e-9)
        rows.append({"window_s": [a, b], **{k: r[k] for k in KEYS}})
    r = classify_regime(ds, START + SETTLE + 1e-9)
    after = {"window_s": [START + SETTLE, t_end], **{k: r[k] for k in KEYS},
             "pressure_drop_Pa_window_std": float(np.std([w["pressure_drop_Pa"] for w in rows
                                                          if w["window_s"][0] >= START + SETTLE], ddof=1))}
    s = summarize(ds, t_min=START + SETTLE)
    after.update({k: s.get(k) for k in SLUG_KEYS})
    stem = Path(path).stem
    source = ({"case_file": f"{stem}.toml"} if Path(__file__).with_name(f"{stem}.toml").exists()
              else {"study_run": stem})
    return {**source, "time_last_s": t_end,
            "grains_in_tube_last": float(ds.grains_in_tube.values[-1]), "wall_time_s": float(ds.attrs["wall_time_s"]),
            "after_first_2s": after, "windows_2s": rows}


def main():
    out = Path(__file__).with_name("extra_runs.json")
    runs = json.loads(out.read_text())
    for path in sys.argv[1:]:
        runs[Path(path).stem] = w = windows(path)
        for row in w["windows_2s"]:
            print(Path(path).stem, row)
        print(Path(path).stem, "after the first 2 s:", w["after_first_2s"])
    out.write_text(json.dumps(runs, indent=1) + "\n")


if __name__ == "__main__":
    main()
