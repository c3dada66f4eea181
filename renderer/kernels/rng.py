"""Counter-based random numbers keyed by (seed, pixel, sample index, dimension).

A path's random numbers depend only on those four integers, never on the batch it was
traced in or the process that traced it, so any sample range can be rendered anywhere
and merged. `path_key` hashes (seed, pixel, sample) once per path; `uniform(key, dim)`
hashes the key with the dimension counter (splitmix64 finaliser, which passes BigCrush
as a counter-based generator).
"""

import numpy as np

from renderer.kernels import inline_kernel, kernel

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S40 = np.uint64(40)
_INV_2_24 = 1.0 / 16777216.0


@inline_kernel
def mix64(x):
    """splitmix64 finaliser: a bijective avalanche on uint64."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@kernel
def path_key(seed, pixel, sample):
    """Key of one path: a hash of (seed, pixel index, sample index)."""
    k = mix64(np.uint64(seed) * _GOLDEN + np.uint64(1))
    k = mix64(k ^ (np.uint64(pixel) * _GOLDEN))
    return mix64(k ^ (np.uint64(sample) * _M1 + _GOLDEN))


@inline_kernel
def uniform(key, dim):
    """Uniform float in [0, 1) for dimension `dim` of the path with `key`.

    24 bits, so the value is exactly representable in float32 and never rounds to 1.
    """
    h = mix64(key + (np.uint64(dim) + np.uint64(1)) * _GOLDEN)
    return float(h >> _S40) * _INV_2_24
