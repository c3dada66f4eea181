"""The inlined maths of renderer.kernels.fastmath against numpy on dense grids of arguments.

Deterministic: the bound is a few units in the last place (the series are truncated below
1e-16 relative, see the module), so any wrong coefficient or reduction shows as an error
orders of magnitude larger.
"""

import math

import numpy as np
from numba import njit

from renderer.kernels import fastmath as fm
from renderer.kernels import simdmath as sm

ULPS = 8 * np.finfo(np.float64).eps  # 1.8e-15


@njit(cache=True)
def _log_all(x):
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = fm.log(x[i])
    return out


@njit(cache=True)
def _log1p_all(x):
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = fm.log1p(x[i])
    return out


@njit(cache=True)
def _atan2_all(y, x):
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = fm.atan2(y[i], x[i])
    return out


@njit(cache=True)
def _sincos_all(x):
    out = np.empty((x.shape[0], 2))
    for i in range(x.shape[0]):
        out[i, 0], out[i, 1] = fm.sincos(x[i])
    return out


def _rel(a, b):
    return np.max(np.abs(a - b) / np.maximum(np.abs(b), np.finfo(np.float64).tiny))


def test_log_and_log1p():
    rng = np.random.default_rng(1)
    x = np.concatenate([np.logspace(-307, 307, 200001), rng.uniform(0.5, 2.0, 100000),
                        1.0 - rng.integers(1, 1 << 24, 100000) / 2.0**24])
    assert _rel(_log_all(x), np.log(x)) < ULPS
    # log1p over the samplers' arguments (-u, -u * miss with u < 1) and beyond; it keeps full
    # relative precision for tiny arguments, where log(1 + x) would not.
    x = np.concatenate([-rng.integers(1, 1 << 24, 100000) / 2.0**24, -np.logspace(-20, -1e-12, 100001),
                        np.logspace(-20, 300, 100001), -1.0 + np.logspace(-15, -1, 1001)])
    assert _rel(_log1p_all(x), np.log1p(x)) < ULPS
    assert fm.log(0.0) == -np.inf and np.isnan(fm.log(-1.0)) and fm.log(np.inf) == np.inf
    assert fm.log1p(-1.0) == -np.inf


def test_atan2_all_quadrants_and_scales():
    rng = np.random.default_rng(2)
    angle = rng.uniform(-np.pi, np.pi, 400000)
    r = np.exp(rng.uniform(-300, 300, angle.shape[0]))
    y, x = r * np.sin(angle), r * np.cos(angle)
    edges_y = np.array([0.0, 1.0, -1.0, 0.0, 1e-300, 5.0, 1.0, -1.0, 3.0])
    edges_x = np.array([1.0, 0.0, 0.0, -1.0, 1.0, 1e-310, 1.0, -1.0, -3.0])
    y, x = np.concatenate([y, edges_y]), np.concatenate([x, edges_x])
    got, ref = _atan2_all(y, x), np.arctan2(y, x)
    assert np.max(np.abs(got - ref)) < 4 * np.finfo(np.float64).eps
    assert _rel(got, ref) < ULPS


def test_sincos():
    rng = np.random.default_rng(3)
    x = np.concatenate([np.linspace(-30.0, 30.0, 400001), rng.uniform(0, 4 * np.pi, 100000)])
    out = _sincos_all(x)
    assert np.max(np.abs(out[:, 0] - np.sin(x))) < 2 * np.finfo(np.float64).eps
    assert np.max(np.abs(out[:, 1] - np.cos(x))) < 2 * np.finfo(np.float64).eps
    # Relative precision too, away from the zeros (where only the absolute error means anything).
    away = np.abs(np.sin(x)) > 1e-3
    assert _rel(out[away, 0], np.sin(x[away])) < ULPS
    assert fm.sincos(1e6) == (np.sin(1e6), np.cos(1e6))


# The branch-free versions (renderer.kernels.simdmath), compiled in loops as the SIMD kernels
# use them.


@njit(cache=True)
def _simd_all(x, y):
    out = np.empty((x.shape[0], 7))
    for i in range(x.shape[0]):
        out[i, 0] = sm.exp_neg(x[i])
        out[i, 1] = sm.log1p(-y[i])
        out[i, 2] = sm.atan2(y[i], x[i] - 1.0)
        out[i, 3], out[i, 4] = sm.sincos(x[i])
        out[i, 5] = sm.log_normal(x[i] + 1e-300)
        out[i, 6] = sm.one_minus_exp_neg(x[i], math.exp(-x[i]))
    return out


def test_branch_free_versions_match_numpy():
    rng = np.random.default_rng(4)
    n = 300000
    x = np.concatenate([np.logspace(-20, np.log10(700.0), n), rng.uniform(0, 40.0, n)])
    y = np.concatenate([rng.integers(0, 1 << 24, n) / 2.0**24, -np.logspace(-20, 2, n)])
    out = _simd_all(x, y)
    assert _rel(out[:, 0], np.exp(-x)) < ULPS
    assert _rel(out[:, 1], np.log1p(-y)) < ULPS
    assert _rel(out[:, 2], np.arctan2(y, x - 1.0)) < ULPS
    small = np.abs(x) < 1e5
    assert np.max(np.abs(out[small, 3] - np.sin(x[small]))) < 2 * np.finfo(np.float64).eps
    assert np.max(np.abs(out[small, 4] - np.cos(x[small]))) < 2 * np.finfo(np.float64).eps
    assert _rel(out[:, 5], np.log(x + 1e-300)) < ULPS
    assert _rel(out[:, 6], -np.expm1(-x)) < ULPS
    # exp(-x) is 0 past 708 (where libm would give a subnormal) and at infinity.
    assert _simd_all(np.array([708.5, np.inf]), np.zeros(2))[:, 0].tolist() == [0.0, 0.0]
