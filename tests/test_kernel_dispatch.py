"""Kernel.__call__ reuses the previous call's compiled entry point only for arguments of the
same types: a changed dtype, layout or tuple must go through numba's dispatch again (a
reused entry point would read the new arguments as the old types)."""

import numpy as np

from renderer.kernels import kernel


@kernel
def _weighted_sum(values, pair):
    total = 0.0
    for i in range(values.shape[0]):
        total += values[i] * pair[0][i] + pair[1]
    return total


def test_same_types_reuse_the_entry_point_and_others_dispatch_again():
    weights = np.arange(4, dtype=np.float64)
    pair = (weights, 0.5)
    floats = np.array([1.0, 2.0, 3.0, 4.0])
    expected = float(np.sum(floats * weights + 0.5))
    assert _weighted_sum(floats, pair) == expected
    memo = _weighted_sum.__dict__["_last_call"]
    assert _weighted_sum(floats * 2.0, pair) == 2.0 * expected - 2.0  # same key: reused
    assert _weighted_sum.__dict__["_last_call"] is memo
    strided = np.array([1.0, 9.0, 2.0, 9.0, 3.0, 9.0, 4.0, 9.0])[::2]
    assert _weighted_sum(strided, pair) == expected  # another layout: dispatched again
    other = (weights.astype(np.float32), 0.5)
    assert _weighted_sum(floats, other) == expected  # a new tuple of other types
    assert _weighted_sum(floats, pair) == expected  # and back
