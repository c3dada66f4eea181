"""Interval arithmetic on numpy arrays: an interval is a pair (lo, hi) of float64 arrays,
one entry per box, and each rule returns an interval holding every value the operation
gives for inputs inside its input intervals (intervals.py, noise_intervals.py).

Unbounded ends are +-inf; a NaN from inf - inf or 0 * inf is resolved where it arises
(a product of finite values at 0 is 0; a caller turns any remaining NaN bound unbounded).
"""

from __future__ import annotations

import math

import numpy as np

INF = math.inf


def add(a, b):
    return a[0] + b[0], a[1] + b[1]


def sub(a, b):
    return a[0] - b[1], a[1] - b[0]


def mul(a, b):
    """Bounds of a product: the extremes of the four corner products."""
    with np.errstate(invalid="ignore"):
        p = np.stack([a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1]])
    p = np.where(np.isnan(p), 0.0, p)  # 0 * inf: the product of finite values there is 0
    return p.min(axis=0), p.max(axis=0)


def div(a, b):
    """safe_divide: a / b, 0 where b == 0; unbounded where b's interval holds 0."""
    straddles = (b[0] <= 0.0) & (b[1] >= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = (np.where(straddles, 1.0, 1.0 / b[1]), np.where(straddles, 1.0, 1.0 / b[0]))
    lo, hi = mul(a, inv)
    exact_zero = (b[0] == 0.0) & (b[1] == 0.0)
    lo = np.where(straddles, np.where(exact_zero, 0.0, -INF), lo)
    hi = np.where(straddles, np.where(exact_zero, 0.0, INF), hi)
    return lo, hi


def mono(f, a):
    """An increasing function at the ends."""
    with np.errstate(all="ignore"):
        return f(a[0]), f(a[1])


def hull(*xs):
    return np.minimum.reduce([x[0] for x in xs]), np.maximum.reduce([x[1] for x in xs])


def absolute(a):
    lo = np.where((a[0] <= 0.0) & (a[1] >= 0.0), 0.0, np.minimum(np.abs(a[0]), np.abs(a[1])))
    return lo, np.maximum(np.abs(a[0]), np.abs(a[1]))


def square(a):
    m = absolute(a)
    return m[0] * m[0], m[1] * m[1]


def const_range(a, lo, hi):
    """The constant interval [lo, hi], shaped like interval a."""
    return np.full_like(a[0], lo), np.full_like(a[0], hi)


def unbounded(a):
    return const_range(a, -INF, INF)


def clamp01(a):
    return np.clip(a[0], 0.0, 1.0), np.clip(a[1], 0.0, 1.0)


def power(a, b):
    """Cycles' safe_powf for a >= 0 (a^b, increasing in a for b >= 0); else unbounded."""
    if not (np.all(a[0] >= 0.0) and np.all(b[0] >= 0.0)):
        return unbounded(a)
    with np.errstate(all="ignore"):
        c = np.stack([a[0] ** b[0], a[0] ** b[1], a[1] ** b[0], a[1] ** b[1], np.zeros_like(a[0])])
    c = np.where(np.isnan(c), INF, c)
    return c.min(axis=0), c.max(axis=0)
