"""Interval bounds of Cycles' Noise Texture (svm/noise.h, fractal_noise.h, noisetex.h,
mirrored in fractal.py) in every dimension and fractal type: the Noise rule of intervals.py.

Perlin noise. perlin_n (n = 1..4) is a blend of the 2^n lattice corners' gradient values:
corner c's weight is the product over the axes of s(f_i) (c_i = 1) or 1 - s(f_i)
(c_i = 0), with f in [0, 1)^n the point's offset in its lattice cell and s the quintic
fade, which maps [0, 1] onto [0, 1]; so the weights are >= 0 and sum to 1. With the
corner's offsets d_i = f_i - c_i (|d_i| <= 1) its gradient value is, by the gradient sets
(grad1..grad4):
  1D: g d with g in {+-1 .. +-8}:              |.| <= M1 = 8 |d|
  2D: +-d_x +- 2 d_y or +-d_y +- 2 d_x:        |.| <= M2 = a + b + max(a, b)
  3D: +-d_i +- d_j, two of the three axes:     |.| <= M3 = a + b + c - min(a, b, c)
  4D: +-d_i +- d_j +- d_k, three of the four:  |.| <= M4 = sum |d_i| - min |d_i|
(a, b, ... the |d_i|), and each bound is met by some gradient of the set. Hence
|perlin_n(f)| <= F_n(f) = sum_c w_c(f) M_n(|d_c|), whatever the lattice hash gives, and
|snoise_n| <= noise_scale_n * max F_n (noise_scale: 0.25, 0.6616, 0.982, 0.8344).
  1D: F_1 = 8 G(f) with G(f) = (1 - s(f)) f + s(f) (1 - f) = f + s(f) (1 - 2 f) <= 1/2
      (for f <= 1/2, s(f) <= s(1/2) = 1/2 as s increases, so G(f) <= f + (1 - 2 f) / 2;
      G(1 - f) = G(f)): max F_1 = 4 (met at f = 1/2), |snoise_1d| <= 1 exactly.
  2D, 3D, 4D: max F_n <= PERLIN_SUP[n] = 1.52, 1.04, 1.56 (the maxima are about 1.5112,
      1.0364, 1.5366, searched numerically), certified by certify_perlin_sup: F_n is
      invariant under f_i -> 1 - f_i (s(1 - t) = 1 - s(t) swaps the corners) and under
      permutations of the axes (M_n is symmetric), so max F_n is its max over
      0 <= f_1 <= ... <= f_n <= 1/2; on a box of f every weight factor and |d_i| is
      monotone in f_i and M_n increases in each |d_i|, so the sum of the factors' and
      M_n's values at the box's worst ends bounds F_n there; boxes whose bound exceeds
      PERLIN_SUP[n] are bisected until none is left (tests/test_noise_intervals.py runs it).
(The plain bounds M_n <= 2 sum |d_i| (2D), sum |d_i| (3D, 4D) give max F_n <= 2, 3/2, 2.)

Fractals (detail D + rmd clamped to [0, 15], roughness r >= 0, pwr_i = r^i, s_i the noise
of octave i, each in [-N, N], N = snoise_bound(n)), evaluated on intervals as written:
  fBM: sum_i pwr_i s_i (+ rmd pwr_{D+1} s_{D+1}); normalized, 0.5 + 0.5 sum / maxamp is a
      convex combination of the s_i, and the fractional mix of two such, so in 0.5 +- N/2.
  Multifractal: prod_{i<=D} (1 + pwr_i s_i) * (1 + rmd pwr_{D+1} s_{D+1}).
  Hetero Terrain: (offset + s_0) prod_{1<=i<=D} (1 + (s_i + offset) pwr_i)
      * (1 + rmd (s_{D+1} + offset) pwr_{D+1}) (value += inc * value, as a product).
  Hybrid: value += w_i (s_i + offset) pwr_i with w_0 = 1, w_{i+1} = min(w_i gain signal_i, 1),
      stopping once w <= 0.001: the loop runs on intervals, and every value it can stop
      at (w's interval reaching 0.001) joins the result.
  Ridged: signal_i = (offset - |s_i|)^2 w_i, w_i = clamp(signal_{i-1} gain, 0, 1), value =
      sum pwr_i signal_i (no fractional octave).
Each recurrence runs for every integer detail the detail interval allows (rmd's interval
with it); the result is their hull. Distortion only moves the point, and the colour's
channels are the same fractal at seeded points, so all four outputs share the bound.

Rounding: the interpreter runs these in float32 (or float64); every interval operation
here is widened by REL times its result's magnitude (16x float32's 2^-24, which also
covers Cycles' different association, e.g. value + inc * value), and N by NOISE_PAD for
the noise's own rounding (its weights and offsets, tens of float32 operations).
"""

from __future__ import annotations

import itertools

import numpy as np

from . import interval_arith as ia
from .fractal import T_FBM, T_HETERO, T_HYBRID, T_MULTI, T_RIDGED

NOISE_SCALE = {1: 0.25, 2: 0.6616, 3: 0.9820, 4: 0.8344}  # noise.h noise_scale1..4
PERLIN_SUP = {1: 4.0, 2: 1.52, 3: 1.04, 4: 1.56}  # bounds of max F_n (module docstring)
NOISE_PAD = 1e-5
REL = 1e-6
HYBRID_STOP = 0.001  # Hybrid Multifractal's loop runs while weight > 0.001
MAX_DETAIL = 15


def snoise_bound(dim: int) -> float:
    """|snoise| of dimension dim is at most this (the module docstring's proof)."""
    return NOISE_SCALE[dim] * PERLIN_SUP[dim] * (1.0 + NOISE_PAD)


# ------------------------------------------------------------------ the certificate


def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _gradient_bound(dim: int, d: list) -> np.ndarray:
    """M_n(|d|): the largest |gradient value| of the dimension's set at offsets |d|."""
    if dim == 1:
        return 8.0 * d[0]
    if dim == 2:
        return d[0] + d[1] + np.maximum(d[0], d[1])
    return sum(d) - np.minimum.reduce(d)


def perlin_upper(dim: int, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Upper bound of F_n over boxes [lo, hi] ((K, n), inside [0, 1]^n): each corner's
    weight factors and offsets at their largest ends (they are monotone in f_i)."""
    total = np.zeros(lo.shape[0])
    for corner in itertools.product((0, 1), repeat=dim):
        w = np.ones(lo.shape[0])
        d = []
        for i, c in enumerate(corner):
            w = w * (_fade(hi[:, i]) if c else 1.0 - _fade(lo[:, i]))
            d.append(1.0 - lo[:, i] if c else hi[:, i])
        total += w * _gradient_bound(dim, d)
    return total


def certify_perlin_sup(dim: int, bound: float, max_boxes: int = 4_000_000) -> bool:
    """True if F_n <= bound on all of [0, 1]^n: branch and bound over the fundamental
    domain 0 <= f_1 <= ... <= f_n <= 1/2 (module docstring). False if it gives up."""
    lo, hi = np.zeros((1, dim)), np.full((1, dim), 0.5)
    while len(lo):
        in_domain = np.all(np.maximum.accumulate(lo, axis=1) <= hi, axis=1)  # meets f sorted
        keep = in_domain & (perlin_upper(dim, lo, hi) > bound - 1e-12)  # 1e-12: float64 slack
        lo, hi = lo[keep], hi[keep]
        if len(lo) > max_boxes or (len(lo) and np.max(hi - lo) < 1e-7):
            return False
        rows = np.arange(len(lo))
        axis = np.argmax(hi - lo, axis=1)
        mid = 0.5 * (lo[rows, axis] + hi[rows, axis])
        upper_lo, lower_hi = lo.copy(), hi.copy()
        lower_hi[rows, axis] = mid
        upper_lo[rows, axis] = mid
        lo, hi = np.vstack([lo, upper_lo]), np.vstack([lower_hi, hi])
    return True


# ------------------------------------------------------------------ rounded interval steps


def _pad(a):
    with np.errstate(invalid="ignore"):
        m = np.maximum(np.abs(a[0]), np.abs(a[1]))
        pad = np.where(np.isfinite(m), REL * m + 1e-37, 0.0)
    return a[0] - pad, a[1] + pad


def _add(a, b):
    return _pad(ia.add(a, b))


def _sub(a, b):
    return _pad(ia.sub(a, b))


def _mul(a, b):
    return _pad(ia.mul(a, b))


def _const(like, lo, hi=None):
    return ia.const_range(like, lo, lo if hi is None else hi)


class _Detail:
    """The integer details D a detail interval allows, and rmd's interval for each."""

    def __init__(self, detail) -> None:
        self.d = (np.clip(detail[0], 0.0, MAX_DETAIL), np.clip(detail[1], 0.0, MAX_DETAIL))
        self.lo, self.hi = np.floor(self.d[0]), np.floor(self.d[1])

    def reach(self, k: int) -> np.ndarray:
        return (self.lo <= k) & (k <= self.hi)

    def rmd(self, k: int):
        return np.where(self.lo == k, self.d[0] - k, 0.0), np.where(self.hi == k, self.d[1] - k, 1.0)


def _join(result, mask, x):
    """result's hull with x where mask."""
    return (np.where(mask, np.minimum(result[0], x[0]), result[0]),
            np.where(mask, np.maximum(result[1], x[1]), result[1]))


# ------------------------------------------------------------------ fractal recurrences


def _fbm(s, det, r, normalize):
    one = _const(r, 1.0)
    if normalize:  # convex combinations of the octaves' noise
        return _add(_mul(_const(r, 0.5), ia.hull(*(s(k) for k in range(MAX_DETAIL + 2)))), _const(r, 0.5))
    result, total, pwr = _const(r, ia.INF, -ia.INF), _const(r, 0.0), one
    for k in range(MAX_DETAIL + 1):
        total = _add(total, _mul(pwr, s(k)))
        pwr = _mul(pwr, r)
        result = _join(result, det.reach(k), _add(total, _mul(det.rmd(k), _mul(pwr, s(k + 1)))))
    return result


def _multi(s, det, r):
    one = _const(r, 1.0)
    result, value, pwr = _const(r, ia.INF, -ia.INF), one, one
    for k in range(MAX_DETAIL + 1):
        value = _mul(value, _add(one, _mul(pwr, s(k))))
        pwr = _mul(pwr, r)
        last = _add(one, _mul(det.rmd(k), _mul(pwr, s(k + 1))))
        result = _join(result, det.reach(k), _mul(value, last))
    return result


def _hetero(s, det, r, offset):
    one = _const(r, 1.0)
    result, value, pwr = _const(r, ia.INF, -ia.INF), _add(offset, s(0)), r
    for k in range(MAX_DETAIL + 1):
        if k >= 1:
            value = _mul(value, _add(one, _mul(_add(s(k), offset), pwr)))
            pwr = _mul(pwr, r)
        last = _add(one, _mul(det.rmd(k), _mul(_add(s(k + 1), offset), pwr)))
        result = _join(result, det.reach(k), _mul(value, last))
    return result


def _hybrid(s, det, r, offset, gain):
    one = _const(r, 1.0)
    result, value, pwr, weight = _const(r, ia.INF, -ia.INF), _const(r, 0.0), one, one
    alive = np.ones_like(r[0], bool)  # the loop can still be running at step k
    with np.errstate(invalid="ignore"):
        for k in range(MAX_DETAIL + 1):
            # stopping before step k (weight <= 0.001) with D >= k leaves value as it is
            result = _join(result, alive & (weight[0] <= HYBRID_STOP) & (det.hi >= k), value)
            alive &= weight[1] > HYBRID_STOP
            w = (np.minimum(np.maximum(weight[0], HYBRID_STOP), 1.0), np.minimum(weight[1], 1.0))
            signal = _mul(_add(s(k), offset), pwr)
            pwr = _mul(pwr, r)
            value = _add(value, _mul(w, signal))
            weight = _mul(w, _mul(gain, signal))
            # D = k: the fractional octave, added only if weight > 0.001 (rmd >= 0: hull with 0)
            w = (np.minimum(np.maximum(weight[0], HYBRID_STOP), 1.0), np.minimum(weight[1], 1.0))
            term = _mul(det.rmd(k), _mul(w, _mul(_add(s(k + 1), offset), pwr)))
            can = weight[1] > HYBRID_STOP
            term = (np.where(can, np.minimum(term[0], 0.0), 0.0),
                    np.where(can, np.maximum(term[1], 0.0), 0.0))
            last = _add(value, term)
            result = _join(result, alive & det.reach(k), last)
    return result


def _ridged(s, det, r, offset, gain):
    def ridge(k):  # (offset - |s_k|)^2
        return _pad(ia.square(_sub(offset, ia.absolute(s(k)))))

    signal = ridge(0)
    result, value, pwr = _join(_const(r, ia.INF, -ia.INF), det.reach(0), signal), signal, r
    for k in range(1, MAX_DETAIL + 1):
        weight = ia.clamp01(_mul(signal, gain))
        signal = _mul(ridge(k), weight)
        value = _add(value, _mul(signal, pwr))
        pwr = _mul(pwr, r)
        result = _join(result, det.reach(k), value)
    return result


def noise_interval(dim: int, kind: int, detail, roughness, offset, gain, normalize: bool):
    """Interval of the Noise texture's value (and of each colour channel) of dimension dim
    and fractal kind (fractal.TYPES index), given intervals of its parameters (arrays, one
    per box). Unbounded (-inf, inf) for a dimension or kind with no rule."""
    if dim not in NOISE_SCALE or kind not in (T_FBM, T_MULTI, T_HETERO, T_HYBRID, T_RIDGED):
        return ia.unbounded(detail)
    n = snoise_bound(dim)

    def s(k):  # octave k's snoise: the same bound at every octave and point
        return _const(detail, -n, n)

    det = _Detail(detail)
    r = (np.maximum(roughness[0], 0.0), np.maximum(roughness[1], 0.0))
    with np.errstate(invalid="ignore", over="ignore"):
        if kind == T_FBM:
            return _fbm(s, det, r, normalize)
        if kind == T_MULTI:
            return _multi(s, det, r)
        if kind == T_HETERO:
            return _hetero(s, det, r, offset)
        if kind == T_HYBRID:
            return _hybrid(s, det, r, offset, gain)
        return _ridged(s, det, r, offset, gain)
