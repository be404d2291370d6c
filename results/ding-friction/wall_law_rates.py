"""The five gas rates of Ding et al.'s Table 1 under both solids wall laws: the paper's modified
condition (eqs. 24-26, ``walls.law = "ding"``, the shipped default) and Schneiderbauer,
Schellander & Pirker's (2012) condition before the modification (``walls.law = "schneiderbauer"``).

    python results/ding-friction/wall_law_rates.py [> wall_law_rates.txt]

Fully developed cross-sections on the cases' 16 x 32 mesh, cases/two_fluid/ding_qs*.toml with
[friction] model and [walls] law changed. Prints, per wall law, Delta p over 2.4 m for the three
frictional models at each rate, the model ordering, the rate of the lowest Delta p, and the
deposit (holdup, section share with alpha_s > 0.4, peak alpha_s) of the modified Berzi model.
The "ding" rows repeat the study's table (results/ding-friction/README.md).
"""

import tomllib
from pathlib import Path

import numpy as np

from eulag.two_fluid import problem_from_case
from tfm.section import solve_section

CASES = Path(__file__).resolve().parents[2] / "cases" / "two_fluid"
RATES = ("0.4", "0.6", "0.8", "1.0", "1.2")
MODELS = ("dartevelle", "srivastava-sundaresan", "berzi")
SHORT = {"dartevelle": "D", "srivastava-sundaresan": "S", "berzi": "B"}
MEASURED_QS08_KPA = 4.26


def solve(rate, model, law):
    with open(CASES / f"ding_qs{rate}.toml", "rb") as fh:
        case = tomllib.load(fh)
    case["friction"]["model"] = model
    case.setdefault("walls", {})["law"] = law
    pb = problem_from_case(case)
    s, st, ok, c = solve_section(pb)
    if not ok:
        raise SystemExit(f"Q_s = {rate}, {model}, walls.law = {law}: the section did not converge")
    a, A = c["a"], s.A
    return {"dp_kpa": st.G * case["pipe"]["length"] / 1e3,
            "holdup": float(np.sum(a * A) / s.Atot),
            "deposit_share": float(np.sum(A[a > 0.4]) / s.Atot),
            "peak_alpha": float(a.max())}


def main():
    print("# python results/ding-friction/wall_law_rates.py (16 x 32; Delta p over 2.4 m [kPa])")
    for law in ("ding", "schneiderbauer"):
        res = {(q, m): solve(q, m, law) for q in RATES for m in MODELS}
        print(f"\nwalls.law = {law!r}")
        print("| Q_s [m3/h] | Dartevelle | Srivastava-Sundaresan | modified Berzi | order (highest first) | spread "
              "| Berzi: holdup, deposit share (alpha_s > 0.4), peak alpha_s |")
        print("|---|---|---|---|---|---|---|")
        for q in RATES:
            dp = {m: res[q, m]["dp_kpa"] for m in MODELS}
            order = " > ".join(SHORT[m] for m in sorted(MODELS, key=lambda m: -dp[m]))
            spread = (max(dp.values()) - min(dp.values())) / min(dp.values())
            b = res[q, "berzi"]
            print(f"| {q} | {dp['dartevelle']:.2f} | {dp['srivastava-sundaresan']:.2f} | {dp['berzi']:.2f} | {order} "
                  f"| {100 * spread:.1f} % | {b['holdup']:.3f}, {b['deposit_share']:.2f}, {b['peak_alpha']:.3f} |")
        for m in MODELS:
            series = [res[q, m]["dp_kpa"] for q in RATES]
            low = RATES[int(np.argmin(series))]
            print(f"{m}: lowest Delta p at Q_s = {low}; "
                  f"Q_s = 0.8 against the measured {MEASURED_QS08_KPA} kPa: "
                  f"{100 * (res['0.8', m]['dp_kpa'] / MEASURED_QS08_KPA - 1):+.1f} %")


if __name__ == "__main__":
    main()
