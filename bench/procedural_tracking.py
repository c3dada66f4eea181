"""Procedural tracking against quadrature: `python -m bench procedural_tracking [--n 4000]`.

The transmittance of a ray through a procedural cloud (the sheared box of Noise -> Map Range
-> Math density below, whose majorants tests/test_procedural_media.py checks), estimated by
ratio tracking and by delta tracking (renderer.media.transmittance: the real trackers, compiled for the
procedural table type) with N independent keys, against exp(-sigma_t * optical depth), the
depth a 40 000-point midpoint quadrature of the same program along the ray. Prints the
means, the expected values and the z-scores per channel; exits 1 if any |z| > 5.

Not in the suite: its first run compiles the trackers for ProceduralMediaTable, about 5 min
of CPU on a cold kernel cache (measured on the loaded 2-core build machine).
"""

from __future__ import annotations

import argparse

import numpy as np

from renderer.kernels.rng import path_key
from renderer.media import compile_media, transmittance
from renderer.media.procedural import evaluate_density
from renderer.scene import Medium
from renderer.shading.fractal import TYPES as FRACTAL_TYPES
from renderer.shading.names import MAP_RANGE_TYPES, MATH_OPS, RAMP_SIZE
from renderer.shading.program import INSTR, OP, ShaderProgram

Z = 5.0


def _row(op: str, dst: int, a: int = 0, b: int = 0, c: int = 0, d: int = 0, i0: int = 0,
         i1: int = 0, i2: int = 0) -> list[int]:
    row = [0] * INSTR.size
    row[:10] = [OP[op], dst, a, b, c, d, 0, i0, i1, i2]
    return row


def cloud_program(scale: float = 2.5, detail: float = 2.5, normalize: bool = True, to_max: float = 6.0,
                  ramp: bool = False, dim: int = 3, kind: str = "FBM") -> tuple[ShaderProgram, int]:
    """Position -> Noise (3D fBM unless told) -> Map Range (linear, clamped) -> [x density
    scale]: the usual procedural cloud. Returns (program, density register)."""
    regs = np.zeros(24, np.float32)
    # noise: W, scale, detail, roughness, lacunarity, offset, gain, distortion
    regs[3:11] = (0.4, scale, detail, 0.55, 2.0, 0.8, 1.2, 0.3)
    regs[12:17] = (0.45, 0.75, 0.0, to_max, 4.0)  # map range: from, to, steps
    regs[18] = 1.7
    code = [_row("position", 0), _row("noise_nd", 20, a=0, b=3, i0=dim, i1=FRACTAL_TYPES.index(kind),
                                      i2=int(normalize)),
            _row("map_range", 17, a=20, b=12, i0=MAP_RANGE_TYPES.index("LINEAR"), i1=1),
            _row("math", 19, a=17, b=18, i0=MATH_OPS.index("MULTIPLY"))]
    data = np.zeros(0, np.float32)
    if ramp:  # a Color Ramp after the noise: RAMP_SIZE RGBA entries, a bump in the middle
        f = np.linspace(0.0, 1.0, RAMP_SIZE)
        table = np.stack([np.exp(-((f - 0.55) / 0.08) ** 2) * 4.0] * 4, axis=1).astype(np.float32)
        data = table.ravel()
        code[2] = _row("ramp", 17, a=20, i0=0, i1=1)
    return ShaderProgram(np.array(code, np.int32), regs, np.zeros((0, 5), np.int32), data), 19


def procedural(program: ShaderProgram, density: int, **kw) -> Medium:
    to_world = np.eye(4)
    to_world[:3, :3] = [[1.0, 0.3, 0.0], [0.0, 0.8, 0.0], [0.1, 0.0, 1.2]]  # sheared, not axis-aligned
    to_world[:3, 3] = (0.2, -0.1, 0.3)
    return Medium("cloud", "grid", sigma_a=(0.3, 0.6, 1.0), sigma_s=(0.5, 0.4, 0.2), p0=(-1.0, -1.0, -1.0),
                  p1=(1.0, 1.0, 1.0), to_world=to_world, program=program, program_density=density, **kw)


def _stack(m: int) -> np.ndarray:
    s = np.full(4, -1, np.int32)
    s[0] = m
    return s


def _optical_depth(mt, o, d, t0, t1, n=40_000) -> float:
    """Midpoint quadrature of the density along the ray (the program is smooth: C2 noise)."""
    t = t0 + (np.arange(n) + 0.5) * (t1 - t0) / n
    x = np.asarray(o)[None, :] + t[:, None] * np.asarray(d)[None, :]
    rho = evaluate_density(mt.programs, 0, x)
    # outside the box the density is 0: mask with the box test the kernel uses
    to_unit = mt.params[0, -12:].astype(np.float64).reshape(3, 4)
    u = x @ to_unit[:, :3].T + to_unit[:, 3]
    rho = np.where(np.all((u >= 0.0) & (u <= 1.0), axis=1), rho, 0.0)
    return float(rho.sum() * (t1 - t0) / n)


def check(use_delta: bool, n: int) -> bool:
    """One estimator against the quadrature: True when every channel is within Z sigma."""
    program, reg = cloud_program()
    mt = compile_media([procedural(program, reg)])
    o, d = (-1.6, 0.05, 0.35), (0.8, 0.36, 0.48)
    t0, t1 = 0.0, 4.0
    depth = _optical_depth(mt, o, d, t0, t1)
    sigma_t = np.array([0.8, 1.0, 1.2])
    expected = np.exp(-sigma_t * depth)
    s = np.zeros(3)
    s2 = np.zeros(3)
    stack = _stack(0)
    for i in range(n):
        tr, _ = transmittance(mt, stack, o, d, t0, t1, np.uint64(path_key(11, i, 0)), 0, use_delta)
        s += tr
        s2 += np.square(tr)
    mean = s / n
    se = np.sqrt(np.maximum(s2 / n - mean ** 2, 0.0) / n)
    z = (mean - expected) / se
    name = "delta" if use_delta else "ratio"
    print(f"{name} tracking, {n} keys: optical depth {depth:.4f}, mean {np.round(mean, 5)}, "
          f"expected {np.round(expected, 5)}, z {np.round(z, 2)}")
    return bool(depth > 0.3 and np.all(np.abs(z) < Z))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench procedural_tracking", description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=4000, help="independent keys per estimator")
    args = parser.parse_args(argv)
    ok = [check(use_delta, args.n) for use_delta in (False, True)]
    return 0 if all(ok) else 1
