"""Interval bounds of the Noise Texture (renderer.shading.noise_intervals): the Perlin
bounds' certificates, and every dimension x fractal type's bound against the values the
interpreter gives at 200,000 random points (through shading.evaluate's entry, the same
interpreter the trackers call by address), bounded yet not absurdly loose.

Measured (this file's points, bound width / width of the values met): 1.0 (Ridged, whose
bound is met) to 3.5 (4D Multifractal, a product of 4.5 factors each as loose as the 4D
noise bound); |snoise| met / bound: 1.00, 0.99, 0.96, 0.70 (dimension 1, 2, 3, 4: the
lattice hash never gives a 4D cell the worst gradients the proof allows)."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.media.procedural import build_program_tables
from renderer.shading.evaluate import evaluate_points
from renderer.shading.fractal import TYPES
from renderer.shading.intervals import run_intervals
from renderer.shading.names import MATH_OPS
from renderer.shading.noise_intervals import PERLIN_SUP, certify_perlin_sup, perlin_upper, snoise_bound
from renderer.shading.program import INSTR, OP, ShaderProgram

N_POINTS = 200_000
OUT = 11  # the noise's value register; 12..14 its colour
# (detail, roughness, offset, gain): a fractional detail; offsets and gains that make the
# recurrences' terms change sign (Hetero, Hybrid) and Ridged's weights clamp.
PARAMS = {"FBM": (3.5, 0.6, 0.0, 1.0), "MULTIFRACTAL": (3.5, 0.6, 0.0, 1.0),
          "HYBRID_MULTIFRACTAL": (3.5, 0.6, 0.7, 1.5), "RIDGED_MULTIFRACTAL": (3.5, 0.6, 1.0, 2.0),
          "HETERO_TERRAIN": (3.5, 0.6, 0.7, 1.0)}
CASES = ([(dim, kind, False) for dim in (1, 2, 3, 4) for kind in TYPES]
         + [(dim, "FBM", True) for dim in (1, 2, 3, 4)])
MAX_LOOSENESS = 4.0  # bound width / values' width; measured at most 3.5


def _row(op: str, dst: int, a: int = 0, b: int = 0, c: int = 0, i0: int = 0, i1: int = 0,
         i2: int = 0) -> list[int]:
    row = [0] * INSTR.size
    row[:10] = [OP[op], dst, a, b, c, 0, 0, i0, i1, i2]
    return row


def noise_program(dim: int, kind: str, normalize: bool, params, distortion: float = 0.4,
                  scale: float = 1.3, varying: bool = False) -> ShaderProgram:
    """Position -> Noise, W = x + y (1D and 4D noise read it). varying: detail, roughness,
    offset and gain are affine functions of the position (intervals, not constants)."""
    regs = np.zeros(24, np.float32)
    regs[3:11] = (0.0, scale, *params[:2], 2.0, *params[2:], distortion)
    code = [_row("position", 0), _row("math", 3, a=0, b=1, i0=MATH_OPS.index("ADD"))]
    if varying:  # detail = 0.25 x + 4, roughness = 0.02 y + 0.6, offset = 0.03 z + 0.5, gain = 0.02 x + 1.2
        regs[15:23] = (0.25, 4.0, 0.02, 0.6, 0.03, 0.5, 0.02, 1.2)
        madd = MATH_OPS.index("MULTIPLY_ADD")
        for k, (axis, reg) in enumerate(((0, 5), (1, 6), (2, 8), (0, 9))):
            code.append(_row("math", reg, a=axis, b=15 + 2 * k, c=16 + 2 * k, i0=madd))
    code.append(_row("noise_nd", OUT, a=0, b=3, i0=dim, i1=TYPES.index(kind), i2=int(normalize)))
    return ShaderProgram(np.array(code, np.int32), regs, np.zeros((0, 5), np.int32), np.zeros(0, np.float32))


def evaluate(program: ShaderProgram, points: np.ndarray) -> np.ndarray:
    """(N, 4) value and colour of the program's noise at points, as the interpreter gives them."""
    tables, _ = build_program_tables([program], [OUT])
    n = len(points)
    out = np.zeros((n, 4), np.float32)
    evaluate_points(tables, np.int64(0), np.full(n, -1, np.int32), np.zeros((n, 3), np.float32),
                    np.ascontiguousarray(points, np.float32), np.zeros((n, 3), np.float32),
                    np.zeros(len(program.registers), np.float32), np.int64(OUT), np.int64(4), out)
    return out.astype(np.float64)


def test_the_1d_perlin_bound_is_met_at_the_middle_of_a_cell():
    f = np.linspace(0.0, 1.0, 100_001)[:, None]
    values = perlin_upper(1, f, f)
    assert values.max() <= PERLIN_SUP[1] + 1e-12
    assert values[50_000] == pytest.approx(PERLIN_SUP[1], abs=1e-12)


@pytest.mark.parametrize("dim", [2, 3, 4])
def test_perlin_bounds_are_certified_and_close_to_the_maximum(dim):
    """The branch and bound proves max F_n <= PERLIN_SUP[n]; F_n's largest value among
    random points is within 3% of it; and a bound just below that value is not certified."""
    assert certify_perlin_sup(dim, PERLIN_SUP[dim])
    f = np.random.default_rng(dim).random((400_000, dim))
    met = perlin_upper(dim, f, f).max()
    assert 0.97 * PERLIN_SUP[dim] < met <= PERLIN_SUP[dim]
    assert not certify_perlin_sup(dim, 0.999 * met, max_boxes=300_000)


@pytest.mark.parametrize("dim", [1, 2, 3, 4])
def test_snoise_stays_within_its_bound(dim):
    """Detail 0, plain fBM: the value is snoise itself."""
    program = noise_program(dim, "FBM", False, (0.0, 0.5, 0.0, 1.0), distortion=0.0, scale=3.7)
    points = np.random.default_rng(10 + dim).uniform(-40.0, 40.0, (N_POINTS, 3))
    met = np.abs(evaluate(program, points)).max()
    assert met <= snoise_bound(dim)
    assert met > 0.65 * snoise_bound(dim), f"|snoise| met {met:.4f}, bound {snoise_bound(dim):.4f}"


@pytest.mark.parametrize("dim, kind, normalize", CASES)
def test_noise_stays_inside_its_interval_bound(dim, kind, normalize):
    program = noise_program(dim, kind, normalize, PARAMS[kind])
    points = np.random.default_rng(dim * 10 + TYPES.index(kind)).uniform(-30.0, 30.0, (N_POINTS, 3))
    values = evaluate(program, points)
    iv = run_intervals(program, points.min(axis=0)[None], points.max(axis=0)[None])
    lo, hi = iv.lo[OUT:OUT + 4, 0], iv.hi[OUT:OUT + 4, 0]
    assert np.all(values >= lo) and np.all(values <= hi), (values.min(axis=0), values.max(axis=0), lo, hi)
    looseness = (hi[0] - lo[0]) / (values.max() - values.min())
    assert looseness < MAX_LOOSENESS, f"bound [{lo[0]:.4f}, {hi[0]:.4f}] for values in " \
                                      f"[{values.min():.4f}, {values.max():.4f}]"


@pytest.mark.parametrize("kind", TYPES)
def test_parameters_that_vary_over_space_are_bounded_per_box(kind):
    """Detail (through integer values), roughness, offset and gain from the position: 2,000
    boxes of 100 points each, every value inside its own box's bound."""
    program = noise_program(3, kind, False, PARAMS[kind], varying=True)
    rng = np.random.default_rng(TYPES.index(kind))
    lo = rng.uniform(-16.0, 15.0, (2_000, 3))
    hi = lo + rng.uniform(0.05, 1.0, (2_000, 3))
    points = (lo[:, None, :] + rng.random((2_000, 100, 3)) * (hi - lo)[:, None, :]).astype(np.float32)
    values = evaluate(program, points.reshape(-1, 3)).reshape(2_000, 100, 4)
    lo, hi = np.minimum(lo, points.min(axis=1)), np.maximum(hi, points.max(axis=1))  # float32 rounding
    iv = run_intervals(program, lo, hi)
    assert np.all(values >= iv.lo[OUT:OUT + 4].T[:, None, :])
    assert np.all(values <= iv.hi[OUT:OUT + 4].T[:, None, :])
    assert np.all(np.isfinite(iv.hi[OUT]))
