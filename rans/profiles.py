"""Profiles of a cell field along the pipe: centreline and vertical diameter.

Interpolation rules (used by tests, reports and plots alike):

* radially, linear in r between cell centres, except next to the wall, where the value is
  taken linear in ln(wall distance) between the wall-cell centre and its neighbour (exact for
  the log law that the wall function imposes);
* on the axis, the innermost ring is extrapolated with an even (parabolic) profile;
* azimuthally, the two sectors that straddle the vertical diameter are averaged (the
  sector edges lie on it when the sector count is a multiple of 4; otherwise the sector
  centred on it is used).
"""

from __future__ import annotations

import numpy as np

__all__ = ["axis_value", "vertical_profile", "radial_profile"]


def axis_value(mesh, section):
    """Value on the axis of a (nr, nt) cross-section field (even extrapolation of rings 0 and 1)."""
    r0, r1 = mesh.r[0], mesh.r[1]
    u0 = section[0].mean()
    u1 = section[1].mean()
    return u0 - (u1 - u0) * r0**2 / (r1**2 - r0**2)


def _sectors(mesh, top):
    target = 0.5 * np.pi if top else 1.5 * np.pi
    d = np.abs((mesh.theta - target + np.pi) % (2 * np.pi) - np.pi)
    order = np.argsort(d)
    if np.isclose(d[order[0]], d[order[1]]):
        return order[:2]
    return order[:1]


def radial_profile(mesh, column, r):
    """Interpolate one radial column (nr,) of cell values at radii r [m] (0 <= r <= R)."""
    R = mesh.radius
    rc = mesh.r
    r = np.atleast_1d(np.asarray(r, dtype=float))
    out = np.interp(r, rc, column)
    # axis: even extrapolation inside the first ring centre
    inner = r < rc[0]
    if inner.any():
        a = column[0] - (column[1] - column[0]) * rc[0] ** 2 / (rc[1] ** 2 - rc[0] ** 2)
        out[inner] = a + (column[0] - a) * (r[inner] / rc[0]) ** 2
    # wall region: linear in ln(wall distance) from the second-to-last centre outward
    near = r > rc[-2]
    if near.any():
        y1, y2 = R - rc[-2], R - rc[-1]
        yw = np.maximum(R - r[near], 1e-12 * R)
        t = np.log(yw / y1) / np.log(y2 / y1)
        out[near] = column[-2] + t * (column[-1] - column[-2])
    return out


def vertical_profile(mesh, section, eta):
    """Values of a (nr, nt) cross-section field along the vertical diameter at y = eta R (-1 bottom)."""
    eta = np.atleast_1d(np.asarray(eta, dtype=float))
    top = _sectors(mesh, True)
    bottom = _sectors(mesh, False)
    col_top = section[:, top].mean(axis=1)
    col_bot = section[:, bottom].mean(axis=1)
    r = np.abs(eta) * mesh.radius
    out = np.where(eta >= 0, radial_profile(mesh, col_top, r), radial_profile(mesh, col_bot, r))
    return out
