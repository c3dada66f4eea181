"""Henyey-Greenstein phase function: sampling matches the density, density is normalised.

Sampling is checked by a chi-square test over (cos theta, phi) bins, with cos theta bins of
equal probability under the analytic CDF (so no bin is sparse even at |g| = 0.999) and
phi measured in a frame independent of the sampler's own basis. Threshold p > 1e-3.
"""

import math

import numpy as np
import pytest
from numba import njit

from renderer.kernels.vecmath import cross, dot, normalize
from renderer.phase.hg import hg_eval, hg_sample, hg_sample_cos

N_SAMPLES = 400_000
COS_BINS = 20
PHI_BINS = 8
P_THRESHOLD = 1e-3


def hg_cdf(g: float, mu: float) -> float:
    """P(cos <= mu) in a form without division by g: (1 - g)(1 + mu) / (s (1 + g + s)),
    s = sqrt(1 + g^2 - 2 g mu); it is (1 + mu) / 2 at g = 0."""
    # s^2 as a sum of non-negative terms (no cancellation for either sign of g).
    if g >= 0.0:
        s = math.sqrt((1.0 - g) ** 2 + 2.0 * g * (1.0 - mu))
    else:
        s = math.sqrt((1.0 + g) ** 2 - 2.0 * g * (1.0 + mu))
    return (1.0 - g) * (1.0 + mu) / (s * (1.0 + g + s))


def chi2_pvalue(stat: float, dof: int) -> float:
    """Upper tail of the chi-square distribution (Wilson-Hilferty; accurate for dof >= 10)."""
    z = ((stat / dof) ** (1.0 / 3.0) - (1.0 - 2.0 / (9.0 * dof))) / math.sqrt(2.0 / (9.0 * dof))
    return 0.5 * math.erfc(z / math.sqrt(2.0))


@njit(cache=True)
def _histogram(g, d, ref, cos_edges, n, seed):
    """Counts of (cos bin, phi bin) of n samples; phi measured from `ref` around d."""
    np.random.seed(seed)
    counts = np.zeros((cos_edges.size - 1, PHI_BINS), np.int64)
    e1 = normalize(cross(d, ref))
    e2 = cross(d, e1)
    bad = 0
    for _ in range(n):
        wi, pdf = hg_sample(g, d, np.random.random(), np.random.random())
        if not (math.isfinite(pdf) and pdf > 0.0):
            bad += 1
            continue
        c = dot(d, wi)
        i = np.searchsorted(cos_edges, c, side="right") - 1
        i = min(max(i, 0), cos_edges.size - 2)
        phi = math.atan2(dot(wi, e2), dot(wi, e1)) + math.pi
        j = min(int(phi / (2.0 * math.pi) * PHI_BINS), PHI_BINS - 1)
        counts[i, j] += 1
    return counts, bad


@pytest.mark.parametrize("g", [-0.999, -0.9, 0.0, 1e-4, 0.5, 0.999])
@pytest.mark.parametrize("d", [(0.36, -0.48, 0.8), (0.0, 0.0, -1.0)])
def test_hg_sampling_chi_square(g, d):
    # Bin edges of equal probability, found by bisection on the analytic CDF.
    edges = [-1.0]
    for k in range(1, COS_BINS):
        lo, hi = -1.0, 1.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if hg_cdf(g, mid) < k / COS_BINS else (lo, mid)
        edges.append(0.5 * (lo + hi))
    edges.append(1.0)
    edges = np.array(edges)
    expected_cos = np.diff([hg_cdf(g, e) for e in edges])
    expected = np.outer(expected_cos, np.full(PHI_BINS, 1.0 / PHI_BINS)) * N_SAMPLES
    counts, bad = _histogram(g, normalize(d), (1.0, 0.0, 0.0) if d[2] != 0.8 else (0.0, 1.0, 0.0),
                             edges, N_SAMPLES, 1234)  # fmt: skip
    assert bad == 0
    assert expected.min() > 20.0
    stat = float(((counts - expected) ** 2 / expected).sum())
    p = chi2_pvalue(stat, expected.size - 1)
    assert p > P_THRESHOLD, f"chi2 = {stat:.1f} over {expected.size - 1} dof, p = {p:.2e}"


@pytest.mark.parametrize("g", [-0.9999, -0.999, -0.5, -1e-9, 0.0, 1e-9, 1e-4, 0.3, 0.9, 0.999, 0.9999])
def test_hg_sample_cos_inverts_cdf(g):
    """hg_sample_cos is the exact inverse of the analytic CDF (deterministic)."""
    for u in np.linspace(0.0, 1.0, 101):
        c = hg_sample_cos(g, u)
        assert -1.0 <= c <= 1.0
        # cos is only known to a few ulps (2.2e-16); near the pole of a sharp lobe the CDF's
        # slope 2 pi p(cos) turns that into a larger, still rounding-sized, error: allow 32 ulps.
        assert abs(hg_cdf(g, c) - u) < 1e-12 + 2.0 * math.pi * hg_eval(g, c) * 32 * 2.2e-16


def test_hg_is_uniform_at_zero():
    for c in (-1.0, -0.3, 0.0, 0.7, 1.0):
        assert hg_eval(0.0, c) == 1.0 / (4.0 * math.pi)
    for u in (0.0, 0.25, 0.5, 0.9):
        assert hg_sample_cos(0.0, u) == 2.0 * u - 1.0


@pytest.mark.parametrize("g", [-0.9999, -0.999, -0.5, 0.0, 1e-9, 1e-4, 0.5, 0.999, 0.9999])
def test_hg_pdf_integrates_to_one(g):
    """2 pi integral of p over cos in [-1, 1], by the trapezoid rule on a grid that is
    geometric in the distance to both poles (where |g| -> 1 concentrates the lobe)."""
    y = np.concatenate([[0.0], np.geomspace(1e-18, 1.0, 200_001)])
    mu_hi = 1.0 - y  # [0, 1] approached from cos = 1
    mu_lo = -1.0 + y  # [-1, 0] approached from cos = -1
    f_hi = np.array([hg_eval(g, m) for m in mu_hi[::-1]])
    f_lo = np.array([hg_eval(g, m) for m in mu_lo])
    total = 2.0 * math.pi * (np.trapz(f_hi, mu_hi[::-1]) + np.trapz(f_lo, mu_lo))
    assert abs(total - 1.0) < 1e-6


@njit(cache=True)
def _pdf_mismatch_and_finiteness(g, n, seed):
    np.random.seed(seed)
    worst = 0.0
    finite = True
    for _ in range(n):
        z = 2.0 * np.random.random() - 1.0
        phi = 2.0 * math.pi * np.random.random()
        r = math.sqrt(max(0.0, 1.0 - z * z))
        d = (r * math.cos(phi), r * math.sin(phi), z)
        wi, pdf = hg_sample(g, d, np.random.random(), np.random.random())
        if not (math.isfinite(wi[0] + wi[1] + wi[2]) and math.isfinite(pdf)):
            finite = False
            continue
        if abs(dot(wi, wi) - 1.0) > 1e-9 or pdf <= 0.0:
            finite = False
        ev = hg_eval(g, dot(d, wi))
        worst = max(worst, abs(ev - pdf) / pdf)
    return worst, finite


@pytest.mark.parametrize("g", [-0.9999, -0.9, -1e-9, 0.0, 1e-9, 1e-4, 0.5, 0.9, 0.9999])
def test_hg_sample_pdf_equals_eval_and_is_finite(g):
    worst, finite = _pdf_mismatch_and_finiteness(g, 100_000, 99)
    assert finite
    # pdf from the sampled cos vs from dot(d, wi): equal up to the rounding of wi.
    assert worst < 1e-6


def test_hg_extremes_finite_at_poles():
    for g in (-0.9999, 0.9999, 1e-9, -1e-9):
        for c in (-1.0, 1.0, 0.0):
            v = hg_eval(g, c)
            assert math.isfinite(v) and v > 0.0
        for u in (0.0, 1.0 - 2.0**-24, 0.5):
            c = hg_sample_cos(g, u)
            assert math.isfinite(c)
