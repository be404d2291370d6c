"""Counter-based random numbers for the particle kernels.

Every random number in a Lagrangian pass is a pure function of the key

    (seed, pass, parcel id, stream, draw counter)

so a parcel draws the same numbers whatever thread tracks it, whatever the
batch split, and a new pass (or a new seed) draws fresh noise.  There is no
hidden generator state: the caller keeps a draw counter per parcel and stream.

Generator: Philox-4x32-10 (Salmon, Moraes, Dror & Shaw 2011, "Parallel random
numbers: as easy as 1, 2, 3", SC'11), the counter-based generator of
Random123, cuRAND and numpy's ``Philox`` family.  It maps a 128-bit counter
and a 64-bit key to 128 random bits; the test suite checks the implementation
against the Random123 known-answer vectors.

Key layout (64-bit key, 128-bit counter, four 32-bit words):

    key      = seed                               (0 <= seed < 2**63)
    counter0 = draw & 0xffffffff                  (0 <= draw < 2**48)
    counter1 = (stream << 16) | (draw >> 32)      (0 <= stream < 2**16)
    counter2 = parcel                             (0 <= parcel < 2**32)
    counter3 = pass                               (0 <= pass < 2**32)

Each draw (one counter value) yields one uniform double, or one standard
normal, or a pair of independent standard normals (one per 64-bit half of the
block, by the 256-layer ziggurat of Marsaglia & Tsang 2000 in the 64-bit form
numpy uses).  The ziggurat is a rejection method: about 1 % of the halves need
more random bits, which come from *auxiliary* Philox blocks keyed by the same
(seed, pass, parcel, stream, draw) plus a flag and an attempt number in the key
(``_ziggurat_slow``), so a normal stays a pure function of its key.

Two calling styles, both ``@njit``:

* functional: ``uniform(seed, pass_, parcel, stream, draw)``, ``uniform_pair``,
  ``normal``, ``normal_pair`` (same arguments);
* a small state array ``rng = rng_state(seed, pass_, parcel, stream)``
  (int64[5]: seed, pass, parcel, stream, next draw), advanced in place by
  ``next_uniform(rng)``, ``next_uniform_pair(rng)``, ``next_normal(rng)``,
  ``next_normal_pair(rng)``; each call consumes exactly one draw.
  The collision kernels take such an array and advance it.
"""

import math

import numpy as np
from numba import njit

from .conf import JIT_FLAGS, KERNEL_FLAGS

# Streams (counter1 high bits): one per physical process, so switching a
# process on or off does not shift the noise of the others.
STREAM_INJECTION = 0
STREAM_DISPERSION = 1
STREAM_WALL = 2
STREAM_COLLISION = 3
N_STREAMS = 4

# Layout of an rng state array.
RNG_SEED = 0
RNG_PASS = 1
RNG_PARCEL = 2
RNG_STREAM = 3
RNG_DRAW = 4
RNG_STATE_SIZE = 5

# Philox-4x32 constants (Salmon et al. 2011; Random123 philox.h).
_M0 = np.uint64(0xD2511F53)
_M1 = np.uint64(0xCD9E8D57)
_W0 = np.uint64(0x9E3779B9)
_W1 = np.uint64(0xBB67AE85)
_MASK32 = np.uint64(0xFFFFFFFF)
_MASK16 = np.uint64(0xFFFF)
_S11 = np.uint64(11)
_S16 = np.uint64(16)
_S32 = np.uint64(32)
_TWO_M53 = 1.0 / 9007199254740992.0  # 2**-53
_TWO_PI = 2.0 * math.pi
_MASK8 = np.uint64(0xFF)
_MASK52 = np.uint64(0xFFFFFFFFFFFFF)
_S8 = np.uint64(8)
_S9 = np.uint64(9)
_ONE = np.uint64(1)
_AUX_FLAG = np.uint64(0x80000000)  # top bit of key word 1 (seed < 2**63 leaves it free)
_ZIG_MAX_TRIES = 1000  # cap of the ziggurat's rejection loop (P(reached) < 1e-1500)


def _ziggurat_tables(layers=256, r=3.6541528853610088):
    """Tables (ki, wi, fi) of the ziggurat for the standard normal (Marsaglia & Tsang 2000).

    f(x) = exp(−x²/2); layer i (1 ≤ i < 256) is the rectangle [0, x_i] × [f(x_i), f(x_{i−1})],
    x_0 = 0 < x_1 < … < x_255 = r, all of area v = r f(r) + ∫_r^∞ f (layer 0: the base
    strip [0, v/f(r)] × [0, f(r)], whose part beyond r stands for the tail).  A 64-bit word
    gives the layer (8 bits), a sign (1 bit) and a 52-bit fraction; x = fraction · wi[layer]
    is accepted at once when fraction < ki[layer] (x inside the part of the layer under f).
    r makes the recursion x_{i−1} = f⁻¹(f(x_i) + v/x_i) end at x_0 = 0 (to 4e-15).
    """
    m1 = 2.0**52
    f = lambda x: math.exp(-0.5 * x * x)  # noqa: E731
    v = r * f(r) + math.sqrt(0.5 * math.pi) * math.erfc(r / math.sqrt(2.0))
    q = v / f(r)
    ki = np.zeros(layers, dtype=np.uint64)
    wi = np.zeros(layers)
    fi = np.zeros(layers)
    ki[0] = np.uint64(int(r / q * m1))
    wi[0] = q / m1
    wi[layers - 1] = r / m1
    fi[0] = 1.0
    fi[layers - 1] = f(r)
    x_hi = r
    for i in range(layers - 2, 0, -1):
        x = math.sqrt(-2.0 * math.log(v / x_hi + f(x_hi)))
        ki[i + 1] = np.uint64(int(x / x_hi * m1))
        x_hi = x
        fi[i] = f(x)
        wi[i] = x / m1
    return ki, wi, fi, r


_ZIG_K, _ZIG_W, _ZIG_F, _ZIG_R = _ziggurat_tables()
_ZIG_INV_R = 1.0 / _ZIG_R


@njit(**JIT_FLAGS)
def philox4x32(c0, c1, c2, c3, k0, k1):
    """Philox-4x32-10 block: four 32-bit counter words and two key words → four 32-bit words.

    All arguments and results are ``np.uint64`` holding 32-bit values.
    Salmon et al. (2011); Random123 ``philox4x32_R`` with R = 10: ten rounds, the key bumped
    by the Weyl constants between rounds.
    """
    for r in range(10):
        if r > 0:
            k0 = (k0 + _W0) & _MASK32
            k1 = (k1 + _W1) & _MASK32
        p0 = _M0 * c0
        p1 = _M1 * c2
        hi0 = p0 >> _S32
        lo0 = p0 & _MASK32
        hi1 = p1 >> _S32
        lo1 = p1 & _MASK32
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
    return c0, c1, c2, c3


@njit(**JIT_FLAGS)
def random_block(seed, pass_, parcel, stream, draw):
    """128 random bits for one key, as two 64-bit words ``(a, b)`` (``np.uint64``).

    Arguments are non-negative integers within the ranges of the module docstring.
    """
    s = np.uint64(seed)
    return _keyed_block(s & _MASK32, s >> _S32, pass_, parcel, stream, draw)


@njit(**JIT_FLAGS)
def _keyed_block(k0, k1, pass_, parcel, stream, draw):
    """Two 64-bit words of the Philox block of the counter (draw, stream, parcel, pass) under
    the key (k0, k1)."""
    d = np.uint64(draw)
    c0 = d & _MASK32
    c1 = ((np.uint64(stream) & _MASK16) << _S16) | ((d >> _S32) & _MASK16)
    c2 = np.uint64(parcel) & _MASK32
    c3 = np.uint64(pass_) & _MASK32
    o0, o1, o2, o3 = philox4x32(c0, c1, c2, c3, k0, k1)
    return (np.uint64(o0) << _S32) | np.uint64(o1), (np.uint64(o2) << _S32) | np.uint64(o3)


@njit(**JIT_FLAGS)
def _bits_to_unit(a):
    """Top 53 bits of a 64-bit word → double in [0, 1)."""
    return np.float64(a >> _S11) * _TWO_M53


@njit(**JIT_FLAGS)
def uniform(seed, pass_, parcel, stream, draw):
    """Uniform double in [0, 1) (53 random bits) for the key (seed, pass, parcel, stream, draw)."""
    a, _ = random_block(seed, pass_, parcel, stream, draw)
    return _bits_to_unit(np.uint64(a))


@njit(**JIT_FLAGS)
def uniform_pair(seed, pass_, parcel, stream, draw):
    """Two independent uniforms in [0, 1) from one key (the two 64-bit halves of the block)."""
    a, b = random_block(seed, pass_, parcel, stream, draw)
    return _bits_to_unit(np.uint64(a)), _bits_to_unit(np.uint64(b))


@njit(**JIT_FLAGS)
def _aux_block(seed, pass_, parcel, stream, draw, lane, attempt):
    """Auxiliary block ``attempt`` ≥ 1 of half ``lane`` (0, 1) of a draw, for the ziggurat's rare
    slow path: the draw's counter under the key (seed low word XOR (2 attempt + lane), seed high
    word with the flag bit set).  No regular block has the flag, so the auxiliary bits are
    independent of every regular draw and of each other within a pass."""
    s = np.uint64(seed)
    k0 = (s & _MASK32) ^ (np.uint64(2 * attempt + lane) & _MASK32)
    return _keyed_block(k0, (s >> _S32) | _AUX_FLAG, pass_, parcel, stream, draw)


@njit(**JIT_FLAGS)
def _ziggurat_slow(w, seed, pass_, parcel, stream, draw, lane):
    """Standard normal from the 64-bit word w by the ziggurat (numpy's ``random_standard_normal``
    algorithm), taking the extra bits it may need from ``_aux_block`` (attempts 1, 2, …): the
    wedge test takes one uniform from a block and, if it rejects, restarts with the block's
    other half as the new word; the tail (Marsaglia 1964) takes two uniforms per try."""
    attempt = 0
    while attempt < _ZIG_MAX_TRIES:
        idx = np.intp(w & _MASK8)
        neg = ((w >> _S8) & _ONE) != np.uint64(0)
        rabs = (w >> _S9) & _MASK52
        x = np.float64(rabs) * _ZIG_W[idx]
        if neg:
            x = -x
        if rabs < _ZIG_K[idx]:
            return x
        if idx == 0:  # tail beyond r: r + e1/r, accepted if 2 e2 > (e1/r)², e1, e2 ~ Exp(1)
            while attempt < _ZIG_MAX_TRIES:
                attempt += 1
                a, b = _aux_block(seed, pass_, parcel, stream, draw, lane, attempt)
                xx = -_ZIG_INV_R * math.log1p(-_bits_to_unit(np.uint64(a)))
                yy = -math.log1p(-_bits_to_unit(np.uint64(b)))
                if yy + yy > xx * xx:
                    return -(_ZIG_R + xx) if neg else _ZIG_R + xx
            return 0.0
        # wedge: accept x with probability (f(x) − f(x_i)) / (f(x_{i−1}) − f(x_i))
        attempt += 1
        a, b = _aux_block(seed, pass_, parcel, stream, draw, lane, attempt)
        if (_ZIG_F[idx - 1] - _ZIG_F[idx]) * _bits_to_unit(np.uint64(a)) + _ZIG_F[idx] < math.exp(-0.5 * x * x):
            return x
        w = np.uint64(b)
    return 0.0


@njit(**JIT_FLAGS)
def _ziggurat(w, seed, pass_, parcel, stream, draw, lane):
    """Standard normal from the 64-bit word w: the ziggurat's fast path (≈ 99 % of words),
    else ``_ziggurat_slow``."""
    idx = np.intp(w & _MASK8)
    rabs = (w >> _S9) & _MASK52
    if rabs < _ZIG_K[idx]:
        x = np.float64(rabs) * _ZIG_W[idx]
        return -x if ((w >> _S8) & _ONE) != np.uint64(0) else x
    return _ziggurat_slow(w, seed, pass_, parcel, stream, draw, lane)


@njit(**JIT_FLAGS)
def normal_pair(seed, pass_, parcel, stream, draw):
    """Two independent standard normals from one key: the ziggurat (Marsaglia & Tsang 2000;
    256 layers, 52-bit fractions, as numpy) on each 64-bit half of the Philox block; the rare
    words that need more bits take them from auxiliary blocks of the same key
    (``_ziggurat_slow``), so the pair is a pure function of the key.
    """
    a, b = random_block(seed, pass_, parcel, stream, draw)
    return (_ziggurat(np.uint64(a), seed, pass_, parcel, stream, draw, 0),
            _ziggurat(np.uint64(b), seed, pass_, parcel, stream, draw, 1))


@njit(**JIT_FLAGS)
def normal(seed, pass_, parcel, stream, draw):
    """One standard normal for the key (the first of ``normal_pair``)."""
    z1, _ = normal_pair(seed, pass_, parcel, stream, draw)
    return z1


@njit(**JIT_FLAGS)
def rng_state(seed, pass_, parcel, stream, draw=0):
    """New state array int64[5] = (seed, pass, parcel, stream, next draw) for the ``next_*`` functions."""
    s = np.empty(RNG_STATE_SIZE, dtype=np.int64)
    s[RNG_SEED] = seed
    s[RNG_PASS] = pass_
    s[RNG_PARCEL] = parcel
    s[RNG_STREAM] = stream
    s[RNG_DRAW] = draw
    return s


@njit(**KERNEL_FLAGS)
def next_uniform(rng):
    """Uniform in [0, 1) from state ``rng`` (int64[5]); advances the draw counter ``rng[4]`` by one."""
    d = rng[RNG_DRAW]
    rng[RNG_DRAW] = d + 1
    return uniform(rng[RNG_SEED], rng[RNG_PASS], rng[RNG_PARCEL], rng[RNG_STREAM], d)


@njit(**KERNEL_FLAGS)
def next_uniform_pair(rng):
    """Two independent uniforms in [0, 1) from state ``rng``; advances the draw counter by one."""
    d = rng[RNG_DRAW]
    rng[RNG_DRAW] = d + 1
    return uniform_pair(rng[RNG_SEED], rng[RNG_PASS], rng[RNG_PARCEL], rng[RNG_STREAM], d)


@njit(**KERNEL_FLAGS)
def next_normal(rng):
    """Standard normal from state ``rng``; advances the draw counter by one."""
    d = rng[RNG_DRAW]
    rng[RNG_DRAW] = d + 1
    return normal(rng[RNG_SEED], rng[RNG_PASS], rng[RNG_PARCEL], rng[RNG_STREAM], d)


@njit(**KERNEL_FLAGS)
def next_normal_pair(rng):
    """Two independent standard normals from state ``rng``; advances the draw counter by one."""
    d = rng[RNG_DRAW]
    rng[RNG_DRAW] = d + 1
    return normal_pair(rng[RNG_SEED], rng[RNG_PASS], rng[RNG_PARCEL], rng[RNG_STREAM], d)


@njit(**KERNEL_FLAGS)
def fill_uniform(seed, pass_, parcel, stream, draw0, out):
    """Fill ``out`` with uniforms for draws draw0, draw0+1, … (vectorised helper for tests and injection)."""
    for i in range(out.shape[0]):
        out[i] = uniform(seed, pass_, parcel, stream, draw0 + i)


@njit(**KERNEL_FLAGS)
def fill_normal(seed, pass_, parcel, stream, draw0, out):
    """Fill ``out`` with standard normals for draws draw0, draw0+1, … (one draw per value)."""
    for i in range(out.shape[0]):
        out[i] = normal(seed, pass_, parcel, stream, draw0 + i)
