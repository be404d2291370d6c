"""Delta p against the size of the wall cell, the one mesh parameter the study's grid
convergence (Table 5's analogue) holds fixed.

    python results/ding-friction/wall_cell_size.py [--developing] [> wall_cell_size.txt]

Fully developed cross-sections, cases/two_fluid/ding_qs*.toml on their 16 x 32 mesh with
``numerics.first_cell_yplus`` changed (the wall ring's centre at that y+ of the gas flow; the
cases hold 30). Prints, for Q_s = 0.8 m3/h, the wall ring's thickness in solids diameters d_s
and Delta p over 2.4 m for the three frictional models under both solids wall laws (the
paper's modified condition, ``walls.law = "ding"``, and Schneiderbauer et al.'s 2012 condition),
with the parts of the force balance; then the modified Berzi model's Delta p at all five rates
for each wall cell (the shape of Delta p against the gas rate).  The interior refinement at a
fixed wall cell is the study's grid table.  ``--developing`` prints instead the modified Berzi
model's Delta p over the 2.4 m pipe marched from the paper's inlet (``numerics.mode =
"developing"``) at Q_s = 0.8 for y+ 30, 100 and 170 (about 40 s each).
"""

import tomllib
from pathlib import Path

import numpy as np

from eulag.two_fluid import problem_from_case, wall_ring_thickness
from tfm.section import solve_section

CASES = Path(__file__).resolve().parents[2] / "cases" / "two_fluid"
RATES = ("0.4", "0.6", "0.8", "1.0", "1.2")
MODELS = ("dartevelle", "srivastava-sundaresan", "berzi")
YPLUS = (30.0, 60.0, 100.0, 170.0)
MEASURED_QS08_KPA = 4.26


def load(rate):
    with open(CASES / f"ding_qs{rate}.toml", "rb") as fh:
        return tomllib.load(fh)


def thickness_in_grains(case, yplus):
    h = wall_ring_thickness(case, yplus)
    return h / case["solids"]["diameter"], h


def solve(rate, model, law, yplus, parts=False):
    case = load(rate)
    case["friction"]["model"] = model
    case.setdefault("walls", {})["law"] = law
    case["numerics"]["first_cell_yplus"] = yplus
    s, st, ok, c = solve_section(problem_from_case(case))
    if not ok:
        return None
    dp = st.G * case["pipe"]["length"] / 1e3
    if not parts:
        return dp
    # the wall forces per unit length, as kPa over the pipe (G A = gas wall + solids wall), split
    # between the wall cells under the deposit (alpha_s > alpha_min) and the others
    w, arc = s.sec.wall, s.sec.wall_arc
    under = c["a"][w] > case["friction"]["alpha_min"]
    to_kpa = case["pipe"]["length"] / s.Atot / 1e3
    gas, sol = s.hg * st.ug[w] * arc * to_kpa, s.hs * st.us[w] * arc * to_kpa
    return dp, {"gas under the deposit": gas[under].sum(), "gas elsewhere": gas[~under].sum(),
                "solids under the deposit": sol[under].sum(), "solids elsewhere": sol[~under].sum()}


def developing():
    import tempfile

    import xarray as xr

    import eulag

    text = (CASES / "ding_qs0.8.toml").read_text()
    print("modified Berzi, Q_s = 0.8, the pipe marched from the paper's inlet: Delta p over 2.4 m")
    with tempfile.TemporaryDirectory() as tmp:
        for yp in (30.0, 100.0, 170.0):
            t = text.replace("first_cell_yplus = 30.0", f"first_cell_yplus = {yp}")
            t = t.replace("[numerics]\n", '[numerics]\nmode = "developing"\n', 1)
            p = Path(tmp) / f"dev{yp:g}.toml"
            p.write_text(t.replace('name = "ding_qs0.8"', f'name = "dev{yp:g}"'))
            eulag.run(p, out=Path(tmp) / f"dev{yp:g}.nc")
            with xr.open_dataset(Path(tmp) / f"dev{yp:g}.nc") as ds:
                print(f"  y+ {yp:5.0f}: {float(ds['pressure_drop']) / 1e3:.3f} kPa", flush=True)


def solve_gas_alone(yplus):
    case = load("0.8")
    case["solids"]["mass_flow"] = 1e-4
    case["numerics"]["first_cell_yplus"] = yplus
    s, st, ok, _ = solve_section(problem_from_case(case))
    return st.G * case["pipe"]["length"] / 1e3 if ok else float("nan")


def main():
    import sys

    if "--developing" in sys.argv[1:]:
        developing()
        return
    base = load("0.8")
    print("Q_s = 0.8 m3/h (U_g 6.43 m/s, M_s 0.194 kg/s), 16 x 32 cells; measured 4.26 kPa")
    print(f"{'y+':>5} {'wall cell':>16} | " + " | ".join(f"{law:>32}" for law in ("ding", "schneiderbauer")))
    print(f"{'':>5} {'':>16} | " + " | ".join(f"{'D':>10} {'S':>10} {'B':>10}" for _ in range(2)))
    for yp in YPLUS:
        n, h = thickness_in_grains(base, yp)
        cells = []
        for law in ("ding", "schneiderbauer"):
            for m in MODELS:
                dp = solve("0.8", m, law, yp)
                cells.append("not conv." if dp is None else f"{dp:5.2f} {100 * (dp / MEASURED_QS08_KPA - 1):+4.0f}%")
        print(f"{yp:5.0f} {1e3 * h:6.3f} mm {n:4.2f} d_s | " + " | ".join(
            " ".join(f"{c:>10}" for c in cells[i:i + 3]) for i in (0, 3)), flush=True)
    print()
    print("the gas alone (solids mass flow 1e-4 kg/s), Q_s = 0.8 gas rate: Delta p [kPa] "
          + ", ".join(f"y+ {yp:g}: {solve_gas_alone(yp):.3f}" for yp in YPLUS))
    print()
    print("modified Berzi, walls.law = ding, Q_s = 0.8: the wall forces as kPa over the pipe")
    for yp in YPLUS:
        dp, parts = solve("0.8", "berzi", "ding", yp, parts=True)
        print(f"{yp:5.0f} Delta p {dp:5.2f}: " + ", ".join(f"{k} {v:.2f}" for k, v in parts.items()), flush=True)
    print()
    print("modified Berzi, walls.law = ding: Delta p [kPa] against Q_s [m3/h]")
    print(f"{'y+':>5} " + " ".join(f"{r:>7}" for r in RATES) + "   lowest at")
    for yp in YPLUS:
        dps = [solve(r, "berzi", "ding", yp) for r in RATES]
        low = RATES[int(np.nanargmin([np.nan if d is None else d for d in dps]))]
        print(f"{yp:5.0f} " + " ".join(f"{d:7.2f}" if d is not None else "   n.c." for d in dps) + f"   {low}",
              flush=True)
    print("wall cell thickness [d_s] per rate: " + "; ".join(
        f"y+ {yp:g}: " + ", ".join(f"{thickness_in_grains(load(r), yp)[0]:.2f}" for r in RATES) for yp in YPLUS))


if __name__ == "__main__":
    main()
