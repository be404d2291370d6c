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
normal, or a pair of independent standard normals (Box–Muller on the two
64-bit halves of the block).

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
    d = np.uint64(draw)
    k0 = s & _MASK32
    k1 = s >> _S32
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
def normal_pair(seed, pass_, parcel, stream, draw):
    """Two independent standard normals from one key (Box & Muller 1958).

    z₁ = sqrt(−2 ln(1 − u₁)) cos(2π u₂),  z₂ = sqrt(−2 ln(1 − u₁)) sin(2π u₂),
    with u₁, u₂ the two 53-bit uniforms of the Philox block (1 − u₁ ∈ (0, 1]).
    """
    a, b = random_block(seed, pass_, parcel, stream, draw)
    u1 = _bits_to_unit(np.uint64(a))
    u2 = _bits_to_unit(np.uint64(b))
    rad = math.sqrt(-2.0 * math.log(1.0 - u1))
    phi = _TWO_PI * u2
    return rad * math.cos(phi), rad * math.sin(phi)


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
