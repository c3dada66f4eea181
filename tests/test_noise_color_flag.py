"""The Noise Texture's colour is computed only when its Color output is used
(program.NOISE_NO_COLOR, set by the add-on's exporter for an unlinked Color output, as
Cycles skips it): the value stays bit-identical, the colour's green and blue are 0 (the
two fractals skipped: two thirds of the node's time, which procedural volumes pay at every
density lookup), and the interval rules bound the zeros too."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_noise_intervals import PARAMS, evaluate, noise_program

from renderer.shading.intervals import run_intervals
from renderer.shading.program import I_OP, I_P2, NOISE_NO_COLOR, OP

OUT = 11  # test_noise_intervals' noise register


def _without_color(program):
    code = program.code.copy()
    code[code[:, I_OP] == OP["noise_nd"], I_P2] |= NOISE_NO_COLOR
    return dataclasses.replace(program, code=code)


@pytest.mark.parametrize("dim, kind", [(3, "FBM"), (4, "HYBRID_MULTIFRACTAL"), (2, "RIDGED_MULTIFRACTAL")])
def test_value_unchanged_colour_skipped(dim, kind):
    program = noise_program(dim, kind, kind == "FBM", PARAMS[kind])
    points = np.random.default_rng(dim).uniform(-20.0, 20.0, (20_000, 3))
    full = evaluate(program, points)
    bare = evaluate(_without_color(program), points)
    np.testing.assert_array_equal(bare[:, 0], full[:, 0])
    np.testing.assert_array_equal(bare[:, 1], full[:, 0])
    assert np.all(bare[:, 2:] == 0.0) and np.any(full[:, 2:] != 0.0)


def test_intervals_hold_the_zeroed_colour():
    program = _without_color(noise_program(3, "MULTIFRACTAL", False, PARAMS["MULTIFRACTAL"]))
    points = np.random.default_rng(5).uniform(-20.0, 20.0, (20_000, 3))
    values = evaluate(program, points)
    iv = run_intervals(program, points.min(axis=0)[None], points.max(axis=0)[None])
    lo, hi = iv.lo[OUT:OUT + 4, 0], iv.hi[OUT:OUT + 4, 0]
    assert np.all(values >= lo) and np.all(values <= hi)

