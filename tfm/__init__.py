"""Two-fluid (Euler–Euler) model of dense-phase gas–solid pipe flow.

Closures are pure functions, one per correlation (``drag``, ``kinetic``, ``friction``,
``wall``, ``inlet``), after Ding, Zhou, Tang, Xiao & Zhou (2024), "Influence of Frictional
Stress Models on Simulation Results of High-Pressure Dense-Phase Pneumatic Conveying in
Horizontal Pipe", Appl. Sci. 14, 2031, https://doi.org/10.3390/app14052031.
Solvers: ``column`` (1-D vertical bed settling to rest, a closure test) and ``section``
(fully developed pipe cross-section).  The package uses ``rans`` (mesh, operators, k-ε
constants and wall functions) and knows nothing of parcels.

Readings of the paper (each stated in the function it concerns)
----------------------------------------------------------------
* β is one convention: force per mixture volume per unit slip (tested against Ergun's
  packed-bed Δp and single-particle terminal velocities).
* McKeen's scale factor C is not given: 1 (Gibilaro's law) by default, a case key.
* Dartevelle's p_f and μ_f are used as printed (eqs. 13–14).
* Srivastava–Sundaresan: Fr = 0.05 Pa, r = 2, s = 5; p_c continued along its tangent above
  α_max − 0.01; p_f = 0 in strong dilation; p_f/p_c ≤ (n/(n−1))^(n−1) so μ_f ≥ 0.
* Modified Berzi: f0 = a (α_s − α_min)/(α_max − α_s) (Berzi, di Prisco & Vescovi 2011),
  k_n/d_s = 4.5 MPa (Fig. 7's ordering holds for 3–6.5 MPa).
* Schneiderbauer wall (eq. 25): √(2π) μ0², and −q_w is the flux into the solids.

Inputs the paper leaves out (Table 1 with eqs. 22–23; tests/test_tfm_closures.py)
--------------------------------------------------------------------------------
D = 10 mm (U_g's slope against Q_s gives 9.2 mm at line pressure), ρ_s = 1650 kg/m³
(ρ_s D² = 0.1655 kg/m in the Q_s = 0.8 row), d_s = 160 µm (Hinkle inverted: 159 µm),
nitrogen 32.7 kg/m³ and 1.78·10⁻⁵ Pa s, Δp over the 2.4 m pipe.
"""

from .parameters import SolidsParameters

__all__ = ["SolidsParameters"]
