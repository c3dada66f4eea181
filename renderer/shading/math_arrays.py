"""The node maths of math_ops.py over numpy arrays, for the exporter's constant folding
(addon/export/node_values.py): the kernels' own scalar functions as numpy ufuncs, so a Math
node, a colour Mix or a float Map Range folded at export gives what the shader interpreter computes from the
same inputs (float64, the kernels' contraction flag), and each Cycles semantic is written
once. Arguments broadcast as numpy's do; the operation code is an index into names.MATH_OPS
or names.BLEND_TYPES. Each compiles on its first call (seconds) into the kernel cache."""

import numpy as np
from numba import vectorize

from renderer.kernels import JIT_OPTIONS

from .math_ops import map_range, math_op, mix_channel

# A ufunc takes no error model (its loops never raise) and no reference counting flag.
_OPTIONS = {"nopython": True, "cache": True, "fastmath": JIT_OPTIONS["fastmath"]}


@vectorize(**_OPTIONS)
def _math(op, a, b, c):
    return math_op(op, a, b, c)


@vectorize(**_OPTIONS)
def _mix(blend, t, a, b):
    return mix_channel(blend, t, a, b)


@vectorize(**_OPTIONS)
def _map_range(kind, clamp, v, from_min, from_max, to_min, to_max, steps):
    return map_range(v, from_min, from_max, to_min, to_max, steps, kind, clamp)


def _f64(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def math_array(op: int, a, b, c) -> np.ndarray:
    """Math operation `op` (names.MATH_OPS index) of a, b and c, element-wise, float64."""
    return _math(np.int64(op), _f64(a), _f64(b), _f64(c))


def mix_array(blend: int, t, a, b) -> np.ndarray:
    """Colour Mix blend `blend` (names.BLEND_TYPES index) of a and b by factor t, per channel
    (t broadcast over the channels), float64."""
    return _mix(np.int64(blend), _f64(t), _f64(a), _f64(b))


def map_range_array(kind: int, clamp: bool, v, from_min, from_max, to_min, to_max, steps) -> np.ndarray:
    """Float Map Range of interpolation `kind` (names.MAP_RANGE_TYPES index) at v, element-wise."""
    return _map_range(np.int64(kind), np.bool_(clamp), _f64(v), _f64(from_min), _f64(from_max), _f64(to_min),
                      _f64(to_max), _f64(steps))
