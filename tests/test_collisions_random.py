"""Counter-based generator (collisions.random): known answers, determinism, statistical quality."""

import numba
import numpy as np
import pytest
from numba import njit, prange
from scipy import stats

from collisions import random as cr

N = 1_000_000


def _hex(words):
    return " ".join(f"{int(w):08x}" for w in words)


# Random123 kat_vectors, philox4x32 10 rounds: counter (4 words), key (2 words) -> output (4 words).
KAT = [
    ((0, 0, 0, 0), (0, 0), "6627e8d5 e169c58d bc57ac4c 9b00dbd8"),
    ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, "408f276d 41c83b0e a20bc7c6 6d5451fd"),
    ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
     "d16cfe09 94fdcceb 5001e420 24126ea1"),
]


@pytest.mark.parametrize("ctr,key,expected", KAT)
@pytest.mark.parametrize("compiled", [True, False])
def test_philox4x32_vs_random123_known_answers(ctr, key, expected, compiled):
    fn = cr.philox4x32 if compiled else cr.philox4x32.py_func
    args = [np.uint64(c) for c in ctr] + [np.uint64(k) for k in key]
    assert _hex(fn(*args)) == expected


def test_key_functions_vs_py_func_bitwise():
    keys = [(0, 0, 0, 0, 0), (1, 2, 3, 4, 5), (2**63 - 17, 2**32 - 1, 2**32 - 1, 2**16 - 1, 2**48 - 1),
            (12345, 7, 99, cr.STREAM_WALL, 2**33 + 1)]
    for k in keys:
        assert cr.uniform(*k) == cr.uniform.py_func(*k)
        assert cr.uniform_pair(*k) == cr.uniform_pair.py_func(*k)
        assert cr.normal_pair(*k) == cr.normal_pair.py_func(*k)
        assert cr.normal(*k) == cr.normal.py_func(*k)
        assert cr.random_block(*k) == cr.random_block.py_func(*k)


def test_fill_helpers_vs_py_func():
    for fill in (cr.fill_uniform, cr.fill_normal):
        a, b = np.empty(16), np.empty(16)
        fill(3, 1, 4, cr.STREAM_INJECTION, 100, a)
        fill.py_func(3, 1, 4, cr.STREAM_INJECTION, 100, b)
        assert np.array_equal(a, b)
    for w in (np.uint64(0), np.uint64(2**64 - 1), np.uint64(12345678901234567890)):
        assert cr._bits_to_unit(w) == cr._bits_to_unit.py_func(w)
    assert cr._bits_to_unit(np.uint64(2**64 - 1)) < 1.0


def test_state_functions_vs_py_func_and_functional_form():
    a = cr.rng_state(7, 3, 11, cr.STREAM_COLLISION)
    b = cr.rng_state.py_func(7, 3, 11, cr.STREAM_COLLISION)
    assert np.array_equal(a, b) and a.dtype == np.int64
    seq_a = [cr.next_uniform(a), cr.next_normal(a), cr.next_normal_pair(a), cr.next_uniform_pair(a)]
    seq_b = [cr.next_uniform.py_func(b), cr.next_normal.py_func(b), cr.next_normal_pair.py_func(b),
             cr.next_uniform_pair.py_func(b)]
    assert seq_a == seq_b
    assert a[cr.RNG_DRAW] == 4 and b[cr.RNG_DRAW] == 4  # one draw per call
    assert seq_a[0] == cr.uniform(7, 3, 11, cr.STREAM_COLLISION, 0)
    assert seq_a[1] == cr.normal(7, 3, 11, cr.STREAM_COLLISION, 1)


def test_determinism_same_key_same_number_and_all_key_fields_matter():
    base = (5, 2, 1000, cr.STREAM_DISPERSION, 42)
    u = cr.uniform(*base)
    assert u == cr.uniform(*base)
    for i, delta in enumerate([1, 1, 1, 1, 1]):
        k = list(base)
        k[i] += delta
        assert cr.uniform(*k) != u, f"key field {i} ignored"
    # high bits of the draw counter (counter word 1) and of the seed (key word 1) matter
    assert cr.uniform(5, 2, 1000, 1, 42 + 2**32) != u
    assert cr.uniform(5 + 2**32, 2, 1000, 1, 42) != u
    # streams are distinct for the same draw
    streams = [cr.uniform(5, 2, 1000, s, 42) for s in range(cr.N_STREAMS)]
    assert len(set(streams)) == cr.N_STREAMS


def test_uniform_mean_variance_and_range():
    x = np.empty(N)
    cr.fill_uniform(1, 0, 0, cr.STREAM_INJECTION, 0, x)
    assert x.min() >= 0.0 and x.max() < 1.0
    # standard errors: mean 0.289/sqrt(N) = 2.9e-4, variance ~ 0.075/sqrt(N) = 7.5e-5; tolerance 5 sigma
    assert abs(x.mean() - 0.5) < 5 * np.sqrt(1 / 12 / N)
    assert abs(x.var() - 1 / 12) < 5 * np.sqrt(1 / 180 / N)


def test_uniform_chi_square_100_bins():
    x = np.empty(N)
    cr.fill_uniform(2, 1, 3, cr.STREAM_WALL, 0, x)
    counts, _ = np.histogram(x, bins=100, range=(0, 1))
    p = stats.chisquare(counts).pvalue
    assert p > 1e-3, p


def test_uniform_pairs_in_unit_square_chi_square():
    """2-D equidistribution: both halves of a block, 20 x 20 cells."""
    n = 400_000
    pairs = _uniform_pairs(3, n)
    h, _, _ = np.histogram2d(pairs[:, 0], pairs[:, 1], bins=20, range=[[0, 1], [0, 1]])
    assert stats.chisquare(h.ravel()).pvalue > 1e-3


@njit
def _uniform_pairs(seed, n):
    out = np.empty((n, 2))
    for i in range(n):
        a, b = cr.uniform_pair(seed, 0, 0, 0, i)
        out[i, 0] = a
        out[i, 1] = b
    return out


@njit
def _neighbour_samples(field, n):
    """u(key) and u(key with `field` + 1) for n base keys varying in the other fields."""
    a = np.empty(n)
    b = np.empty(n)
    for i in range(n):
        k = np.array([11, 3, i, 1, 7], dtype=np.int64)
        if field == 2:  # parcel: vary the draw instead
            k[2] = 5
            k[4] = i
        a[i] = cr.uniform(k[0], k[1], k[2], k[3], k[4])
        k[field] += 1
        b[i] = cr.uniform(k[0], k[1], k[2], k[3], k[4])
    return a, b


@pytest.mark.parametrize("field,name", [(0, "seed"), (1, "pass"), (2, "parcel"), (3, "stream"), (4, "draw")])
def test_independence_of_neighbouring_keys(field, name):
    n = 200_000
    a, b = _neighbour_samples(field, n)
    r = np.corrcoef(a, b)[0, 1]
    assert abs(r) < 5 / np.sqrt(n), (name, r)
    # the joint distribution of neighbours is uniform on the square
    h, _, _ = np.histogram2d(a, b, bins=10, range=[[0, 1], [0, 1]])
    assert stats.chisquare(h.ravel()).pvalue > 1e-3, name


def test_normal_moments_and_ks_vs_standard_normal():
    z = np.empty(N)
    cr.fill_normal(4, 0, 9, cr.STREAM_DISPERSION, 0, z)
    assert np.all(np.isfinite(z))
    assert abs(z.mean()) < 5 / np.sqrt(N)
    assert abs(z.var() - 1) < 5 * np.sqrt(2 / N)
    assert abs(stats.skew(z)) < 5 * np.sqrt(6 / N)
    assert abs(stats.kurtosis(z)) < 5 * np.sqrt(24 / N)
    assert stats.kstest(z, "norm").pvalue > 1e-3


@njit
def _normal_pairs(n):
    out = np.empty((n, 2))
    for i in range(n):
        a, b = cr.normal_pair(8, 1, 2, cr.STREAM_COLLISION, i)
        out[i, 0] = a
        out[i, 1] = b
    return out


def test_normal_pair_components_independent_standard_normals():
    n = 500_000
    z = _normal_pairs(n)
    assert abs(np.corrcoef(z[:, 0], z[:, 1])[0, 1]) < 5 / np.sqrt(n)
    # independence of squares too (Box-Muller radius/angle)
    assert abs(np.corrcoef(z[:, 0] ** 2, z[:, 1] ** 2)[0, 1]) < 5 / np.sqrt(n)
    for c in range(2):
        assert stats.kstest(z[:, c], "norm").pvalue > 1e-3


@njit(parallel=True)
def _parallel_fill(n_parcels, draws):
    out = np.empty((n_parcels, draws))
    for p in prange(n_parcels):
        rng = cr.rng_state(21, 4, p, cr.STREAM_DISPERSION)
        for d in range(draws):
            out[p, d] = cr.next_normal(rng)
    return out


def test_independent_of_thread_count():
    n_threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = _parallel_fill(1000, 50)
        numba.set_num_threads(n_threads)
        many = _parallel_fill(1000, 50)
    finally:
        numba.set_num_threads(n_threads)
    assert np.array_equal(one, many)
    # and equal to a serial evaluation of the same keys
    assert one[123, 17] == cr.normal(21, 4, 123, cr.STREAM_DISPERSION, 17)


@njit
def _ziggurat_sample(n, seed):
    """n normal pairs of one parcel stream, and which halves took the slow path."""
    z = np.empty(2 * n)
    slow = np.zeros(2 * n, dtype=np.bool_)
    for i in range(n):
        a, b = cr.random_block(seed, 2, 77, cr.STREAM_DISPERSION, i)
        for lane, w in enumerate((a, b)):
            idx = np.intp(w & cr._MASK8)
            slow[2 * i + lane] = ((w >> cr._S9) & cr._MASK52) >= cr._ZIG_K[idx]
        z[2 * i], z[2 * i + 1] = cr.normal_pair(seed, 2, 77, cr.STREAM_DISPERSION, i)
    return z, slow


def test_ziggurat_normals_fine_bins_and_tails():
    """N(0, 1) to the far tail: 200 equiprobable bins, and the rates beyond the ziggurat's
    base-strip edge r (the tail algorithm) and beyond 4 and 4.5 against the normal law."""
    n = 4_000_000
    z, slow = _ziggurat_sample(n, 31)
    assert 0.005 < slow.mean() < 0.02  # the wedge/tail paths are exercised (≈ 1 %)
    edges = stats.norm.ppf(np.linspace(0.0, 1.0, 201)[1:-1])
    counts = np.bincount(np.searchsorted(edges, z), minlength=200)
    assert stats.chisquare(counts).pvalue > 1e-3
    for t in (cr._ZIG_R, 4.0, 4.5):
        expected = z.size * 2.0 * stats.norm.sf(t)
        assert abs(np.sum(np.abs(z) > t) - expected) < 5.0 * np.sqrt(expected) + 1.0, t
    # the slow-path values alone are the normal law restricted to the wedges and the tail:
    # symmetric, and beyond r they are exactly the tail
    zs = z[slow]
    assert abs(np.mean(zs > 0) - 0.5) < 5 * 0.5 / np.sqrt(zs.size)
    assert np.sum(np.abs(z) > cr._ZIG_R) == np.sum(np.abs(zs) > cr._ZIG_R)
    assert abs(z.mean()) < 5 / np.sqrt(z.size) and abs(z.var() - 1) < 5 * np.sqrt(2 / z.size)


def test_ziggurat_slow_path_is_a_pure_function_of_the_key():
    """Halves that need the wedge or tail test draw auxiliary blocks of their own key: the
    pair is the same compiled and in Python, and a stream still advances one draw per pair."""
    z, slow = _ziggurat_sample(20_000, 5)
    draws = np.flatnonzero(slow.reshape(-1, 2).any(axis=1))[:20]
    assert draws.size == 20
    for d in draws:
        k = (5, 2, 77, cr.STREAM_DISPERSION, int(d))
        assert cr.normal_pair(*k) == cr.normal_pair.py_func(*k) == (z[2 * d], z[2 * d + 1])
    rng = cr.rng_state(5, 2, 77, cr.STREAM_DISPERSION, int(draws[0]))
    assert cr.next_normal_pair(rng) == (z[2 * draws[0]], z[2 * draws[0] + 1])
    assert rng[cr.RNG_DRAW] == draws[0] + 1
    # auxiliary blocks differ from the regular blocks of the same counter
    assert cr._aux_block(5, 2, 77, 1, 3, 0, 1) != cr.random_block(5, 2, 77, 1, 3)
    assert cr._aux_block(5, 2, 77, 1, 3, 0, 1) != cr._aux_block(5, 2, 77, 1, 3, 1, 1)
