"""The convergence benchmark's denoised curve (bench/convergence.py haze_curve, denoised):
the same progressive render with the denoiser's passes on, each pass's image denoised and
measured against the reference at its elapsed time plus the denoising's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.convergence import haze_curve
from bench.metrics import film_reference
from examples.scenes import cornell_fog
from helpers.films import render_film
from renderer.denoise import available

pytestmark = [pytest.mark.slow, pytest.mark.skipif(not available(), reason="Open Image Denoise not found")]


def test_denoised_curve_is_measured_beside_the_raw_one():
    scene = cornell_fog(size=32, spp=512)
    scene.integrator.seed = 7
    reference = film_reference(render_film(scene), 0.0)
    raw = haze_curve(scene, "default", {}, reference, 3.0, workers=1)
    clean = haze_curve(scene, "default, denoised", {}, reference, 3.0, workers=1, denoised=True)
    assert clean.label == "default, denoised" and len(clean.seconds) >= 2
    assert all(np.diff(clean.seconds) > 0) and all(math.isfinite(e) for e in clean.relmse)
    assert all(math.isnan(e) for e in clean.estimate)  # Haze's estimate is the raw image's
    # At equal samples the denoised image is the closer one (fog box: several times).
    spp = sorted(set(raw.spp) & set(clean.spp))
    assert spp, "the two curves share no sample count"
    n = spp[0]
    assert clean.relmse[clean.spp.index(n)] < raw.relmse[raw.spp.index(n)]
