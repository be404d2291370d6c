"""A cross-section of the tube from the grains: solids-fraction image and layer velocities.

Strauß, McNamara & Herrmann (2006, §3.4, Figs. 17–19) look at one slice of the tube at half
its length, filmed at 100 Hz: the solids volume fraction over the cross-section (Fig. 17),
the grains' velocity there as a slug passes (Fig. 18) and the velocity of the horizontal grain
layers through the slug (Fig. 19; the lowest layers slowest, the uppermost fastest).  This
module computes both from the grains' positions and velocities, independently of the gas grid:

- :func:`solids_fraction_image`: the slice x_s ± w/2 is cut into square pixels of side
  ``D_t/n_pix`` across the tube.  Each grain is represented by the points of a cubic lattice
  inside its sphere (spacing d/8, 280 points, each carrying V_p/280), so a grain that straddles
  a pixel or the slice faces deposits the part of its volume that lies there.  A pixel's solids
  fraction is its deposited volume over its volume inside the tube, (area inside the wall) × w.
  Pixels less than half inside the wall carry 0 (their few lattice points make them noisy);
  :func:`pixel_inside_fraction` gives their coverage.
- :func:`layer_velocity`: the grains whose centres lie in the slice, binned by the height of
  their centre (bins of d/2 from −(R_t − d/2) to R_t − d/2); per bin the count, the mean axial
  velocity and its root-mean-square fluctuation about that mean.

Pure numpy: a record costs ~1 ms for the ~100 grains near a slug's slice.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["sphere_lattice", "pixel_inside_fraction", "pixel_centres", "solids_fraction_image",
           "layer_edges", "layer_velocity", "slice_offsets"]

LATTICE_PER_DIAMETER = 8
MIN_PIXEL_INSIDE = 0.5


def sphere_lattice(n: int = LATTICE_PER_DIAMETER) -> np.ndarray:
    """Offsets, in units of the grain diameter, of the points of the cubic lattice of spacing
    1/n (offset by half a spacing, so symmetric about the centre) that lie inside the sphere of
    diameter 1.  For n = 8: 280 points (the sphere holds (π/6) n³ = 268.1 cells; each point
    carries V_p/280, so a grain deposits exactly its volume)."""
    k = (np.arange(n) + 0.5) / n - 0.5
    p = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    return p[(p * p).sum(axis=1) <= 0.25]


def pixel_centres(tube_r: float, n_pix: int) -> np.ndarray:
    """Pixel-centre coordinates across the tube (the same for y and z), −R_t + (k + ½) 2R_t/n."""
    return -tube_r + (np.arange(n_pix) + 0.5) * (2.0 * tube_r / n_pix)


def pixel_inside_fraction(tube_r: float, n_pix: int, sub: int = 64) -> np.ndarray:
    """Share of each pixel's area inside the wall, (n_pix, n_pix) indexed [z, y], from a
    ``sub`` × ``sub`` midpoint rule per pixel (error ≲ 1/sub of a pixel's edge)."""
    h = 2.0 * tube_r / n_pix
    s = -tube_r + (np.arange(n_pix * sub) + 0.5) * (h / sub)
    inside = (s[:, None] ** 2 + s[None, :] ** 2) <= tube_r ** 2
    return inside.reshape(n_pix, sub, n_pix, sub).mean(axis=(1, 3))


def slice_offsets(x: np.ndarray, x_s: float, periodic: bool, length: float) -> np.ndarray:
    """Axial distance of positions ``x`` from the slice centre x_s (wrapped in a periodic tube)."""
    rel = x - x_s
    if periodic:
        rel = (rel + 0.5 * length) % length - 0.5 * length
    return rel


def solids_fraction_image(pos: np.ndarray, diameter: float, x_s: float, width: float, tube_r: float,
                          n_pix: int, periodic: bool = False, length: float = 0.0,
                          inside: np.ndarray | None = None, lattice: np.ndarray | None = None) -> np.ndarray:
    """Solids volume fraction of the slice x_s ± width/2 on an n_pix × n_pix image [z, y].

    ``pos``: centres (m, 3) of the grains to count (free grains only; the caller selects).
    Pixels less than :data:`MIN_PIXEL_INSIDE` inside the wall carry 0."""
    if inside is None:
        inside = pixel_inside_fraction(tube_r, n_pix)
    if lattice is None:
        lattice = sphere_lattice()
    image = np.zeros(n_pix * n_pix)
    r = 0.5 * diameter
    rel = slice_offsets(pos[:, 0], x_s, periodic, length)
    near = np.abs(rel) < 0.5 * width + r
    if near.any():
        c = np.column_stack([rel[near], pos[near, 1], pos[near, 2]])
        pts = (c[:, None, :] + diameter * lattice[None, :, :]).reshape(-1, 3)
        keep = np.abs(pts[:, 0]) < 0.5 * width
        h = 2.0 * tube_r / n_pix
        iy = np.floor((pts[keep, 1] + tube_r) / h).astype(np.int64)
        iz = np.floor((pts[keep, 2] + tube_r) / h).astype(np.int64)
        ok = (iy >= 0) & (iy < n_pix) & (iz >= 0) & (iz < n_pix)
        v_point = (math.pi / 6.0) * diameter ** 3 / len(lattice)
        image = np.bincount(iz[ok] * n_pix + iy[ok], minlength=n_pix * n_pix) * v_point
    image = image.reshape(n_pix, n_pix)
    vol = inside * (2.0 * tube_r / n_pix) ** 2 * width
    return np.where(inside >= MIN_PIXEL_INSIDE, image / np.where(vol > 0, vol, 1.0), 0.0)


def layer_edges(tube_r: float, diameter: float) -> np.ndarray:
    """Bin edges of the layer heights: steps of d/2 from −(R_t − d/2) to R_t − d/2 (the range
    the centres can reach); the last bin is shortened if the range is not a whole number of
    steps."""
    top = tube_r - 0.5 * diameter
    n = max(1, int(math.ceil(2.0 * top / (0.5 * diameter) - 1e-9)))
    e = -top + 0.5 * diameter * np.arange(n + 1)
    e[-1] = top
    return e


def layer_velocity(pos: np.ndarray, vel: np.ndarray, x_s: float, width: float, edges: np.ndarray,
                   periodic: bool = False, length: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grains with centres in the slice x_s ± width/2, binned by the height of their centre
    (``pos[:, 2]``, bins ``edges``): (count, mean axial velocity, rms of the axial velocity
    about that mean).  A bin without grains has 0 for both velocities."""
    rel = slice_offsets(pos[:, 0], x_s, periodic, length)
    sel = (rel >= -0.5 * width) & (rel < 0.5 * width)
    z, u = pos[sel, 2], vel[sel, 0]
    k = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, len(edges) - 2)
    nb = len(edges) - 1
    cnt = np.bincount(k, minlength=nb).astype(float)
    per = np.maximum(cnt, 1.0)
    mean = np.bincount(k, weights=u, minlength=nb) / per
    var = np.bincount(k, weights=(u - mean[k]) ** 2, minlength=nb) / per
    return cnt, mean, np.sqrt(var)
