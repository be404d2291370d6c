"""The recorded cross-section of the slug model (dem.sections, SMH §3.4, Figs. 17-19):

- a grain deposits exactly its volume, and half of it when its centre lies on a slice face;
- grains whose centres are uniform in the accessible cylinder give, in the pixels a whole grain
  radius inside that cylinder, the analytic solids fraction N V_p / (π R_c² L);
- the pixel areas inside the wall sum to the tube's cross-section;
- the layer velocities of a sheared packing are its shear profile, from the slice's grains only.
"""

import math

import numpy as np

from dem import sections

RT, D = 3.5e-3, 1.4e-3
VP = math.pi / 6 * D ** 3


def test_lattice_is_symmetric_and_carries_the_grain_volume():
    p = sections.sphere_lattice()
    assert len(p) == 280
    assert np.allclose(p.mean(axis=0), 0.0)
    assert (np.linalg.norm(p, axis=1) <= 0.5).all()


def test_pixel_areas_inside_the_wall_sum_to_the_tube_section():
    for n in (7, 14, 20):
        f = sections.pixel_inside_fraction(RT, n)
        assert abs(f.sum() * (2 * RT / n) ** 2 / (math.pi * RT ** 2) - 1) < 2e-3


def _deposited(image, n, width):
    inside = sections.pixel_inside_fraction(RT, n)
    return float((image * inside * (2 * RT / n) ** 2 * width).sum())


def test_one_grain_deposits_its_volume_and_half_of_it_on_a_slice_face():
    n, w = 14, 3.5e-3
    one = np.array([[0.2, 0.3e-3, -0.6e-3]])
    img = sections.solids_fraction_image(one, D, 0.2, w, RT, n)
    assert abs(_deposited(img, n, w) / VP - 1) < 1e-12
    face = one + np.array([0.5 * w, 0, 0])
    img = sections.solids_fraction_image(face, D, 0.2, w, RT, n)
    assert abs(_deposited(img, n, w) / VP - 0.5) < 1e-12
    far = one + np.array([0.5 * w + 0.51 * D, 0, 0])
    assert sections.solids_fraction_image(far, D, 0.2, w, RT, n).sum() == 0.0
    # a periodic tube wraps the slice: the grain at x = L - 0.5 mm is 1 mm from a slice at 0.5 mm
    img = sections.solids_fraction_image(np.array([[0.0495, 0, 0]]), D, 0.5e-3, w, RT, n, periodic=True, length=0.05)
    assert abs(_deposited(img, n, w) / VP - 1) < 1e-12


def test_uniform_centres_give_the_analytic_solids_fraction_in_the_core():
    rng = np.random.default_rng(4)
    rc = RT - 0.5 * D
    length, n_grains, n, w = 0.06, 60_000, 14, 0.05
    r = rc * np.sqrt(rng.uniform(size=n_grains))
    th = rng.uniform(0, 2 * np.pi, n_grains)
    pos = np.column_stack([rng.uniform(-0.5 * length, 0.5 * length, n_grains), r * np.cos(th), r * np.sin(th)])
    img = sections.solids_fraction_image(pos, D, 0.0, w, RT, n)
    expected = n_grains * VP / (math.pi * rc ** 2 * length)   # sum of grain volumes per volume (overlaps count)
    c = sections.pixel_centres(RT, n)
    half_diag = math.sqrt(2) * RT / n
    core = np.hypot(c[None, :], c[:, None]) + half_diag <= rc - 0.5 * D
    assert core.sum() >= 12
    # each core pixel sees ~ 60,000 × (w/L) × V_pix/V_c ≈ 400 grains' points: 5 % per pixel, 1.5 % on the mean
    assert abs(img[core].mean() / expected - 1) < 0.03
    assert np.all(np.abs(img[core] / expected - 1) < 0.2)


def test_layer_velocities_of_a_sheared_packing():
    edges = sections.layer_edges(RT, D)
    assert np.isclose(edges[0], -(RT - D / 2)) and np.isclose(edges[-1], RT - D / 2)
    assert np.allclose(np.diff(edges), D / 2)
    mid = 0.5 * (edges[1:] + edges[:-1])
    rng = np.random.default_rng(1)
    pos, vel = [], []
    for zc in mid:
        for _ in range(5):
            pos.append([0.26 + rng.uniform(-1.7e-3, 1.7e-3), rng.uniform(-1e-3, 1e-3), zc])
            vel.append([0.4 + 100.0 * zc, 0.0, 0.0])
    pos.append([0.26 + 2.0e-3, 0.0, mid[0]])   # outside the 3.5 mm slice: not counted
    vel.append([50.0, 0.0, 0.0])
    cnt, mean, rms = sections.layer_velocity(np.array(pos), np.array(vel), 0.26, 3.5e-3, edges)
    assert (cnt == 5).all()
    assert np.allclose(mean, 0.4 + 100.0 * mid)
    assert np.allclose(rms, 0.0, atol=1e-12)
    cnt, mean, rms = sections.layer_velocity(np.array(pos[:5]), np.array(vel[:5]), 0.26, 3.5e-3, edges)
    assert cnt[0] == 5 and (cnt[1:] == 0).all() and (mean[1:] == 0).all()
