"""Secondary-flow pattern columns shared by the scene and ablation studies: the reference
paper's pattern per scene and the noise-robust pattern metrics of a section
(:func:`eulag.analysis.pattern_metrics`, with the replicas' error bars)."""

from __future__ import annotations

from .report import Column

#: The reference paper's pattern per scene (its results section at x = 3.56 m, U0 = 10 m/s).
PAPER_PATTERN = {
    "a": (2, "2 fairly symmetric cells, ≈ 0.2 % of U0"),
    "b": (4, "4 cells, saddle near the centre"),
    "c": (2, "2 cells, up on the axis"),
    "d": (4, "4 cells, upper pair smaller"),
    "e": (2, "2 large cells, ≈ 1 % of U0"),
    "f": (2, "2 cells and an incipient upper cell"),
    "g": (2, "2 very clear cells, ≈ 2.5 % of U0, up on the axis"),
    "h": (4, "4 cells (two upper cells appear)"),
}
#: The main pair's sense where the paper states it: without inter-particle collisions (two-way
#: scenes) the pair turns up near the vertical axis and down near the side walls.
PAPER_SENSE = {"c": "up on the axis", "g": "up on the axis"}
#: the pattern metrics of a scene row (eulag.analysis.pattern_metrics on the mirror-symmetrised
#: section, error bars from the replicas of the final passes where the dataset has them)
PATTERN_KEYS = ("cells_sym", "index", "uy_pattern", "sense", "second", "interior", "coll")
PATTERN_COLUMNS = (Column("cells_sym", "cells (symmetrised; replica agreement)"),
                   Column("index", "sin2θ/cosθ index"), Column("uy_pattern", "u_y signs bottom→top"),
                   Column("sense", "main pair"), Column("second", "second pair [% of max ψ_s], centre y/R"),
                   Column("interior", "interior max [% U0]"),
                   Column("coll", "collision force x, y [N]"))


def pattern_columns(ds, x: float) -> dict:
    """The pattern cells of a scene row: symmetrised cell count (with the number of replicas
    that give the same count), the sin 2θ / cos θ index and the interior solenoidal maximum (± the
    replicas' standard error), the u_y sign pattern on the vertical diameter, the main pair's
    rotation sense, the second pair (the strongest cell turning against the main pair at any
    strength, in % of max ψ_s ± the replicas' standard error, and the y/R of its centre; "none")
    and the pipe integral of the collision force on the particles."""
    import math

    from eulag import analysis as an

    m = an.pattern_metrics(ds, x)
    reps = an.dataset_replicas(ds)
    rm = an.replica_pattern_metrics(reps, x, template=ds) if len(reps) > 1 else None

    def pm(key, fmt):
        text = format(m[key], fmt)
        if rm is not None and math.isfinite(rm["stderr"][key]):
            text += " ± " + format(rm["stderr"][key], ".1g")
        return text

    cells = str(m["count_symmetrised"])
    if rm is not None:
        # the replicas that give the dataset's own count (the most common replica count may differ)
        agree = sum(r["count_symmetrised"] == m["count_symmetrised"] for r in rm["replicas"])
        cells += f" ({agree}/{rm['n']} replicas)"
    coll = None
    if "particle_collision_force_total_x" in ds:
        coll = ", ".join(f"{float(ds[f'particle_collision_force_total_{c}']):+.2g} ± "
                         f"{float(ds[f'particle_collision_force_total_{c}_stderr']):.1g}" for c in "xy")
    if m["second_pair_fraction"] > 0.0:
        second = format(100.0 * m["second_pair_fraction"], ".3g")
        if rm is not None and math.isfinite(rm["stderr"]["second_pair_fraction"]):
            second += " ± " + format(100.0 * rm["stderr"]["second_pair_fraction"], ".2g")
        second += f", {m['second_pair_y']:+.2f}"
    else:
        second = "none"
    return {"cells_sym": cells, "index": pm("mode_index", ".2f"), "second": second,
            "uy_pattern": an.sign_text(m["uy_sign_pattern"]),
            "sense": m["main_pair_sense"] or "-", "interior": pm("interior_solenoidal_max", ".3g"), "coll": coll}


