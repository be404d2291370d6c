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


def test_slab_volume_of_a_sphere():
    r = 0.5 * D
    assert np.isclose(sections.slab_volume(np.array([0.0]), r, 4 * r)[0], VP)
    assert np.isclose(sections.slab_volume(np.array([2 * r]), r, 4 * r)[0], 0.5 * VP)   # centre on a face
    assert np.isclose(sections.slab_volume(np.array([0.0]), r, 2 * r * 0.5)[0],        # |x| < r/2: π(r²t − t³/3)
                      math.pi * 2 * (r ** 2 * r / 2 - (r / 2) ** 3 / 3))
    assert sections.slab_volume(np.array([3 * r]), r, 4 * r)[0] == 0.0


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
    img = sections.solids_fraction_image(pos, D, 0.0, w, RT, n, sub=4)   # coarser chords: the statistics are tested
    expected = n_grains * VP / (math.pi * rc ** 2 * length)   # sum of grain volumes per volume (overlaps count)
    c = sections.pixel_centres(RT, n)
    half_diag = math.sqrt(2) * RT / n
    core = np.hypot(c[None, :], c[:, None]) + half_diag <= rc - 0.5 * D
    assert core.sum() >= 12
    # each core pixel sees ~ 60,000 × (w/L) × V_pix/V_c ≈ 400 grains' points: 5 % per pixel, 1.5 % on the mean
    assert abs(img[core].mean() / expected - 1) < 0.03
    assert np.all(np.abs(img[core] / expected - 1) < 0.2)


def test_image_orientation_and_the_pixels_at_the_wall():
    """Rows are z, columns y; a grain, also one against the wall, fills each pixel with its
    volume there over the pixel's volume inside the wall (an independent Monte-Carlo estimate of
    the sphere's volume per pixel, 10⁶ points: 1-2 % in the pixels compared)."""
    n, w = 14, 3.5e-3
    h = 2 * RT / n
    img = sections.solids_fraction_image(np.array([[0.0, 1.5e-3, -2.0e-3]]), D, 0.0, w, RT, n)
    iz, iy = np.unravel_index(np.argmax(img), img.shape)
    c = sections.pixel_centres(RT, n)
    assert c[iz] < 0 < c[iy]
    # a grain touching the wall at the bottom: its volume per pixel from random points in the sphere
    centre = np.array([0.0, 0.2e-3, -(RT - D / 2)])
    img = sections.solids_fraction_image(centre[None], D, 0.0, w, RT, n)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-0.5, 0.5, (2_000_000, 3)) * D
    pts = pts[(pts ** 2).sum(axis=1) <= D * D / 4] + centre
    jy = np.floor((pts[:, 1] + RT) / h).astype(int)
    jz = np.floor((pts[:, 2] + RT) / h).astype(int)
    share = np.bincount(jz * n + jy, minlength=n * n).reshape(n, n) / len(pts)
    inside = sections.pixel_inside_fraction(RT, n)
    expected = share * VP / (np.maximum(inside, 1e-9) * h * h * w)
    big = (inside >= 0.5) & (share > 0.02)
    assert big.sum() >= 6 and np.any(inside[big] < 0.95)   # wall pixels among them
    assert np.allclose(img[big], expected[big], rtol=0.03)
    assert (img[inside < 0.5] == 0).all()


def test_layer_velocity_rms_is_the_population_rms():
    edges = sections.layer_edges(RT, D)
    rng = np.random.default_rng(3)
    z = rng.uniform(edges[0], edges[-1], 300)
    pos = np.column_stack([rng.uniform(-1.7e-3, 1.7e-3, 300), np.zeros(300), z])
    vel = np.column_stack([rng.normal(0.3, 0.05, 300), np.zeros(300), np.zeros(300)])
    cnt, mean, rms = sections.layer_velocity(pos, vel, 0.0, 3.5e-3, edges)
    k = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, len(edges) - 2)
    for b in range(len(edges) - 1):
        assert cnt[b] == (k == b).sum()
        assert np.isclose(mean[b], vel[k == b, 0].mean()) and np.isclose(rms[b], vel[k == b, 0].std())


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


def test_radial_layers_of_a_vertical_tube():
    edges = sections.radial_layer_edges(RT, D)
    assert edges[0] == 0 and np.isclose(edges[-1], RT - D / 2) and np.allclose(np.diff(edges), D / 2)
    # grains on a ring of radius 1.0 mm at 0.3 m/s, one on the axis at 0.1 m/s
    th = np.linspace(0, 2 * np.pi, 7)[:-1]
    pos = np.vstack([[0.1, 0, 0], np.column_stack([np.full(6, 0.1), 1e-3 * np.cos(th), 1e-3 * np.sin(th)])])
    vel = np.zeros_like(pos)
    vel[0, 0], vel[1:, 0] = 0.1, 0.3
    cnt, mean, rms = sections.layer_velocity(pos, vel, 0.1, 3.5e-3, edges, radial=True)
    assert list(cnt) == [1, 6, 0, 0] and np.allclose(mean[:2], [0.1, 0.3])
