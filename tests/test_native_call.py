"""renderer.kernels.native_call: a kernel calls a compiled function through its address
with the arguments it was compiled for, exceptions propagate, and scalars of other types
are refused when the caller compiles (they would be read as the wrong bits)."""

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from renderer.kernels import helper_kernel, kernel
from renderer.kernels.native_call import call_native, native_address


@helper_kernel
def _accumulate(out, k, v, pair, flag):
    out[k] += v + pair[0] * pair[1] + (100.0 if flag else 0.0)


@kernel
def _call_each(address, out):
    for k in range(out.shape[0]):
        call_native(address, (out, np.int64(k), np.float64(k), (2.0, 0.5 * k), k == 2))


def test_calls_with_every_argument_kind() -> None:
    out = np.zeros(4)
    address = native_address(_accumulate, out, np.int64(0), 0.0, (0.0, 0.0), False)
    _call_each(address, out)
    k = np.arange(4.0)
    np.testing.assert_array_equal(out, k + 2.0 * 0.5 * k + np.where(k == 2, 100.0, 0.0))


def test_same_types_same_address() -> None:
    out = np.zeros(2)
    a = native_address(_accumulate, out, np.int64(0), 0.0, (0.0, 0.0), False)
    b = native_address(_accumulate, np.ones(3), np.int64(5), 1.0, (1.0, 2.0), True)
    assert a == b != 0


@njit(error_model="python", cache=False)
def _divide(out, d):
    out[0] = 1 // d


@njit(error_model="python", cache=False)
def _call_divide(address, out, d):
    call_native(address, (out, d))


def test_exception_propagates() -> None:
    out = np.zeros(1, np.int64)
    address = native_address(_divide, out, np.int64(1))
    _call_divide(address, out, np.int64(2))
    assert out[0] == 0
    with pytest.raises(ZeroDivisionError):
        _call_divide(address, out, np.int64(0))


@pytest.mark.parametrize("value", [np.float32(1.0), np.int32(1)])
def test_refuses_scalars_python_does_not_make(value) -> None:
    @njit(cache=False)
    def bad(address, v):
        call_native(address, (v,))

    with pytest.raises(TypingError, match="int64, float64 or bool"):
        bad(0, value)
