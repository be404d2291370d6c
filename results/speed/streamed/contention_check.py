"""Do two processes slow each other on this machine? A compute-bound numba loop (exp, sin) and a
random read of a 200 MB and of a 32 MB array, each timed alone and as two processes at once:

    python contention_check.py alu; (python contention_check.py alu & python contention_check.py alu; wait)
    python contention_check.py mem; (python contention_check.py mem & python contention_check.py mem; wait)
"""
import math
import sys
import time

import numba
import numpy as np


@numba.njit(cache=True)
def alu(n):
    x = 0.0
    for i in range(n):
        x += math.exp(-1e-9 * i) * math.sin(1e-7 * i)
    return x


@numba.njit(cache=True)
def gather(a, idx):
    s = 0.0
    for _ in range(3):
        for i in range(idx.size):
            s += a[idx[i]]
    return s


if sys.argv[1] == "alu":
    alu(10)
    t = time.perf_counter()
    alu(200_000_000)
    print(f"{time.perf_counter() - t:.2f}")
else:
    a = np.random.rand(25_000_000)  # 200 MB
    idx = np.random.randint(0, a.size, 20_000_000)
    gather(a[:10], idx[:10] % 10)
    t = time.perf_counter()
    gather(a, idx)
    print(f"random {time.perf_counter() - t:.2f}")
    b = np.random.rand(4_000_000)  # 32 MB
    idx2 = np.random.randint(0, b.size, 20_000_000)
    t = time.perf_counter()
    gather(b, idx2)
    print(f"l3 {time.perf_counter() - t:.2f}")
