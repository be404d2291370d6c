"""Analysis of eulag datasets: pure numpy/xarray functions.

Everything here reads a dataset only (never the solvers). The cross-section is taken from
the auxiliary coordinates ``y(r, theta)``, ``z(r, theta)`` and ``cell_area(r, theta)``:
ring radii and sector angles follow from y and z, ring edges from cell_area (or from the
``r_edge`` / ``theta_edge`` coordinates when the dataset has them). The stream-function
and profile functions need the polar (r, theta) layout and say so if it is absent.

Secondary-flow patterns under Monte-Carlo noise: :func:`pattern_metrics` (cell counts of the
raw and the mirror-symmetrised stream function, azimuthal mode index, u_y signs along the
vertical diameter, main-pair sense, upper/lower psi-peak ratio, interior solenoidal maximum)
and :func:`replica_pattern_metrics` (their means and standard errors over replicas).

Conventions: x along the axis, y up, z horizontal, right-handed; a section is drawn as
seen looking downstream, z to the right and y up; theta is measured from +z towards +y.
SI units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
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
    "mirror_index", "mirror_average", "mirror_symmetrise_psi", "mirror_symmetrise_velocity",
    "azimuthal_mode_index", "pattern_metrics", "vertical_uy_sign_pattern", "sign_text",
    "interior_solenoidal_max", "upper_lower_peak_ratio", "replica_pattern_metrics",
]

TWO_PI = 2.0 * np.pi


# ---------------------------------------------------------------------------
# attributes and geometry
# ---------------------------------------------------------------------------

def attr(ds: xr.Dataset, key: str, default: Any = None) -> Any:
    """Global attribute ``key`` (flattened case keys such as ``"gas.bulk_velocity"``, stored as
    ``case_gas_bulk_velocity``; datasets written before: the dotted name itself) as a
    plain Python value (numpy scalars unwrapped, 1-element arrays kept as arrays)."""
    if key in ds.attrs:
        value = ds.attrs[key]
    else:
        from eulag.config import dataset_attr_name

        value = ds.attrs.get(dataset_attr_name(key), default) if "." in key else default
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


def require_euler_lagrange(ds, what: str) -> None:
    """ValueError unless ``ds`` is a dataset of the Euler–Lagrange model (single-phase or
    coupled), which the section analysis of ``what`` reads."""
    if not isinstance(ds, xr.Dataset):
        raise ValueError(f"{what}: ds = {type(ds).__name__}; allowed: an xarray.Dataset of an Euler-Lagrange run "
                         "(eulag.open_dataset)")
    model = str(ds.attrs.get("model", "euler-lagrange"))
    if model != "euler-lagrange":
        raise ValueError(f"{what}: a model = {model!r} dataset; allowed: an Euler-Lagrange dataset (the "
                         f"{model} datasets carry their own summary: eulag plot, docs/slug.md, docs/two-fluid.md)")


def check_station(ds: xr.Dataset, x: float | None) -> None:
    """Raise ValueError if the axial position ``x`` [m] lies outside the pipe [0, L].

    L is the attribute ``pipe.length`` (else the last ``x_edge``); periodic (single-station)
    datasets accept any x within the pipe.
    """
    if x is None:
        return
    try:
        x = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"x = {x!r}: not a number; allowed: a position within the pipe [m]") from None
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
    require_euler_lagrange(ds, "secondary_flow_strength")
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
    return _vorticity(geo, _field(ds, "gas_uy", x), _field(ds, "gas_uz", x))


def _vorticity(geo: PolarSection, uy: np.ndarray, uz: np.ndarray) -> np.ndarray:
    """:func:`vorticity` of the Cartesian in-plane components uy, uz (nr, nt) [m s-1] on geo."""
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
    return _stream_function(geo, _field(ds, "gas_uy", x), _field(ds, "gas_uz", x))


_POISSON_LU: dict = {}


def _poisson_lu(geo: PolarSection):
    """Sparse LU of :func:`_poisson_matrix` for geo, cached by the geometry (the same mesh is
    analysed many times: replicas, stations, Monte-Carlo draws)."""
    key = (geo.r_edges.tobytes(), geo.r.tobytes(), geo.theta.tobytes(), geo.theta_edges.tobytes())
    lu = _POISSON_LU.get(key)
    if lu is None:
        if len(_POISSON_LU) >= 16:
            _POISSON_LU.clear()
        lu = _POISSON_LU[key] = spla.splu(_poisson_matrix(geo).tocsc())
    return lu


def _stream_function(geo: PolarSection, uy: np.ndarray, uz: np.ndarray) -> np.ndarray:
    """:func:`stream_function` of the Cartesian in-plane components uy, uz (nr, nt) on geo."""
    omega = _vorticity(geo, uy, uz)
    if not np.all(np.isfinite(omega)):
        raise ValueError("gas_uy/gas_uz hold NaN or inf at this section; no stream function")
    rhs = -(omega * geo.area).ravel()
    psi = _poisson_lu(geo).solve(rhs)
    return psi.reshape(geo.nr, geo.nt)


@lru_cache(maxsize=16)
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
                        min_strength: float = 1e-6, details: bool = False,
                        symmetrise: bool = False, min_area: float = 0.0):
    """Number of recirculation cells of the gas secondary flow at the section x.

    The cells are the connected same-sign regions of the stream function
    (:func:`stream_function`) where |psi| exceeds ``threshold`` (fraction, default 10 %) of
    max|psi| (see :func:`count_cells`); small wiggles from noise stay below the level and are
    not counted. A classic two-cell secondary flow gives 2, a four-cell one 4. When max|psi|
    is below ``min_strength`` U_b R (U_b the bulk velocity, R the pipe radius; default
    1e-6, i.e. round-off), the flow has no cells and the result is 0: this covers no in-plane
    flow and a purely divergent (irrotational) one, whose psi is round-off noise.

    ``symmetrise=True`` counts the cells of the mirror-symmetrised stream function
    (:func:`mirror_symmetrise_psi`): the problem is mirror-symmetric about z = 0, so the part
    of psi with the wrong parity is noise; the symmetrised count is always even (see
    :func:`pattern_metrics`). The default (False) counts the raw psi, as before.
    ``min_area`` (fraction of the section area, default 0) drops the cells smaller than
    that (noise blobs; :func:`pattern_metrics` uses 0.05).

    Returns the count (int), or ``(count, cells)`` with the list of cell dicts when
    ``details`` is true.
    """
    require_euler_lagrange(ds, "recirculation_cells")
    geo = polar_section(ds)
    psi = stream_function(ds, x)
    if symmetrise:
        psi = mirror_symmetrise_psi(psi, geo.theta)
    if not np.max(np.abs(psi)) > min_strength * bulk_velocity(ds) * geo.radius:
        return (0, []) if details else 0
    cells = count_cells(psi, threshold, geo.area, geo.y, geo.z)
    if min_area > 0:
        cells = [c for c in cells if c["area"] >= min_area * geo.area.sum()]
    return (len(cells), cells) if details else len(cells)


# ---------------------------------------------------------------------------
# mirror symmetry and noise-robust secondary-flow pattern metrics
# ---------------------------------------------------------------------------

def mirror_index(nt: int) -> np.ndarray:
    """Sector map of the mirror z -> -z on a polar section of ``nt`` uniform sectors.

    The mirror about the vertical plane z = 0 maps theta -> pi - theta (theta from +z towards
    +y). Sector k of nt uniform sectors starting at theta = 0 has its mid-angle at
    (k + 1/2) 2 pi / nt, whose image is the mid-angle of sector (nt/2 - 1 - k) mod nt; the
    returned int array (nt,) holds that index for every k. The map is an involution. It
    needs nt even (with nt odd the image of a mid-angle is a sector face): ValueError
    otherwise.
    """
    nt = int(nt)
    if nt < 2 or nt % 2:
        raise ValueError(f"the mirror z -> -z needs an even number of sectors (nt uniform sectors from "
                         f"theta = 0 map sector k to nt/2 - 1 - k); got nt = {nt}")
    return np.mod(nt // 2 - 1 - np.arange(nt), nt)


def _mirror_perm(nt: int, theta=None) -> np.ndarray:
    """:func:`mirror_index`, checked against the sector mid-angles theta when given."""
    perm = mirror_index(nt)
    if theta is not None:
        theta = np.asarray(theta, dtype=float)
        if theta.size != nt:
            raise ValueError(f"theta has {theta.size} sectors, the field {nt}")
        image = np.pi - theta
        miss = np.abs(np.angle(np.exp(1j * (image - theta[perm]))))
        if miss.max() > 1e-6 * TWO_PI / nt:
            raise ValueError("the sectors are not mirror images of each other about z = 0 (the "
                             "mirror needs uniform sectors starting at theta = 0); largest mismatch "
                             f"{np.degrees(miss.max()):.3g} deg")
    return perm


def mirror_average(field, parity: int, theta=None) -> np.ndarray:
    """Part of a polar field with the given parity under the mirror z -> -z.

    ``field`` is (..., nt), the last axis the sectors (uniform from theta = 0, nt even; see
    :func:`mirror_index`); ``parity`` +1 (even: the field is its own mirror image, e.g. u_x,
    u_y, p, concentration) or -1 (odd: the mirror image is minus the field, e.g. u_z and the
    stream function psi). Returns (f + parity f o M) / 2 with (f o M)[k] = f[M(k)],
    M = :func:`mirror_index`, in the units of the field. This is the orthogonal (cell-area
    weighted too, the areas being mirror-symmetric) projection on the fields of that parity:
    applying it twice changes nothing, and a field of that parity is a fixed point. With
    ``theta`` (nt,) given, the sector mid-angles are checked to be mirror images.
    """
    f = np.asarray(field, dtype=float)
    if parity not in (1, -1):
        raise ValueError(f"parity must be +1 (even) or -1 (odd); got {parity!r}")
    perm = _mirror_perm(f.shape[-1], theta)
    return 0.5 * (f + parity * f[..., perm])


def mirror_symmetrise_psi(psi, theta=None) -> np.ndarray:
    """The mirror-symmetric part of a stream function psi (nr, nt) [m2 s-1]: the odd part
    psi_s = (psi - psi o M) / 2 (:func:`mirror_average` with parity -1).

    Why odd: a mirror-symmetric in-plane flow (about z = 0) has u_y(y, -z) = u_y(y, z) (even)
    and u_z(y, -z) = -u_z(y, z) (odd). With u_y = -d psi/dz (:func:`stream_function`)
    d psi/dz is even, so psi is odd (the constant is 0: psi = 0 on the wall). Check on a two-cell
    flow psi = f(r) cos(theta): cos(pi - theta) = -cos(theta), odd; the right (z > 0) and left
    cells turn opposite ways, as mirror images do. A four-cell flow f(r) sin(2 theta) is odd
    too (sin(2 pi - 2 theta) = -sin(2 theta)). The even part of psi, e.g. a single cell f(r)
    or f(r) sin(theta), would be a mirror-asymmetric flow (a net swirl, a cell turning one way
    on both sides): in this problem, noise. psi_s vanishes on the mirror plane; a sector
    centred on it (nt = 2 mod 4) gets psi_s = 0 exactly.
    """
    return mirror_average(psi, -1, theta)


def mirror_symmetrise_velocity(uy, uz, theta=None) -> tuple[np.ndarray, np.ndarray]:
    """Mirror-symmetric part (even u_y, odd u_z) of the Cartesian in-plane velocity (nr, nt)
    [m s-1] (:func:`mirror_average`). Its stream function is the odd part of the stream
    function of (u_y, u_z) (the grid and the operators of :func:`stream_function` are
    mirror-symmetric, so symmetrising commutes with them)."""
    return mirror_average(uy, 1, theta), mirror_average(uz, -1, theta)


def azimuthal_mode_index(psi, geo: PolarSection, details: bool = False):
    """Four-cell/two-cell azimuthal mode index of a stream function psi (nr, nt) on geo.

    Definition: in each ring j the least-squares coefficients of the two modes,
    c_j = sum_k psi_jk cos(theta_k) dtheta_k / sum_k cos^2(theta_k) dtheta_k and
    s_j = sum_k psi_jk sin(2 theta_k) dtheta_k / sum_k sin^2(2 theta_k) dtheta_k [m2 s-1];
    the mode amplitudes are the cell-area-weighted RMS of the projections over the section,
    A_1 = sqrt(sum_jk A_jk (c_j cos theta_k)^2 / sum A) and
    A_2 = sqrt(sum_jk A_jk (s_j sin 2 theta_k)^2 / sum A) [m2 s-1]; the index is
    A_2 / A_1 [1] (inf if A_1 = 0 < A_2, NaN if both are 0). A two-cell flow (cells left and
    right of the vertical diameter, psi ~ f(r) cos theta) gives 0, a four-cell flow (an upper
    and a lower pair, psi ~ f(r) sin 2 theta) gives inf; > 1 means the four-cell mode carries
    more of psi than the two-cell mode. Both modes are odd under the mirror z -> -z, so the
    index is the same for psi and its symmetrised part (:func:`mirror_symmetrise_psi`).
    ``details=True`` returns ``(index, dict(cos_theta=A_1, sin_2theta=A_2))``.
    """
    psi = np.asarray(psi, dtype=float)
    dth = geo.dtheta[None, :]
    amps = {}
    for name, mode in (("cos_theta", np.cos(geo.theta)), ("sin_2theta", np.sin(2.0 * geo.theta))):
        coef = (psi * mode * dth).sum(axis=1) / (mode**2 * dth).sum()
        proj = coef[:, None] * mode[None, :]
        amps[name] = float(np.sqrt((geo.area * proj**2).sum() / geo.area.sum()))
    a1, a2 = amps["cos_theta"], amps["sin_2theta"]
    index = a2 / a1 if a1 > 0 else (float("inf") if a2 > 0 else float("nan"))
    return (index, amps) if details else index


def _centred_difference(fm, f0, fp, hm, hp):
    """Second-order derivative at the middle of three points at offsets -hm, 0, +hp."""
    return (hm**2 * fp - hp**2 * fm + (hp**2 - hm**2) * f0) / (hm * hp * (hm + hp))


def _psi_velocity(geo: PolarSection, psi) -> tuple[np.ndarray, np.ndarray]:
    """Polar velocity (u_r, u_theta) (nr, nt) [m s-1] of the solenoidal flow curl(psi e_x) at
    the cell centres: u_r = (1/r) d psi/d theta, u_theta = -d psi/dr, second-order centred
    differences (periodic in theta; ring 0 takes its inner point across the axis, psi of the
    opposite sector at -r_0; the wall ring its outer point on the wall, psi = 0)."""
    psi = np.asarray(psi, dtype=float)
    nr, nt = psi.shape
    th = geo.theta
    hp = np.mod(np.roll(th, -1) - th, TWO_PI)
    hm = np.mod(th - np.roll(th, 1), TWO_PI)
    dpsi_dth = _centred_difference(np.roll(psi, 1, axis=1), psi, np.roll(psi, -1, axis=1),
                                   hm[None, :], hp[None, :])
    r = geo.r
    inner = np.vstack([np.roll(psi[:1], -(nt // 2), axis=1), psi[:-1]])   # ring 0: across the axis
    outer = np.vstack([psi[1:], np.zeros((1, nt))])                      # wall ring: psi = 0 on the wall
    rm = np.concatenate([[2.0 * r[0]], np.diff(r)])
    rp = np.concatenate([np.diff(r), [geo.radius - r[-1]]])
    dpsi_dr = _centred_difference(inner, psi, outer, rm[:, None], rp[:, None])
    return dpsi_dth / r[:, None], -dpsi_dr


def _vertical_uy(geo: PolarSection, uy, segments: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment means of u_y along the vertical diameter, from the mirror-even part of uy.

    Returns (y, u, sigma), (2 segments,) each, ordered from the bottom wall to the top wall:
    each radius (theta = 270 deg below the centre, 90 deg above it) is cut into ``segments``
    groups of consecutive rings (``numpy.array_split`` of the rings, inner to outer); u
    [m s-1] is the mean over the group's rings of the mirror-even part of uy
    (:func:`mirror_average`) interpolated onto the ray as :func:`vertical_profile` does
    (where a sector face lies on the ray, the two sectors beside it are mirror images and u is
    their mean); y [m] the group's mean ring radius with the ray's sign. sigma [m s-1] is the
    noise standard deviation of u, estimated from the mirror-odd part of uy, which a
    mirror-symmetric flow does not have: the same ring-group mean of the odd part, taken in
    every sector that is not its own image, has mean square s^2, and a group mean of
    per-sector noise has variance 2 s^2 (odd = (n_k - n_M(k))/2); sigma^2 = 2 s^2 sum_k c_k^2,
    c_k the weights of u on the sectors (this assumes noise independent between sectors;
    the ring-group mean keeps any radial correlation of the noise).
    """
    nr, nt = uy.shape
    perm = _mirror_perm(nt, geo.theta)
    even = mirror_average(uy, 1)
    odd = uy - even
    moving = perm != np.arange(nt)
    groups = [g for g in np.array_split(np.arange(nr), max(1, min(int(segments), nr))) if g.size]
    ys, us, ss = [], [], []
    for target, sign in ((1.5 * np.pi, -1.0), (0.5 * np.pi, 1.0)):
        k0, k1, w = _ray_weights(geo.theta, target)
        c = np.zeros(nt)
        for k, wk in ((k0, 1.0 - w), (k1, w)):
            c[k] += 0.5 * wk
            c[perm[k]] += 0.5 * wk
        line = (1.0 - w) * even[:, k0] + w * even[:, k1]
        order = groups[::-1] if sign < 0 else groups        # bottom wall -> centre -> top wall
        for g in order:
            gm = odd[g].mean(axis=0)                          # (nt,) ring-group means of the odd part
            s2 = float((gm[moving] ** 2).mean()) if moving.any() else 0.0
            # lag-1 correlation between neighbouring sectors, from the pairs that are not
            # mirror images of each other (clipped to [0, 1])
            nxt = np.roll(np.arange(nt), -1)
            pair = moving & moving[nxt] & (perm != nxt)
            rho = float(np.clip((gm[pair] * gm[nxt][pair]).mean() / s2, 0.0, 1.0)) \
                if s2 > 0 and pair.any() else 0.0
            quad = float((c**2).sum() + 2.0 * rho * (c * np.roll(c, -1)).sum())
            ys.append(sign * float(geo.r[g].mean()))
            us.append(float(line[g].mean()))
            ss.append(float(np.sqrt(2.0 * s2 * quad)))
    return np.array(ys), np.array(us), np.array(ss)


def _sign_runs(u, sigma, noise_factor: float, floor: float) -> list[int]:
    """Signs (+1/-1), in order, of the runs of segments whose |u| exceeds the noise-aware level
    max(noise_factor sigma, floor max|u|); segments below the level are skipped (they do not
    split a run), so neighbouring runs of the same sign merge."""
    u = np.asarray(u, dtype=float)
    top = float(np.max(np.abs(u))) if u.size else 0.0
    if not top > 0.0:
        return []
    level = np.maximum(noise_factor * np.asarray(sigma, dtype=float), floor * top)
    pattern: list[int] = []
    for v, lv in zip(u, level):
        if abs(v) > lv:
            sgn = 1 if v > 0 else -1
            if not pattern or pattern[-1] != sgn:
                pattern.append(sgn)
    return pattern


def _peak_ratio(psi, y) -> float:
    """max|psi| over the cells with y > 0 / max|psi| over y < 0 [1] (inf / NaN if the lower
    half is 0)."""
    up = float(np.max(np.abs(np.where(y > 0, psi, 0.0))))
    low = float(np.max(np.abs(np.where(y < 0, psi, 0.0))))
    if low > 0:
        return up / low
    return float("inf") if up > 0 else float("nan")


def _second_pair(geo: PolarSection, psi_s, level: float = 0.01) -> tuple[float, float]:
    """The strongest counter-rotating cell beside the main pair, at any strength.

    Cells of the mirror-symmetrised psi_s are found as :func:`count_cells` does, at ``level``
    (1 %) of max|psi_s| and with no minimum area. In the right half (z > 0) the strongest
    cell is the main pair's; the second pair is the strongest right-half cell of the other
    sign. Returns (|peak| / max|psi_s| [1], y/R of its peak [1]); (0, NaN) if there is none.
    The study's count keeps only cells above 10 % of the maximum and 5 % of the section, so
    a weak upper or lower pair shows here first."""
    if not np.max(np.abs(psi_s)) > 0.0:
        return 0.0, float("nan")
    right = [c for c in count_cells(psi_s, level, geo.area, geo.y, geo.z) if c["z"] > 0]
    if not right:
        return 0.0, float("nan")
    other = [c for c in right if c["sign"] != right[0]["sign"]]
    if not other:
        return 0.0, float("nan")
    return float(other[0]["peak_fraction"]), float(other[0]["y"]) / geo.radius


def _pattern(geo: PolarSection, uy, uz, u_b: float, threshold: float, min_area: float,
             noise_factor: float, segments: int, floor: float, min_strength: float) -> dict:
    """:func:`pattern_metrics` of the Cartesian in-plane velocity uy, uz (nr, nt) [m s-1] on geo,
    U_b = u_b [m s-1]."""
    uy = np.asarray(uy, dtype=float)
    uz = np.asarray(uz, dtype=float)
    psi = _stream_function(geo, uy, uz)
    psi_s = mirror_symmetrise_psi(psi, geo.theta)
    small = min_strength * u_b * geo.radius
    raw = count_cells(psi, threshold) if np.max(np.abs(psi)) > small else []
    cells = count_cells(psi_s, threshold, geo.area, geo.y, geo.z) if np.max(np.abs(psi_s)) > small else []
    cells = [c for c in cells if c["area"] >= min_area * geo.area.sum()]
    right = [c for c in cells if c["z"] > 0]
    sense = None
    if right:
        sense = "down on the axis" if right[0]["sign"] > 0 else "up on the axis"
    y, u, sig = _vertical_uy(geo, uy, segments)
    pattern = _sign_runs(u, sig, noise_factor, floor)
    # the same along the vertical diameter for the solenoidal flow curl(psi e_x) of the raw psi
    # (its mirror-odd part still carries the noise that _vertical_uy estimates sigma from)
    ur_raw, ut_raw = _psi_velocity(geo, psi)
    sth, cth = np.sin(geo.theta)[None, :], np.cos(geo.theta)[None, :]
    _, u_sol, sig_sol = _vertical_uy(geo, ur_raw * sth + ut_raw * cth, segments)
    pattern_sol = _sign_runs(u_sol, sig_sol, noise_factor, floor)
    line = _vertical_line(geo, mirror_average(uy, 1))[1]
    centre = 0.5 * (line[geo.nr - 1] + line[geo.nr])   # innermost ring, y = -r_0 and +r_0
    ur, ut = _psi_velocity(geo, psi_s)
    interior = np.hypot(ur, ut)[:-1]
    second, second_y = _second_pair(geo, psi_s)
    return {
        "count_raw": len(raw),
        "count_symmetrised": len(cells),
        "mode_index": azimuthal_mode_index(psi_s, geo),
        "uy_sign_pattern": pattern,
        "uy_sign_changes": max(len(pattern) - 1, 0),
        "uy_solenoidal_sign_pattern": pattern_sol,
        "second_pair_fraction": second,
        "second_pair_y": second_y,
        "main_pair_sense": sense,
        "upper_lower_peak_ratio": _peak_ratio(psi_s, geo.y),
        "interior_solenoidal_max": 100.0 * float(interior.max()) / u_b if interior.size else float("nan"),
        "strength": 100.0 * float(np.max(np.hypot(uy, uz))) / u_b,
        "uy_centre": float(centre),
    }


def pattern_metrics(ds: xr.Dataset, x: float | None = None, threshold: float = 0.1,
                    min_area: float = 0.05, noise_factor: float = 3.0, segments: int = 4, floor: float = 0.05,
                    min_strength: float = 1e-6) -> dict:
    """Secondary-flow pattern metrics at the section x that per-cell noise cannot fool.

    The problem (horizontal pipe, gravity -y) is mirror-symmetric about z = 0, so the parts
    of the in-plane gas flow with the wrong mirror parity are Monte-Carlo noise of the
    particle sources; the metrics read the mirror-symmetric part. Needs the polar section
    with nt even, uniform sectors from theta = 0 (:func:`mirror_index`). Keys:

    - ``count_raw`` [1]: :func:`recirculation_cells` of the raw stream function (connected
      same-sign regions above ``threshold`` of max|psi|; odd counts happen under noise).
    - ``count_symmetrised`` [1]: the same count on psi_s = :func:`mirror_symmetrise_psi`,
      leaving out cells smaller than ``min_area`` (fraction of the section area, default
      0.05: noise blobs above the level are a few grid cells, < 2 % of the section in the
      tests, while a cell of a two- or four-cell flow covers 10-50 %). Always even: the mirror
      maps the neighbour graph of :func:`count_cells` (ring and sector neighbours, all
      innermost wedges through the axis) onto itself, psi_s onto -psi_s and the cell areas
      onto themselves, so it maps each counted cell onto a counted cell of the other sign; no
      cell is its own image (that would need both signs in one cell), and none straddles the
      mirror plane, where psi_s = 0 (the two sectors beside the plane hold opposite psi_s, a
      sector centred on it holds 0, below the level).
    - ``mode_index`` [1]: :func:`azimuthal_mode_index` of psi_s, A(sin 2 theta) / A(cos theta):
      ~0 for two cells, large for four; > 1 four-cell-like.
    - ``uy_sign_pattern`` (list of +1/-1, from the bottom wall to the top wall) and
      ``uy_sign_changes`` (its length - 1): each radius of the vertical diameter is cut into
      ``segments`` groups of rings; a segment's sign counts where its mean mirror-even u_y
      exceeds max(noise_factor sigma, floor max|segment mean|), sigma the segment's noise
      estimated from the mirror-odd part of u_y (:func:`_vertical_uy`); segments below the
      level are skipped and equal neighbouring signs merged. Two cells
      (psi = a f(r) cos theta, f = (1 - r^2/R^2)^2 r/R): u_y = -a (1 - r^2/R^2)^2 / R on the
      whole diameter, one sign, 0 changes. Four cells (psi = a (1 - r^2/R^2)^2 (r/R)^2 sin 2 theta
      = 2 a (1 - r^2/R^2)^2 y z / R^2): u_y = -2 a (1 - r^2/R^2)^2 y / R^2 on z = 0, which
      changes sign once, at the centre (where u_y = 0): pattern [+1, -1] for a > 0 (the flow
      meets at the centre along the vertical diameter), [-1, +1] for a < 0 (it leaves the
      centre); 1 change. More changes mean more than one pair along the diameter.
    - ``uy_solenoidal_sign_pattern``: the same sign pattern for the u_y of the solenoidal flow
      curl(psi e_x) (psi of the raw field): the divergent in-plane flow that the axial
      development drives (div u = -du_x/dx) is left out, so a sign change here is a second
      pair of cells.
    - ``second_pair_fraction`` [1] and ``second_pair_y`` [1]: the strongest cell of psi_s in
      the right half that turns against the main pair, at any strength (:func:`_second_pair`:
      cells down to 1 % of max|psi_s|, no minimum area): its |peak| / max|psi_s| and the y/R
      of its peak (0 and NaN if there is none); weak pairs below the count's threshold show
      here.
    - ``main_pair_sense``: "up on the axis" or "down on the axis", the rotation sense of the
      strongest cell of psi_s in the right half (z > 0): clockwise (psi < 0) turns upward on
      its side towards the vertical diameter and downward at the side wall ("up on the axis",
      the paper's two-cell pattern), counter-clockwise the reverse. For a two-cell flow this is
      the sign of u_y at the centre; for a four-cell flow (u_y = 0 at the centre) it is the
      direction along the half of the vertical diameter that the stronger pair borders.
      None without cells.
    - ``upper_lower_peak_ratio`` [1]: max|psi_s| over the grid cells with y > 0 / max|psi_s|
      over those with y < 0 (inf / NaN when the lower half is 0).
    - ``interior_solenoidal_max`` [% of U_b]: the largest speed of the solenoidal flow
      u = curl(psi_s e_x) (:func:`_psi_velocity`, centred differences of psi_s at the cell
      centres) outside the wall ring.
    - ``strength`` [% of U_b]: :func:`secondary_flow_strength`, the largest raw in-plane speed,
      which includes the divergent part, the noise and the wall ring.
    - ``uy_centre`` [m s-1]: the mirror-even u_y on the vertical diameter at the centre (mean
      of the innermost ring's two points).

    U_b is :func:`bulk_velocity`. ``min_strength``: as in :func:`recirculation_cells` (below
    it both counts are 0). ``recirculation_cells(ds, x, threshold, symmetrise=True,
    min_area=0.05)`` gives ``count_symmetrised``. Error bars from replicas:
    :func:`replica_pattern_metrics`.
    """
    geo = polar_section(ds)
    return _pattern(geo, _field(ds, "gas_uy", x), _field(ds, "gas_uz", x), bulk_velocity(ds),
                    threshold, min_area, noise_factor, segments, floor, min_strength)


def sign_text(pattern) -> str:
    """A sign pattern (``uy_sign_pattern`` of :func:`pattern_metrics`: +1/-1 from the bottom wall
    up) as text, e.g. [1, -1] -> "+-"; "0" for an empty pattern (no segment above the noise)."""
    return "".join("+" if v > 0 else "-" for v in pattern) or "0"


def vertical_uy_sign_pattern(ds: xr.Dataset, x: float | None = None, noise_factor: float = 3.0,
                             segments: int = 4, floor: float = 0.05) -> tuple[list[int], int]:
    """Sign pattern of u_y along the vertical diameter (bottom to top) and its number of sign
    changes: ``(pattern, changes)`` as ``uy_sign_pattern`` / ``uy_sign_changes`` of
    :func:`pattern_metrics`."""
    geo = polar_section(ds)
    y, u, sig = _vertical_uy(geo, _field(ds, "gas_uy", x), segments)
    pattern = _sign_runs(u, sig, noise_factor, floor)
    return pattern, max(len(pattern) - 1, 0)


def interior_solenoidal_max(ds: xr.Dataset, x: float | None = None, symmetrise: bool = True) -> float:
    """Largest in-plane speed of the solenoidal part of the gas flow, u = curl(psi e_x) with psi
    from :func:`stream_function` (mirror-symmetrised when ``symmetrise``), at the cell
    centres outside the wall ring, in % of the bulk velocity [%]. Unlike
    :func:`secondary_flow_strength` it leaves out the divergent part of the in-plane flow
    (-du_x/dx in a developing pipe) and the wall ring."""
    geo = polar_section(ds)
    psi = stream_function(ds, x)
    if symmetrise:
        psi = mirror_symmetrise_psi(psi, geo.theta)
    ur, ut = _psi_velocity(geo, psi)
    return 100.0 * float(np.hypot(ur, ut)[:-1].max()) / bulk_velocity(ds)


def upper_lower_peak_ratio(ds: xr.Dataset, x: float | None = None, symmetrise: bool = True) -> float:
    """max|psi| over the cells with y > 0 divided by max|psi| over y < 0 [1], psi the stream
    function (:func:`stream_function`, mirror-symmetrised when ``symmetrise``)."""
    geo = polar_section(ds)
    psi = stream_function(ds, x)
    if symmetrise:
        psi = mirror_symmetrise_psi(psi, geo.theta)
    return _peak_ratio(psi, geo.y)


_NUMERIC_PATTERN_KEYS = ("count_raw", "count_symmetrised", "mode_index", "uy_sign_changes",
                         "upper_lower_peak_ratio", "interior_solenoidal_max", "strength", "uy_centre",
                         "second_pair_fraction")


def _agreement(values) -> tuple[Any, float]:
    """Most common value (first seen on ties) and the fraction of values equal to it."""
    values = [tuple(v) if isinstance(v, list) else v for v in values]
    best, best_n = None, 0
    for v in values:
        n = values.count(v)
        if n > best_n:
            best, best_n = v, n
    best = list(best) if isinstance(best, tuple) else best
    return best, best_n / len(values)


def dataset_replicas(ds: xr.Dataset) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (u_y, u_z) replicas a coupled dataset stores (``replica_gas_uy/uz``: the gas at the
    first reported station solved on each final pass's own sources), for
    :func:`replica_pattern_metrics` with ``template=ds``; [] when the dataset has none."""
    if "replica_gas_uy" not in ds:
        return []
    uy, uz = ds["replica_gas_uy"].values, ds["replica_gas_uz"].values
    return [(uy[i], uz[i]) for i in range(uy.shape[0])]


def replica_pattern_metrics(replicas, x: float | None = None, template: xr.Dataset | None = None,
                            **options) -> dict:
    """:func:`pattern_metrics` of replicas of one section, with error bars.

    ``replicas``: a list of datasets (e.g. the gas solved on each final coupling pass's
    sources), or of ``(u_y, u_z)`` (nr, nt) arrays [m s-1] on the section of ``template``
    (whose geometry and bulk velocity are used). ``options`` go to :func:`pattern_metrics`.
    Returns a dict:

    - ``n``: number of replicas; ``replicas``: the list of their metric dicts;
    - ``mean`` / ``stderr``: for each numeric metric (count_raw, count_symmetrised,
      mode_index, uy_sign_changes, upper_lower_peak_ratio, interior_solenoidal_max, strength,
      uy_centre, second_pair_fraction) the mean over the replicas and its standard error std(ddof=1)/sqrt(n)
      (NaN for n = 1), in the metric's units;
    - ``count``: the most common symmetrised count, ``count_agreement``: the fraction of the
      replicas giving it; likewise ``count_raw`` / ``count_raw_agreement``,
      ``main_pair_sense`` / ``main_pair_sense_agreement`` and ``uy_sign_pattern`` /
      ``uy_sign_pattern_agreement``;
    - ``pooled``: :func:`pattern_metrics` of the replica-mean velocity (noise down by
      sqrt(n) if the replicas' noise is independent).
    """
    replicas = list(replicas)
    if not replicas:
        raise ValueError("no replicas")
    opts = dict(threshold=0.1, min_area=0.05, noise_factor=3.0, segments=4, floor=0.05, min_strength=1e-6)
    unknown = set(options) - set(opts)
    if unknown:
        raise TypeError(f"unknown options {sorted(unknown)}; allowed: {sorted(opts)}")
    opts.update(options)
    fields = []
    if all(isinstance(r, xr.Dataset) for r in replicas):
        base = template if template is not None else replicas[0]
        for r in replicas:
            fields.append((_field(r, "gas_uy", x), _field(r, "gas_uz", x)))
    else:
        if template is None:
            raise ValueError("replicas given as (u_y, u_z) arrays need a template dataset for the geometry")
        base = template
        fields = [(np.asarray(a, dtype=float), np.asarray(b, dtype=float)) for a, b in replicas]
    geo = polar_section(base)
    u_b = bulk_velocity(base)
    shape = (geo.nr, geo.nt)
    for a, b in fields:
        if a.shape != shape or b.shape != shape:
            raise ValueError(f"a replica's velocity has shape {a.shape}/{b.shape}, the section {shape}")
    per = [_pattern(geo, a, b, u_b, **opts) for a, b in fields]
    n = len(per)
    mean, stderr = {}, {}
    for key in _NUMERIC_PATTERN_KEYS:
        v = np.array([float(m[key]) for m in per])
        mean[key] = float(v.mean())
        stderr[key] = float(v.std(ddof=1) / np.sqrt(n)) if n > 1 else float("nan")
    out: dict[str, Any] = {"n": n, "replicas": per, "mean": mean, "stderr": stderr}
    for key, name in (("count_symmetrised", "count"), ("count_raw", "count_raw"),
                      ("main_pair_sense", "main_pair_sense"), ("uy_sign_pattern", "uy_sign_pattern")):
        out[name], out[f"{name}_agreement"] = _agreement([m[key] for m in per])
    uy = np.mean([a for a, _ in fields], axis=0)
    uz = np.mean([b for _, b in fields], axis=0)
    out["pooled"] = _pattern(geo, uy, uz, u_b, **opts)
    return out


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
    return _vertical_line(geo, _field(ds, var, x))


def _vertical_line(geo: PolarSection, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`vertical_profile` of an (nr, nt) array f on geo: ``(y, values)`` sorted by y."""
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
    require_euler_lagrange(ds, "pressure_drop_summary")
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
