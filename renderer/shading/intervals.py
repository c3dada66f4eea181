"""Interval bounds of a shader program over boxes of space: what a procedural medium's
majorant is built from (renderer.media.procedural).

run_intervals() runs a program (program.py) on intervals instead of numbers: every register
holds a lower and an upper bound per box, (R, N) float64 arrays for N boxes, and each
operation maps its inputs' intervals to an interval that contains every value the
interpreter (interpreter.py) can produce from inputs inside them. Rules, by operation:

* position: the box itself (the caller gives world-space boxes).
* add, subtract, multiply, divide, multiply-add, min, max, abs, ...: standard interval
  arithmetic (interval_arith.py: a product's bounds are the extremes of the four corner
  products; a division by an interval containing 0 is unbounded).
* monotone functions (sqrt, exp, floor, Map Range with constant parameters, Clamp,
  smoothstep...): the function at the interval's ends.
* bounded functions (sine, fract, comparisons, Gradient, Checker's factor): their range.
* Mapping with constant location, rotation and scale: the affine image of the box,
  centre +- |M| radius.
* Color Ramp: the least and greatest table entry between the factor's ends (the lookup
  interpolates linearly between neighbouring entries, so it never leaves that hull).
* Noise (value and colour), every dimension and fractal type: a range proved from the
  structure of Cycles' Perlin noise and fractal recurrences (noise_intervals.py, not sampled).
* anything else: unbounded (-inf, inf); a later clamp may bound it again.

Rounding: registers are float32 and the interpreter computes in float64, so every result
is widened by REL_PAD times the largest magnitude among the operation's input and output
bounds (float32 rounding is 6e-8 relative, per operation).
"""

from __future__ import annotations

import math

import numpy as np

from .interval_arith import (
    INF,
    absolute,
    add,
    clamp01,
    const_range,
    div,
    hull,
    mono,
    mul,
    power,
    sub,
    unbounded,
)
from .names import MATH_OPS, RAMP_SIZE, VECTOR_OPS
from .noise_intervals import noise_interval
from .program import (
    I_A,
    I_B,
    I_C,
    I_D,
    I_DST,
    I_OP,
    I_P0,
    I_P1,
    I_P2,
    NOISE_NO_COLOR,
    NOISE_NORMALIZE,
    OPCODES,
    ShaderProgram,
)

REL_PAD = 1e-6

_MATH = {name: k for k, name in enumerate(MATH_OPS)}
_VECTOR = {name: k for k, name in enumerate(VECTOR_OPS)}


class Intervals:
    """The register file on intervals: lo, hi (R, N) float64, N boxes."""

    def __init__(self, registers: np.ndarray, n: int) -> None:
        init = np.asarray(registers, np.float64)[:, None]
        self.lo = np.repeat(init, n, axis=1)
        self.hi = self.lo.copy()

    def get(self, r: int) -> tuple[np.ndarray, np.ndarray]:
        # copies: an operation may write a register it reads
        return self.lo[r].copy(), self.hi[r].copy()

    def put(self, r: int, lo, hi, *inputs) -> None:
        """Store [lo, hi] widened for rounding; NaN bounds (inf - inf) become unbounded."""
        lo = np.where(np.isnan(lo), -INF, lo)
        hi = np.where(np.isnan(hi), INF, hi)
        mag = np.maximum(np.abs(lo), np.abs(hi))
        for a_lo, a_hi in inputs:
            mag = np.maximum(mag, np.maximum(np.abs(a_lo), np.abs(a_hi)))
        with np.errstate(invalid="ignore"):
            pad = np.where(np.isfinite(mag), REL_PAD * mag + 1e-37, 0.0)
        self.lo[r] = lo - pad
        self.hi[r] = hi + pad

    def constant(self, r: int) -> bool:
        return bool(np.all(self.lo[r] == self.hi[r]))

    def value(self, r: int) -> float:
        return float(self.lo[r, 0])


# ------------------------------------------------------------------------ interval rules


def math_interval(op: int, a, b, c):  # noqa: C901 - one branch per Math operation
    """Interval of Math operation `op` (names.MATH_OPS) of a, b, c (intervals)."""
    name = MATH_OPS[op]
    if name == "ADD":
        return add(a, b)
    if name == "SUBTRACT":
        return sub(a, b)
    if name == "MULTIPLY":
        return mul(a, b)
    if name == "DIVIDE":
        return div(a, b)
    if name == "MULTIPLY_ADD":
        return add(mul(a, b), c)
    if name == "POWER":
        return power(a, b)
    if name == "SQRT":
        return mono(lambda x: np.sqrt(np.maximum(x, 0.0)), a)
    if name == "ABSOLUTE":
        return absolute(a)
    if name == "EXPONENT":
        return mono(np.exp, a)
    if name == "MINIMUM":
        return np.minimum(a[0], b[0]), np.minimum(a[1], b[1])
    if name == "MAXIMUM":
        return np.maximum(a[0], b[0]), np.maximum(a[1], b[1])
    if name in ("LESS_THAN", "GREATER_THAN", "COMPARE", "FRACT"):
        return const_range(a, 0.0, 1.0)
    if name in ("SIGN", "SINE", "COSINE", "TANH"):
        return const_range(a, -1.0, 1.0)
    if name in ("FLOOR", "CEIL", "ROUND", "TRUNC"):
        rounding = {"FLOOR": np.floor, "CEIL": np.ceil, "TRUNC": np.trunc}
        return mono(rounding.get(name, lambda x: np.floor(x + 0.5)), a)
    if name in ("RADIANS", "DEGREES"):
        k = math.pi / 180.0 if name == "RADIANS" else 180.0 / math.pi
        return a[0] * k, a[1] * k
    return unbounded(a)


def _vec(iv: Intervals, r: int):
    return [iv.get(r + k) for k in range(3)]


def vector_interval(op: int, a, b, c, s):
    """(vector intervals (3) or None, scalar interval or None) of Vector Math op `op`."""
    name = VECTOR_OPS[op]
    per = {"ADD": "ADD", "SUBTRACT": "SUBTRACT", "MULTIPLY": "MULTIPLY", "DIVIDE": "DIVIDE",
           "MINIMUM": "MINIMUM", "MAXIMUM": "MAXIMUM", "FLOOR": "FLOOR", "CEIL": "CEIL",
           "FRACTION": "FRACT", "SINE": "SINE", "COSINE": "COSINE", "SIGN": "SIGN"}
    if name in per:
        k = _MATH[per[name]]
        return [math_interval(k, a[i], b[i], c[i]) for i in range(3)], None
    if name == "MULTIPLY_ADD":
        return [add(mul(a[i], b[i]), c[i]) for i in range(3)], None
    if name == "SCALE":
        return [mul(a[i], s) for i in range(3)], None
    if name == "ABSOLUTE":
        return [absolute(a[i]) for i in range(3)], None
    if name == "NORMALIZE":
        return [const_range(a[i], -1.0, 1.0) for i in range(3)], None
    if name == "DOT_PRODUCT":
        return None, add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
    if name in ("LENGTH", "DISTANCE"):
        d = a if name == "LENGTH" else [sub(a[i], b[i]) for i in range(3)]
        sq = [mul(absolute(x), absolute(x)) for x in d]
        total = add(add(sq[0], sq[1]), sq[2])
        return None, mono(np.sqrt, total)
    return [unbounded(a[0])] * 3, None


# ------------------------------------------------------------------------ texture rules


def _euler(r):
    cx, cy, cz = (math.cos(v) for v in r)
    sx, sy, sz = (math.sin(v) for v in r)
    return np.array([[cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz],
                     [cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz],
                     [-sy, cy * sx, cy * cx]])


def _affine(m: np.ndarray, t: np.ndarray, v):
    """The image of box v (3 intervals) under x -> m x + t: centre +- |m| radius."""
    lo = np.stack([x[0] for x in v])
    hi = np.stack([x[1] for x in v])
    centre, radius = 0.5 * (lo + hi), 0.5 * (hi - lo)
    c = m @ centre + t[:, None]
    r = np.abs(m) @ radius
    return [(c[k] - r[k], c[k] + r[k]) for k in range(3)]


def mapping_interval(kind: int, v, loc, rot, scale):
    """Mapping node with constant loc, rot, scale (3-vectors of floats) on box v."""
    m = _euler(rot)
    s = np.asarray(scale, np.float64)
    if kind == 0:
        return _affine(m @ np.diag(s), np.asarray(loc, np.float64), v)
    if kind == 1:
        if np.any(s == 0.0):
            return None
        inv = np.diag(1.0 / s) @ m.T
        return _affine(inv, -inv @ np.asarray(loc, np.float64), v)
    if kind == 2:
        return _affine(m @ np.diag(s), np.zeros(3), v)
    return [const_range(v[0], -1.0, 1.0)] * 3


def map_range_value(v: np.ndarray, fmin, fmax, tmin, tmax, steps, kind: int, clamp: bool) -> np.ndarray:
    """Map Range (float) at v, as math_ops.map_range (numpy, constant parameters)."""
    if fmax == fmin:
        return np.zeros_like(v)
    with np.errstate(all="ignore"):
        if kind >= 2:
            lo, hi = (fmax, fmin) if fmin > fmax else (fmin, fmax)
            t = np.clip((v - lo) / (hi - lo), 0.0, 1.0)
            f = t * t * t * (t * (t * 6.0 - 15.0) + 10.0) if kind == 3 else (3.0 - 2.0 * t) * t * t
            f = np.where(v < lo, 0.0, np.where(v >= hi, 1.0, f))
            if fmin > fmax:
                f = 1.0 - f
            return tmin + f * (tmax - tmin)
        f = (v - fmin) / (fmax - fmin)
        if kind == 1:
            f = np.floor(f * (steps + 1.0)) / steps if steps > 0.0 else np.zeros_like(f)
        r = tmin + f * (tmax - tmin)
    if clamp:
        r = np.clip(r, min(tmin, tmax), max(tmin, tmax))
    return r


def ramp_interval(data: np.ndarray, start: int, channels: int, channel: int, f):
    """Bounds of ramp_lookup over factor interval f: table entries between its ends."""
    table = np.asarray(data[start:start + RAMP_SIZE * channels], np.float64)
    table = table.reshape(RAMP_SIZE, channels)[:, channel]
    lo_i = np.floor(np.clip(np.nan_to_num(f[0], nan=0.0), 0.0, 1.0) * (RAMP_SIZE - 1)).astype(np.int64)
    hi_f = np.clip(np.nan_to_num(f[1], nan=1.0), 0.0, 1.0) * (RAMP_SIZE - 1)
    hi_i = np.minimum(np.ceil(hi_f).astype(np.int64), RAMP_SIZE - 1)
    nan_possible = np.isnan(f[0]) | np.isnan(f[1])
    lo_i = np.where(nan_possible, 0, lo_i)  # NaN reads entry 0
    mins = np.array([table[i:j + 1].min() for i, j in zip(lo_i, hi_i)])
    maxs = np.array([table[i:j + 1].max() for i, j in zip(lo_i, hi_i)])
    return mins, maxs


# ------------------------------------------------------------------------ the evaluator


def run_intervals(program: ShaderProgram, boxes_lo: np.ndarray, boxes_hi: np.ndarray) -> Intervals:  # noqa: C901
    """Run `program` on N world-space boxes ((N, 3) corners); returns its register
    intervals. Operations without a rule here give unbounded results."""
    n = boxes_lo.shape[0]
    iv = Intervals(program.registers, n)
    code = np.asarray(program.code, np.int64).reshape(-1, 10)
    for ins in code:
        op, dst, a, b, c = (int(ins[k]) for k in (I_OP, I_DST, I_A, I_B, I_C))
        name = OPCODES[op]
        p0, p1, p2 = int(ins[I_P0]), int(ins[I_P1]), int(ins[I_P2])
        if name == "position":
            for k in range(3):
                iv.put(dst + k, boxes_lo[:, k], boxes_hi[:, k])
        elif name == "math":
            lo, hi = math_interval(p0, iv.get(a), iv.get(b), iv.get(c))
            if p1:
                lo, hi = clamp01((lo, hi))
            iv.put(dst, lo, hi, iv.get(a), iv.get(b), iv.get(c))
        elif name == "vector_math":
            va, vb, vc = _vec(iv, a), _vec(iv, b), _vec(iv, c)
            vec, scalar = vector_interval(p0, va, vb, vc, iv.get(int(ins[I_D])))
            if p1:
                iv.put(dst, *(scalar if scalar is not None else unbounded(va[0])), *va, *vb)
            else:
                vec = vec if vec is not None else [const_range(va[0], 0.0, 0.0)] * 3
                for k in range(3):
                    iv.put(dst + k, *vec[k], va[k], vb[k], vc[k])
        elif name in ("mix", "mix_float"):
            t = iv.get(a)
            if p1:
                t = clamp01(t)
            width = 3 if name == "mix" else 1
            blend_mix = name == "mix_float" or p0 == 0
            for k in range(width):
                x, y = iv.get(b + k), iv.get(c + k)
                one = (np.ones_like(t[0]),) * 2
                r = add(mul(sub(one, t), x), mul(t, y)) if blend_mix else unbounded(x)
                if name == "mix" and p2:
                    r = clamp01(r)
                iv.put(dst + k, *r, x, y, t)
        elif name == "mapping":
            consts = [b, c, int(ins[I_D])]
            fixed = all(iv.constant(r + k) for r in consts for k in range(3))
            out = None
            if fixed:
                loc, rot, scale = ([iv.value(r + k) for k in range(3)] for r in consts)
                out = mapping_interval(p0, _vec(iv, a), loc, rot, scale)
            out = out or [unbounded(iv.get(a))] * 3
            src = _vec(iv, a)
            for k in range(3):
                iv.put(dst + k, *out[k], *src)
        elif name == "checker":
            for k in range(3):
                iv.put(dst + k, *hull(iv.get(b + k), iv.get(c + k)))
            iv.put(dst + 3, *const_range(iv.get(a), 0.0, 1.0))
        elif name == "ramp":
            f = iv.get(a)
            for ch in range(4):
                iv.put(dst + ch, *ramp_interval(program.data, p0, 4, ch, f))
        elif name == "combine":
            for k, r in enumerate((a, b, c)):
                iv.put(dst + k, *iv.get(r))
        elif name == "copy":  # a move, no rounding: constants stay constant (iv.constant)
            src = [iv.get(a + k) for k in range(p0)]
            for k in range(p0):
                iv.lo[dst + k], iv.hi[dst + k] = src[k]
        elif name == "invert":
            t = iv.get(a)
            for k in range(3):
                x = iv.get(b + k)
                one_minus = sub((np.ones_like(x[0]),) * 2, x)
                r = add(mul(t, one_minus), mul(sub((np.ones_like(x[0]),) * 2, t), x))
                iv.put(dst + k, *r, x, t)
        elif name == "rgb_to_bw":
            parts = [iv.get(a + k) for k in range(3)]
            w = (0.2126, 0.7152, 0.0722)
            lo = sum(wk * p[0] for wk, p in zip(w, parts))
            iv.put(dst, lo, sum(wk * p[1] for wk, p in zip(w, parts)), *parts)
        elif name == "clamp":
            x, lo_b, hi_b = iv.get(a), iv.get(b), iv.get(c)
            r = (np.minimum(np.maximum(x[0], lo_b[0]), hi_b[0]),
                 np.minimum(np.maximum(x[1], lo_b[1]), hi_b[1]))
            if p0 == 1:  # range mode swaps the bounds when min > max
                r = hull(r, (np.minimum(np.maximum(x[0], hi_b[0]), lo_b[0]),
                              np.minimum(np.maximum(x[1], hi_b[1]), lo_b[1])))
            iv.put(dst, *r, x, lo_b, hi_b)
        elif name == "map_range":
            x = iv.get(a)
            if all(iv.constant(b + k) for k in range(5)):
                params = [iv.value(b + k) for k in range(5)]
                ends = [map_range_value(e, *params, p0, bool(p1)) for e in x]
                r = (np.minimum(ends[0], ends[1]), np.maximum(ends[0], ends[1]))
            elif p1 and p0 < 2:  # clamped to [to min, to max]
                r = hull(iv.get(b + 2), iv.get(b + 3))
            else:
                r = unbounded(x)
            iv.put(dst, *r, x, *(iv.get(b + k) for k in range(5)))
        elif name == "gradient":
            iv.put(dst, *const_range(iv.get(a), 0.0, 1.0))
        elif name == "noise_nd":  # b..b+7: W, scale, detail, roughness, lacunarity, offset, gain, ...
            params = [iv.get(b + k) for k in (2, 3, 5, 6)]
            value = noise_interval(p0, p1, *params, (p2 & NOISE_NORMALIZE) != 0)
            for k in range(4):  # the value, and the colour (the same fractal at seeded points)
                iv.put(dst + k, *value)  # (noise_interval pads its own rounding)
            if p2 & NOISE_NO_COLOR:  # the colour's green and blue are left 0
                for k in (2, 3):
                    iv.put(dst + k, np.minimum(value[0], 0.0), np.maximum(value[1], 0.0))
        else:  # attribute, normal, image, curve, gamma, hsv, fresnel, ...: no rule
            width = 1 if name in ("fresnel", "layer_weight") else 4 if name == "image" else 3
            for k in range(width):
                iv.put(dst + k, *unbounded(iv.get(dst)))
    return iv
