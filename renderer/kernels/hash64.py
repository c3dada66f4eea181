"""The 64-bit integer hash every random number of Haze starts from."""

import numpy as np

from renderer.kernels import inline_kernel

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)


@inline_kernel
def mix64(x):
    """splitmix64 finaliser: a bijective avalanche on uint64 (passes BigCrush as a
    counter-based generator)."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)
