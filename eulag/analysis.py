"""Analysis of eulag datasets (DESIGN.md, "Dataset schema"): pure numpy/xarray functions.

Everything here reads a dataset only (never the solvers). The cross-section is taken from
the auxiliary coordinates ``y(r, theta)``, ``z(r, theta)`` and ``cell_area(r, theta)``:
ring radii and sector angles follow from y and z, ring edges from cell_area (or from the
``r_edge`` / ``theta_edge`` coordinates when the dataset has them). The stream-function
and profile functions need the polar (r, theta) layout and say so if it is absent.

Conventions: x along the axis, y up, z horizontal, right-handed; a section is drawn as
seen looking downstream, z to the right and y up; theta is measured from +z towards +y.
SI units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import xarray as xr

__all__ = [
    "PolarSection", "polar_section", "check_station", "section", "bulk_velocity",
    "secondary_flow_strength", "in_plane_velocity", "vorticity", "stream_function",
    "recirculation_cells", "count_cells", "gas_maximum_half", "wall_impact_rates",
    "vertical_profile", "section_mean", "pressure_drop_summary", "attr",
]

TWO_PI = 2.0 * np.pi


# ---------------------------------------------------------------------------
# attributes and geometry
# ---------------------------------------------------------------------------

def attr(ds: xr.Dataset, key: str, default: Any = None) -> Any:
    """Global attribute ``key`` (flattened case keys such as ``"gas.bulk_velocity"``) as a
    plain Python value (numpy scalars unwrapped, 1-element arrays kept as arrays)."""
    value = ds.attrs.get(key, default)
    if isinstance(value, np.generic):
        return value.item()
    return value


def bulk_velocity(ds: xr.Dataset) -> float:
    """Gas bulk velocity U_b [m s-1] from the attribute ``gas.bulk_velocity``.

    Falls back to the area-weighted section mean of ``gas_ux`` at the last station when the
    attribute is absent.
    """
    value = attr(ds, "gas.bulk_velocity")
    if value is not None:
        return float(value)
    if "gas_ux" not in ds:
        raise ValueError("the dataset has neither the attribute gas.bulk_velocity nor gas_ux")
    last = float(ds["x"].values[-1]) if "x" in ds.dims else None
    return section_mean(ds, "gas_ux", last)


@dataclass(frozen=True)
class PolarSection:
    """Geometry of a polar (r, theta) cross-section, derived from a dataset.

    r (nr,) ring centre radii [m]; r_edges (nr+1,) ring faces, r_edges[0] = 0, r_edges[-1] = R
    [m]; theta (nt,) sector mid-angles in [0, 2 pi) [rad]; theta_edges (nt+1,) sector faces
    [rad] (theta_edges[0] <= theta[0], increasing); area (nr, nt) cell areas [m2]; y, z
    (nr, nt) cell centres [m].
    """

    r: np.ndarray
    r_edges: np.ndarray
    theta: np.ndarray
    theta_edges: np.ndarray
    area: np.ndarray
    y: np.ndarray
    z: np.ndarray

    @property
    def radius(self) -> float:
        """Pipe radius R [m]."""
        return float(self.r_edges[-1])

    @property
    def nr(self) -> int:
        return self.r.size

    @property
    def nt(self) -> int:
        return self.theta.size

    @property
    def dtheta(self) -> np.ndarray:
        """Sector widths (nt,) [rad]."""
        return np.diff(self.theta_edges)


def ring_edges_from_area(cell_area) -> np.ndarray:
    """Ring faces r_0 = 0 < r_1 < ... < r_nr = R [m] from the cell areas (nr, nt) [m2].

    The cells of ring j together cover the annulus pi (r_{j+1}^2 - r_j^2), so
    r_{j+1} = sqrt(sum_{i <= j} A_i / pi) with A_i the summed cell area of ring i.
    """
    ring_area = np.asarray(cell_area, dtype=float).sum(axis=1)
    return np.sqrt(np.concatenate([[0.0], np.cumsum(ring_area)]) / np.pi)


def polar_section(ds: xr.Dataset) -> PolarSection:
    """The polar cross-section geometry of ``ds`` (see :class:`PolarSection`).

    Radii and angles come from the auxiliary coordinates y, z (r = hypot(y, z),
    theta = atan2(y, z)); ring edges from ``r_edge`` if present, else from cell_area
    (:func:`ring_edges_from_area`); sector edges from ``theta_edge`` if present, else half
    way between neighbouring sector mid-angles.
    """
    for name in ("y", "z", "cell_area"):
        if name not in ds.variables:
            raise ValueError(f"the dataset has no '{name}' coordinate; a cross-section needs y, z "
                             "and cell_area")
    if ds["y"].dims != ("r", "theta"):
        raise ValueError(f"y has dims {ds['y'].dims}; this analysis needs a polar (r, theta) "
                         "cross-section")
    y = np.asarray(ds["y"].values, dtype=float)
    z = np.asarray(ds["z"].values, dtype=float)
    area = np.asarray(ds["cell_area"].transpose("r", "theta").values, dtype=float)
    r = np.hypot(y, z).mean(axis=1)
    theta = np.mod(np.arctan2(y[-1], z[-1]), TWO_PI)  # outermost ring: well away from the axis
    if "r_edge" in ds.variables and ds["r_edge"].size == r.size + 1:
        r_edges = np.asarray(ds["r_edge"].values, dtype=float)
    else:
        r_edges = ring_edges_from_area(area)
    if "theta_edge" in ds.variables and ds["theta_edge"].size == theta.size + 1:
        theta_edges = np.asarray(ds["theta_edge"].values, dtype=float)
    else:
        gaps = np.diff(np.concatenate([theta, [theta[0] + TWO_PI]]))
        upper = theta + 0.5 * gaps
        theta_edges = np.concatenate([[upper[-1] - TWO_PI], upper])
    return PolarSection(r=r, r_edges=r_edges, theta=theta, theta_edges=theta_edges, area=area,
                        y=y, z=z)


def _pipe_length(ds: xr.Dataset) -> float | None:
    value = attr(ds, "pipe.length")
    if value is not None:
        return float(value)
    if "x_edge" in ds.variables:
        return float(np.max(ds["x_edge"].values))
    return None


def check_station(ds: xr.Dataset, x: float | None) -> None:
    """Raise ValueError if the axial position ``x`` [m] lies outside the pipe [0, L].

    L is the attribute ``pipe.length`` (else the last ``x_edge``); periodic (single-station)
    datasets accept any x within the pipe.
    """
    if x is None:
        return
    if not np.isfinite(x):
        raise ValueError(f"x = {x}: not a number; allowed: a position within the pipe")
    length = _pipe_length(ds)
    if length is None:
        xs = np.atleast_1d(ds["x"].values) if "x" in ds.variables else np.array([x])
        lo, hi = float(xs.min()), float(xs.max())
    else:
        lo, hi = 0.0, length
    tol = 1e-9 * max(abs(hi), 1.0)
    if x < lo - tol or x > hi + tol:
        raise ValueError(f"x = {x:g} m is outside the pipe; allowed: {lo:g} <= x <= {hi:g} m")


def section(ds: xr.Dataset, x: float | None = None) -> xr.Dataset:
    """The dataset at the axial station nearest to ``x`` [m] (the x dimension dropped).

    ``x=None`` takes the last station (the outlet; the only one in a periodic dataset).
    A dataset without an x dimension is returned unchanged. Raises ValueError if x lies
    outside the pipe (see :func:`check_station`).
    """
    if "x" not in ds.dims:
        return ds
    check_station(ds, x)
    if x is None or ds.sizes["x"] == 1:
        return ds.isel(x=-1)
    return ds.sel(x=x, method="nearest")


def _field(ds: xr.Dataset, var, x) -> np.ndarray:
    """Values (nr, nt) of a cell variable (name or array) at the station nearest x."""
    if isinstance(var, str):
        if var not in ds:
            raise KeyError(f"the dataset has no variable '{var}'")
        sec = section(ds, x)[var]
        return np.asarray(sec.transpose("r", "theta").values, dtype=float)
    return np.asarray(var, dtype=float)


# ---------------------------------------------------------------------------
# secondary flow
# ---------------------------------------------------------------------------

def in_plane_velocity(ds: xr.Dataset, x: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Polar components (u_r, u_theta), each (nr, nt) [m s-1], of the gas in-plane velocity.

    u_r = u_y sin(theta) + u_z cos(theta) (outward), u_theta = u_y cos(theta) - u_z sin(theta)
    (towards increasing theta, i.e. counter-clockwise looking downstream).
    """
    geo = polar_section(ds)
    uy, uz = _field(ds, "gas_uy", x), _field(ds, "gas_uz", x)
    s, c = np.sin(geo.theta), np.cos(geo.theta)
    return uy * s + uz * c, uy * c - uz * s


def secondary_flow_strength(ds: xr.Dataset, x: float | None = None) -> float:
    """Largest in-plane gas speed max sqrt(u_y^2 + u_z^2) over the section at x, in % of
    the bulk velocity ``gas.bulk_velocity`` [%]."""
    uy, uz = _field(ds, "gas_uy", x), _field(ds, "gas_uz", x)
    speed = np.hypot(uy, uz)
    if not np.any(np.isfinite(speed)):
        return float("nan")
    return 100.0 * float(np.nanmax(speed)) / bulk_velocity(ds)


def vorticity(ds: xr.Dataset, x: float | None = None) -> np.ndarray:
    """Cell-mean in-plane vorticity omega = du_y/dz - du_z/dy, (nr, nt) [s-1].

    Positive omega turns counter-clockwise as seen looking downstream (z right, y up); it is
    minus the axial vorticity component omega_x. Method: Stokes' theorem per cell, omega =
    (circulation around the cell) / (cell area), with the face velocities interpolated
    linearly (Cartesian components) between neighbouring cell centres and u = 0 on the wall
    (no slip); the axis faces of the innermost wedges have zero length.
    """
    geo = polar_section(ds)
    uy, uz = _field(ds, "gas_uy", x), _field(ds, "gas_uz", x)
    re, r, te = geo.r_edges, geo.r, geo.theta_edges
    nt = geo.nt

    # u_theta at the radial faces r_edges[1..nr] along each sector mid-ray
    w = ((re[1:-1] - r[:-1]) / (r[1:] - r[:-1]))[:, None]
    uy_f = np.vstack([(1 - w) * uy[:-1] + w * uy[1:], np.zeros((1, nt))])
    uz_f = np.vstack([(1 - w) * uz[:-1] + w * uz[1:], np.zeros((1, nt))])
    ut_face = uy_f * np.cos(geo.theta) - uz_f * np.sin(geo.theta)          # (nr, nt): outer faces
    ut_inner = np.vstack([np.zeros((1, nt)), ut_face[:-1]])               # inner faces
    dth = geo.dtheta[None, :]
    circulation = ut_face * re[1:, None] * dth - ut_inner * re[:-1, None] * dth

    # u_r on the sector faces theta_edges[k+1] (between sectors k and k+1, periodic)
    t_face = te[1:]
    uy_s = 0.5 * (uy + np.roll(uy, -1, axis=1))
    uz_s = 0.5 * (uz + np.roll(uz, -1, axis=1))
    ur_face = uy_s * np.sin(t_face) + uz_s * np.cos(t_face)               # face k+1/2
    dr = np.diff(re)[:, None]
    # counter-clockwise: outward along the lower face (k-1/2), inward along the upper (k+1/2)
    circulation += np.roll(ur_face, 1, axis=1) * dr - ur_face * dr
    return circulation / geo.area


def _poisson_matrix(geo: PolarSection) -> sp.csr_matrix:
    """Finite-volume Laplacian (integrated over each cell, [m0]) with psi = 0 on the wall.

    Two-point fluxes between neighbouring centres (orthogonal polar grid): radial faces
    r_{j+1} dtheta / (r_{j+1} - r_j) (centre distance), sector faces dr / (r_j dtheta_face);
    the innermost wedges meet at the axis through zero-length faces and couple through their
    sector faces only; theta is periodic.
    """
    nr, nt = geo.nr, geo.nt
    re, r = geo.r_edges, geo.r
    idx = np.arange(nr * nt).reshape(nr, nt)
    rows, cols, vals = [], [], []

    def add(i, j, c):
        rows.extend([i, i, j, j])
        cols.extend([i, j, j, i])
        vals.extend([-c, c, -c, c])

    dth = geo.dtheta
    # radial faces between rings j and j+1
    for j in range(nr - 1):
        c = re[j + 1] * dth / (r[j + 1] - r[j])
        for k in range(nt):
            add(idx[j, k], idx[j + 1, k], c[k])
    # sector faces (periodic)
    gap = np.diff(np.concatenate([geo.theta, [geo.theta[0] + TWO_PI]]))  # centre to next centre
    for j in range(nr):
        c = (re[j + 1] - re[j]) / (r[j] * gap)
        for k in range(nt):
            add(idx[j, k], idx[j, (k + 1) % nt], c[k])
    # wall faces: psi_wall = 0
    cw = re[-1] * dth / (re[-1] - r[-1])
    for k in range(nt):
        rows.append(idx[-1, k])
        cols.append(idx[-1, k])
        vals.append(-cw[k])
    n = nr * nt
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def stream_function(ds: xr.Dataset, x: float | None = None) -> np.ndarray:
    """Stream function psi (nr, nt) [m2 s-1] of the gas in-plane flow at the section x.

    Convention (looking downstream, z right, y up): u_z = d psi/dy, u_y = -d psi/dz, so in
    polar form u_r = (1/r) d psi/d theta, u_theta = -d psi/dr; positive psi marks a cell
    turning counter-clockwise, negative psi a clockwise one. psi = 0 on the wall.

    Method: the in-plane velocity of a developing pipe is not divergence-free (cross-section
    continuity holds -du_x/dx), so psi is not integrated along paths; it solves the Poisson
    problem laplacian(psi) = -omega (omega from :func:`vorticity`) with psi = 0 on the wall,
    finite volumes on the polar grid (:func:`_poisson_matrix`, direct sparse LU). This keeps
    the solenoidal part of the in-plane flow and drops the divergent (potential) part.
    """
    geo = polar_section(ds)
    omega = vorticity(ds, x)
    if not np.all(np.isfinite(omega)):
        raise ValueError("gas_uy/gas_uz hold NaN or inf at this section; no stream function")
    A = _poisson_matrix(geo)
    rhs = -(omega * geo.area).ravel()
    psi = spla.spsolve(A.tocsc(), rhs)
    return psi.reshape(geo.nr, geo.nt)


def _neighbours(nr: int, nt: int):
    """Adjacency lists of the polar grid: rings j +- 1, sectors k +- 1 (periodic), and every
    pair of innermost wedges (they all touch at the axis)."""
    nbrs = [[] for _ in range(nr * nt)]
    for j in range(nr):
        for k in range(nt):
            i = j * nt + k
            nbrs[i].append(j * nt + (k + 1) % nt)
            nbrs[i].append(j * nt + (k - 1) % nt)
            if j + 1 < nr:
                nbrs[i].append((j + 1) * nt + k)
            if j > 0:
                nbrs[i].append((j - 1) * nt + k)
            else:
                nbrs[i].extend(kk for kk in range(nt) if kk != k)
    return nbrs


def count_cells(psi: np.ndarray, threshold: float = 0.1, area: np.ndarray | None = None,
                y: np.ndarray | None = None, z: np.ndarray | None = None) -> list[dict]:
    """Recirculation cells of a polar stream-function field psi (nr, nt).

    A cell is a connected region (ring/sector neighbours, periodic in theta, all innermost
    wedges touching at the axis) where psi has one sign and |psi| > threshold * max|psi|.
    Returns one dict per cell, largest |peak| first: sign (+1 counter-clockwise, -1
    clockwise looking downstream), peak psi [m2 s-1], peak_fraction (|peak| / max|psi|),
    cells (count), and, when area / y / z are given, area [m2] and the y, z [m] of the peak.
    """
    psi = np.asarray(psi, dtype=float)
    nr, nt = psi.shape
    top = float(np.max(np.abs(psi))) if psi.size else 0.0
    if not top > 0.0:
        return []
    flat = psi.ravel()
    level = threshold * top
    nbrs = _neighbours(nr, nt)
    label = np.full(flat.size, -1)
    found = []
    for start in np.argsort(-np.abs(flat)):
        if label[start] >= 0 or abs(flat[start]) <= level:
            continue
        sign = 1.0 if flat[start] > 0 else -1.0
        members, stack = [], [start]
        label[start] = len(found)
        while stack:
            i = stack.pop()
            members.append(i)
            for n in nbrs[i]:
                if label[n] < 0 and sign * flat[n] > level:
                    label[n] = len(found)
                    stack.append(n)
        cell = dict(sign=int(sign), peak=float(flat[start]),
                    peak_fraction=abs(float(flat[start])) / top, cells=len(members))
        if area is not None:
            cell["area"] = float(np.asarray(area, dtype=float).ravel()[members].sum())
        if y is not None and z is not None:
            cell["y"] = float(np.asarray(y).ravel()[start])
            cell["z"] = float(np.asarray(z).ravel()[start])
        found.append(cell)
    return found


def recirculation_cells(ds: xr.Dataset, x: float | None = None, threshold: float = 0.1,
                        min_strength: float = 1e-6, details: bool = False):
    """Number of recirculation cells of the gas secondary flow at the section x.

    The cells are the connected same-sign regions of the stream function
    (:func:`stream_function`) where |psi| exceeds ``threshold`` (fraction, default 10 %) of
    max|psi| (see :func:`count_cells`); small wiggles from noise stay below the level and are
    not counted. A classic two-cell secondary flow gives 2, a four-cell one 4. When max|psi|
    is below ``min_strength`` U_b R (U_b the bulk velocity, R the pipe radius; default
    1e-6, i.e. round-off), the flow has no cells and the result is 0: this covers no in-plane
    flow and a purely divergent (irrotational) one, whose psi is round-off noise.

    Returns the count (int), or ``(count, cells)`` with the list of cell dicts when
    ``details`` is true.
    """
    geo = polar_section(ds)
    psi = stream_function(ds, x)
    if not np.max(np.abs(psi)) > min_strength * bulk_velocity(ds) * geo.radius:
        return (0, []) if details else 0
    cells = count_cells(psi, threshold, geo.area, geo.y, geo.z)
    return (len(cells), cells) if details else len(cells)


# ---------------------------------------------------------------------------
# profiles, means, wall and pressure
# ---------------------------------------------------------------------------

def gas_maximum_half(ds: xr.Dataset, x: float | None = None, rtol: float = 1e-6) -> str:
    """Which half of the section holds the maximum of the gas axial velocity u_x.

    Returns ``"upper"`` (y > 0) or ``"lower"`` (y < 0); ``"neither"`` when the two halves'
    maxima agree within ``rtol`` (relative), as in a single-phase, mirror-symmetric flow.
    """
    ux = _field(ds, "gas_ux", x)
    y = np.asarray(ds["y"].values, dtype=float)
    up = np.nanmax(np.where(y > 0, ux, -np.inf))
    low = np.nanmax(np.where(y < 0, ux, -np.inf))
    if abs(up - low) <= rtol * max(abs(up), abs(low)):
        return "neither"
    return "upper" if up > low else "lower"


def _arc_overlap(a0: np.ndarray, a1: np.ndarray, b0: float, b1: float) -> np.ndarray:
    """Length [rad] of the overlap of arcs [a0, a1] with [b0, b1] (b within one turn), any turn."""
    total = np.zeros_like(a0, dtype=float)
    for shift in (-TWO_PI, 0.0, TWO_PI):
        lo = np.maximum(a0, b0 + shift)
        hi = np.minimum(a1, b1 + shift)
        total += np.clip(hi - lo, 0.0, None)
    return total


def wall_impact_rates(ds: xr.Dataset, x: float | None = None) -> dict[str, float]:
    """Particle-wall impact rate per wall area on the upper (y > 0) and lower (y < 0) wall
    halves [m-2 s-1], from ``wall_collision_rate(x, theta)`` [m-2 s-1].

    Each half is the wall-area-weighted mean over its sectors (a sector straddling y = 0
    counts with the fraction of its arc in each half). ``x=None`` averages over the pipe
    length weighted by the axial cell lengths (``x_edge``, else uniform); a given x takes the
    nearest station. Returns ``dict(upper=..., lower=...)``.
    """
    if "wall_collision_rate" not in ds:
        raise KeyError("the dataset has no variable 'wall_collision_rate' (no particle phase?)")
    rate = ds["wall_collision_rate"]
    if "x" in rate.dims:
        if x is None:
            if "x_edge" in ds.variables and ds["x_edge"].size == ds.sizes["x"] + 1:
                dx = np.diff(np.asarray(ds["x_edge"].values, dtype=float))
            else:
                dx = np.ones(ds.sizes["x"])
            values = np.asarray(rate.transpose("x", "theta").values, dtype=float)
            per_theta = (values * dx[:, None]).sum(axis=0) / dx.sum()
        else:
            per_theta = np.asarray(section(ds, x)["wall_collision_rate"].values, dtype=float)
    else:
        per_theta = np.asarray(rate.values, dtype=float)
    geo = polar_section(ds)
    t0, t1 = geo.theta_edges[:-1], geo.theta_edges[1:]
    out = {}
    for name, (b0, b1) in (("upper", (0.0, np.pi)), ("lower", (np.pi, TWO_PI))):
        w = _arc_overlap(t0, t1, b0, b1)
        out[name] = float((w * per_theta).sum() / w.sum())
    return out


def _ray_weights(theta: np.ndarray, target: float) -> tuple[int, int, float]:
    """Two sectors straddling the ray at angle ``target`` and the weight of the second:
    linear interpolation in theta between their mid-angles (weight 0 if the ray is a
    mid-line of the first)."""
    d = np.mod(target - theta, TWO_PI)               # angle from each centre forward to the ray
    k0 = int(np.argmin(d))                            # nearest centre at or before the ray
    k1 = (k0 + 1) % theta.size
    gap = np.mod(theta[k1] - theta[k0], TWO_PI) or TWO_PI
    return k0, k1, float(d[k0] / gap)


def vertical_profile(ds: xr.Dataset, var, x: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Values of ``var`` along the vertical diameter (z = 0) of the section x.

    For each ring the value on the upper ray (theta = 90 deg, y = +r) and the lower ray
    (theta = 270 deg, y = -r) is interpolated linearly in theta between the two sectors that
    straddle the ray: with sectors centred on the ray it is that sector's value, with a
    sector face on the ray the mean of the two sectors. NaN-aware: if one of the two is NaN
    the other is used; if both are, the point is NaN (particle variables are NaN where no
    particle passed). Returns ``(y, values)`` sorted by y [m], [units of var].
    """
    geo = polar_section(ds)
    f = _field(ds, var, x)
    ys, vs = [], []
    for target, sign in ((0.5 * np.pi, 1.0), (1.5 * np.pi, -1.0)):
        k0, k1, w = _ray_weights(geo.theta, target)
        a, b = f[:, k0], f[:, k1]
        wa = np.where(np.isnan(a), 0.0, 1.0 - w)
        wb = np.where(np.isnan(b), 0.0, w)
        total = wa + wb
        with np.errstate(invalid="ignore", divide="ignore"):
            v = (wa * np.nan_to_num(a) + wb * np.nan_to_num(b)) / total
        v = np.where(total > 0, v, np.where(np.isnan(a), b, a))
        ys.append(sign * geo.r)
        vs.append(v)
    y, v = np.concatenate(ys), np.concatenate(vs)
    order = np.argsort(y)
    return y[order], v[order]


def section_mean(ds: xr.Dataset, var, x: float | None = None, weight=None) -> float:
    """Area-weighted section mean of ``var`` at x: sum(w A v) / sum(w A) over the cells where
    v (and w) is finite, A = cell_area [m2]; ``weight`` is None (plain area mean), a variable
    name (e.g. ``"gas_ux"`` for a flux-weighted mean) or an (nr, nt) array. NaN if no cell
    has a value. Units of var."""
    v = _field(ds, var, x)
    area = np.asarray(ds["cell_area"].transpose("r", "theta").values, dtype=float)
    w = area if weight is None else area * _field(ds, weight, x)
    ok = np.isfinite(v) & np.isfinite(w)
    den = float(w[ok].sum())
    if not ok.any() or den == 0.0:
        return float("nan")
    return float((w[ok] * v[ok]).sum() / den)


def _scalar(ds: xr.Dataset, name: str) -> float | None:
    if name in ds and ds[name].ndim == 0:
        return float(ds[name].values)
    if name in ds.attrs:
        try:
            return float(attr(ds, name))
        except (TypeError, ValueError):
            return None
    return None


def pressure_drop_summary(ds: xr.Dataset) -> dict[str, float | str]:
    """Pressure-drop figures of a run.

    Keys: ``solids_pressure_drop_ratio`` (Delta p_total / Delta p_gas [1]),
    ``additional_pressure_loss_coefficient`` (lambda_Z [1]), ``pressure_gradient`` and
    ``pressure_gradient_single_phase`` (length-weighted means of -dp/dx [Pa m-1]), and
    ``source``: "dataset" when the two scalars are stored in the dataset (0-d variables or
    attributes), "computed" otherwise. Computed: ratio = mean(pressure_gradient) /
    mean(pressure_gradient_single_phase); lambda_Z = (mean difference) D / (eta rho U_b^2 / 2)
    with D = pipe.diameter, eta = particles.mass_loading, rho = gas.density,
    U_b = gas.bulk_velocity (NaN when any is missing or eta = 0).
    """
    out: dict[str, float | str] = {}
    means = {}
    for name in ("pressure_gradient", "pressure_gradient_single_phase"):
        if name in ds and "x" in ds[name].dims:
            v = np.asarray(ds[name].values, dtype=float)
            if "x_edge" in ds.variables and ds["x_edge"].size == v.size + 1:
                dx = np.diff(np.asarray(ds["x_edge"].values, dtype=float))
            else:
                dx = np.ones_like(v)
            ok = np.isfinite(v)
            means[name] = float((v[ok] * dx[ok]).sum() / dx[ok].sum()) if ok.any() else float("nan")
        else:
            means[name] = float("nan")
    out.update(means)

    ratio = _scalar(ds, "solids_pressure_drop_ratio")
    lam = _scalar(ds, "additional_pressure_loss_coefficient")
    out["source"] = "dataset" if ratio is not None and lam is not None else "computed"
    dp, dp0 = means["pressure_gradient"], means["pressure_gradient_single_phase"]
    if ratio is None:
        ratio = dp / dp0 if np.isfinite(dp0) and dp0 != 0.0 else float("nan")
    if lam is None:
        try:
            d = float(attr(ds, "pipe.diameter"))
            eta = float(attr(ds, "particles.mass_loading"))
            rho = float(attr(ds, "gas.density"))
            ub = float(attr(ds, "gas.bulk_velocity"))
            lam = (dp - dp0) * d / (eta * 0.5 * rho * ub**2) if eta > 0 else float("nan")
        except (TypeError, ValueError):
            lam = float("nan")
    out["solids_pressure_drop_ratio"] = float(ratio)
    out["additional_pressure_loss_coefficient"] = float(lam)
    return out
