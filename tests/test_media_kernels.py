"""Media kernels: every estimator is checked against a closed form or a quadrature.

Monte Carlo checks use z-scores: |mean - expected| < Z standard errors of the mean, the
standard error estimated from the same samples (a deterministic estimator has standard
error 0 and must then match to rounding). Sample loops run inside @njit helpers; seeds
are fixed.
"""

import math

import numpy as np
import pytest
from numba import njit

from renderer.errors import SceneError
from renderer.kernels.rng import path_key
from renderer.media import (
    compile_media,
    equiangular_pdf,
    equiangular_sample,
    nee_vertex,
    phase_eval,
    phase_pdf,
    sample_distance,
    sample_phase,
    stack_has_grid,
    stack_is_empty,
    stack_push,
    stack_remove,
    transmittance,
)
from renderer.phase.hg import hg_eval
from renderer.scene import Medium

Z = 5.0
ORIGIN = (0.3, -0.2, 0.1)
DIR = (0.0, 0.6, 0.8)


def stack_of(*ids: int) -> np.ndarray:
    s = np.full(4, -1, np.int32)
    s[: len(ids)] = ids
    return s


def assert_mean(samples_sum, samples_sq, n, expected, what=""):
    """|mean - expected| < Z standard errors (plus rounding), per channel."""
    for k in range(len(expected)):
        mean = samples_sum[k] / n
        var = max(samples_sq[k] / n - mean * mean, 0.0)
        se = math.sqrt(var / n)
        tol = Z * se + 1e-12 * (abs(expected[k]) + abs(mean)) + 1e-300
        assert abs(mean - expected[k]) < tol, (
            f"{what} channel {k}: mean {mean:.6g} expected {expected[k]:.6g} "
            f"({(mean - expected[k]) / max(se, 1e-300):.1f} se)"
        )


# ------------------------------------------------------------------------------ stack


def test_stack_push_remove():
    s = stack_of()
    assert stack_is_empty(s)
    assert stack_push(s, 2) and stack_push(s, 0) and stack_push(s, 2) and stack_push(s, 1)
    assert list(s) == [2, 0, 2, 1]
    assert not stack_push(s, 3)  # full: dropped, no crash
    assert list(s) == [2, 0, 2, 1]
    assert stack_remove(s, 2)  # the last occurrence goes, slots stay packed
    assert list(s) == [2, 0, 1, -1]
    assert not stack_remove(s, 7)
    assert stack_remove(s, 2) and stack_remove(s, 0) and stack_remove(s, 1)
    assert stack_is_empty(s) and list(s) == [-1, -1, -1, -1]


def test_empty_media_list_gives_valid_table():
    mt = compile_media([], True)
    s = stack_of()
    t, scattered, w, le, dim = sample_distance(
        mt, s, ORIGIN, DIR, 5.0, (1.0, 1.0, 1.0), np.uint64(1), 0, False
    )
    assert (t, scattered, w, le) == (5.0, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    assert transmittance(mt, s, ORIGIN, DIR, 0.0, 5.0, np.uint64(1), 0, False)[0] == (1.0, 1.0, 1.0)
    assert not stack_has_grid(mt, s)


# ------------------------------------------------------------------------------ homogeneous


def homogeneous(sigma_a, sigma_s, **kw) -> Medium:
    return Medium("m", sigma_a=sigma_a, sigma_s=sigma_s, **kw)


def test_homogeneous_transmittance_closed_form():
    mt = compile_media(
        [homogeneous((0.1, 0.0, 2.0), (0.4, 0.0, 1.0), scale=2.0), homogeneous((0.5, 0, 0), (0, 0, 0))]
    )
    s = stack_of(0, 1)
    tr, dim = transmittance(mt, s, ORIGIN, DIR, 0.5, 2.0, np.uint64(3), 7, False)
    sigma_t = np.array([(0.1 + 0.4) * 2 + 0.5, 0.0, (2.0 + 1.0) * 2])
    np.testing.assert_allclose(tr, np.exp(-sigma_t * 1.5), rtol=1e-6)
    assert dim == 7  # closed form: no random numbers
    tr, _ = transmittance(mt, stack_of(1), ORIGIN, DIR, 0.0, 1e30, np.uint64(3), 0, False)
    assert tr == (0.0, 1.0, 1.0)


@njit(cache=True)
def _free_flight_moments(mt, stack, tmax, throughput, uniform_channel, n, seed):
    """Per channel: sums and squared sums of weight * [not scattered] and weight * [scattered]."""
    out = np.zeros((4, 3))
    bad = 0
    dim_ok = True
    for i in range(n):
        key = path_key(seed, i, 0)
        t, scattered, w, le, dim = sample_distance(
            mt, stack, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tmax, throughput, key, 0, uniform_channel
        )
        if dim != 2:
            dim_ok = False
        for k in range(3):
            if not math.isfinite(w[k]) or w[k] < 0.0:
                bad += 1
            row = 2 if scattered else 0
            out[row, k] += w[k]
            out[row + 1, k] += w[k] * w[k]
        if scattered and not (0.0 <= t < tmax):
            bad += 1
        if not scattered and t != tmax:
            bad += 1
    return out, bad, dim_ok


CHROMATIC = [
    # (sigma_a, sigma_s): sigma_t = (0, 1, 1e4) and (1e-8, 1e-3, 1e6) with albedos 0..1
    ((0.0, 0.5, 1e3), (0.0, 0.5, 9e3)),
    ((1e-8, 0.0, 1e4), (0.0, 1e-3, 9.9e5)),
    ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)),
    ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
]


@pytest.mark.parametrize("sigma_a, sigma_s", CHROMATIC)
@pytest.mark.parametrize("tmax", [0.7, 1e30])
@pytest.mark.parametrize("throughput, uniform_channel", [((1.0, 1.0, 1.0), True), ((1.0, 0.2, 0.05), False)])
def test_homogeneous_free_flight_unbiased(sigma_a, sigma_s, tmax, throughput, uniform_channel):
    mt = compile_media([homogeneous(sigma_a, sigma_s)])
    n = 200_000
    m, bad, dim_ok = _free_flight_moments(mt, stack_of(0), tmax, throughput, uniform_channel, n, 11)
    assert bad == 0 and dim_ok
    sa, ss = np.array(sigma_a, float), np.array(sigma_s, float)
    st = sa + ss
    with np.errstate(invalid="ignore", over="ignore"):
        tr = np.where(st > 0, np.exp(-st * tmax), 1.0)
        # integral_0^tmax T(t) sigma_s dt
        scat = np.where(st > 0, ss * -np.expm1(-st * tmax) / np.where(st > 0, st, 1.0), ss * tmax)
    assert_mean(m[0], m[1], n, tr, "E[w; not scattered] = T(tmax)")
    assert_mean(m[2], m[3], n, scat, "E[w; scattered] = int T sigma_s")


def test_homogeneous_emission_closed_form():
    e = (2.0, 0.5, 1.0)
    mt = compile_media(
        [homogeneous((1.0, 0.0, 1e-12), (0.5, 0.0, 0.0), emission=e), homogeneous((0, 0, 0), (0, 0, 0))]
    )
    for tmax in (0.3, 4.0):
        for s in (stack_of(0), stack_of(0, 1)):
            _, _, _, le, _ = sample_distance(
                mt, s, ORIGIN, DIR, tmax, (1.0, 1.0, 1.0), np.uint64(5), 0, False
            )
            np.testing.assert_allclose(le[0], 2.0 * -math.expm1(-1.5 * tmax) / 1.5, rtol=1e-6)
            assert le[1] == 0.5 * tmax  # sigma_t = 0: the limit E t exactly
            np.testing.assert_allclose(le[2], tmax, rtol=1e-6)  # sigma_t = 1e-12
    # A medium without emission gives exactly zero emission.
    _, _, _, le, _ = sample_distance(
        mt, stack_of(1), ORIGIN, DIR, 3.0, (1.0, 1.0, 1.0), np.uint64(5), 0, False
    )
    assert le == (0.0, 0.0, 0.0)
    assert list(mt.has_emission) == [1, 0]


# ------------------------------------------------------------------------------ equiangular


EQUI_CASES = [
    # (light, tmax)
    ((1.0, 2.0, 0.5), 5.0),
    ((1.0, 2.0, 0.5), 1e30),
    ((0.0, -3.0, 0.0), 4.0),  # light behind the ray origin
    ((0.0, 2.0, 0.0), 6.0),  # light on the ray line, inside the segment
    ((0.0, 1e-9, 1e-12), 3.0),  # light almost at the origin
]


def _equiangular_integral(light, tmax):
    """Trapezoid rule on a grid refined around the light's foot point (and geometric
    toward huge tmax)."""
    o, d = (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    delta = light[1]
    pts = [0.0, tmax]
    for scale in np.geomspace(1e-14, max(tmax, 1.0), 4000):
        pts += [delta - scale, delta + scale, scale]
    t = np.unique(np.clip(pts, 0.0, tmax))
    f = np.array([equiangular_pdf(o, d, light, tmax, x) for x in t])
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))


@pytest.mark.parametrize("light, tmax", EQUI_CASES)
def test_equiangular_pdf_integrates_to_one(light, tmax):
    assert abs(_equiangular_integral(light, tmax) - 1.0) < 1e-4


@pytest.mark.parametrize("light, tmax", EQUI_CASES)
def test_equiangular_sample_matches_pdf(light, tmax):
    o, d = (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    for u in np.linspace(0.0, 1.0 - 2.0**-24, 97):
        t, pdf = equiangular_sample(o, d, light, tmax, u)
        assert 0.0 <= t <= tmax and math.isfinite(pdf) and pdf > 0.0
        np.testing.assert_allclose(pdf, equiangular_pdf(o, d, light, tmax, t), rtol=1e-9)


# ------------------------------------------------------------------------------ NEE vertex


@njit(cache=True)
def _nee_moments(mt, stack, tmax, light, use_eq, uniform_channel, n, seed):
    out = np.zeros((2, 3))
    bad = 0
    for i in range(n):
        key = path_key(seed, i, 0)
        t, w, dim = nee_vertex(
            mt, stack, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tmax, light, (1.0, 0.3, 0.1), key, 0, use_eq,
            uniform_channel,
        )  # fmt: skip
        # test function: inverse-square falloff toward the light, like direct lighting
        dx = t - light[0]
        f = 1.0 / (dx * dx + light[1] * light[1] + light[2] * light[2])
        if not (0.0 <= t <= tmax) or dim != 3:
            bad += 1
        for k in range(3):
            v = w[k] * f
            if not math.isfinite(v):
                bad += 1
            out[0, k] += v
            out[1, k] += v * v
    return out, bad


@pytest.mark.parametrize("use_eq", [True, False])
@pytest.mark.parametrize("uniform_channel", [True, False])
@pytest.mark.parametrize(
    "sigma_a, sigma_s, tmax", [((0.1, 0.0, 3.0), (0.4, 0.2, 1.0), 6.0), ((0, 0, 0), (0, 0.05, 2.0), 1e30)]
)
def test_nee_vertex_unbiased(use_eq, uniform_channel, sigma_a, sigma_s, tmax):
    light = (2.5, 0.3, 0.0)
    mt = compile_media([homogeneous(sigma_a, sigma_s)])
    n = 200_000
    m, bad = _nee_moments(mt, stack_of(0), tmax, light, use_eq, uniform_channel, n, 5)
    assert bad == 0
    st = np.add(sigma_a, sigma_s)
    # reference integral_0^tmax T(t) sigma_s f(t) dt on a fine grid (the integrand decays
    # or, for sigma_t = 0, falls off as 1/t^2: the tail beyond 1e6 is < 1e-6)
    t = np.concatenate([np.linspace(0.0, 10.0, 400_001), np.geomspace(10.0, min(tmax, 1e7), 200_001)[1:]])
    f = 1.0 / ((t - light[0]) ** 2 + light[1] ** 2)
    for k in range(3):
        ref = np.trapz(np.exp(-st[k] * t) * sigma_s[k] * f, t)
        tail = sigma_s[k] / min(tmax, 1e7) if st[k] == 0.0 and tmax > 1e7 else 0.0
        assert_mean(m[0, k : k + 1], m[1, k : k + 1], n, [ref + tail], f"nee channel {k}")


# ------------------------------------------------------------------------------ phase mixture


def test_single_entry_phase_is_hg():
    mt = compile_media([homogeneous((0, 0, 0), (1.0, 0.2, 0.1), g=0.6)])
    s = stack_of(0)
    d = (0.0, 0.0, 1.0)
    wi, w, pdf = sample_phase(mt, s, ORIGIN, d, 0.3, 0.7, 0.2)
    assert w == (1.0, 1.0, 1.0)
    np.testing.assert_allclose(pdf, hg_eval(float(mt.g[0]), wi[2]), rtol=1e-9)
    np.testing.assert_allclose(phase_pdf(mt, s, ORIGIN, d, wi), pdf, rtol=1e-9)


@njit(cache=True)
def _phase_moments(mt, stack, d, n, seed):
    """E[weight3 * h(cos)] with h(cos) = (1 + cos)^2, and the worst |pdf - phase_pdf|."""
    np.random.seed(seed)
    out = np.zeros((2, 3))
    worst = 0.0
    for _ in range(n):
        wi, w, pdf = sample_phase(mt, stack, (0.0, 0.0, 0.0), d, np.random.random(), np.random.random(),
                                  np.random.random())  # fmt: skip
        c = d[0] * wi[0] + d[1] * wi[1] + d[2] * wi[2]
        h = (1.0 + c) * (1.0 + c)
        for k in range(3):
            out[0, k] += w[k] * h
            out[1, k] += (w[k] * h) ** 2
        worst = max(worst, abs(pdf - phase_pdf(mt, stack, (0.0, 0.0, 0.0), d, wi)) / pdf)
    return out, worst


def test_phase_mixture_chromatic_overlap():
    """Two overlapping media of different g and colour: the sampled weight f/pdf is unbiased
    for the per-channel mixture f_k = sum_i sigma_s,i,k hg_i / sum_i sigma_s,i,k."""
    media = [homogeneous((0, 0, 0), (1.0, 0.1, 0.0), g=0.8), homogeneous((0, 0, 0), (0.2, 0.5, 1.0), g=-0.4)]
    mt = compile_media(media)
    s = stack_of(0, 1)
    d = (0.0, 0.6, 0.8)
    n = 200_000
    m, worst = _phase_moments(mt, s, d, n, 3)
    assert worst < 1e-9
    mu = np.linspace(-1.0, 1.0, 200_001)
    s0, s1 = np.array(media[0].sigma_s), np.array(media[1].sigma_s)
    g0, g1 = float(mt.g[0]), float(mt.g[1])  # as stored (float32)
    h0 = np.array([hg_eval(g0, x) for x in mu])
    h1 = np.array([hg_eval(g1, x) for x in mu])
    for k in range(3):
        f = (s0[k] * h0 + s1[k] * h1) / (s0[k] + s1[k])
        ref = 2.0 * math.pi * np.trapz(f * (1.0 + mu) ** 2, mu)
        assert_mean(m[0, k : k + 1], m[1, k : k + 1], n, [ref], f"phase channel {k}")
    f3, pdf = phase_eval(mt, s, ORIGIN, d, (0.0, 0.0, 1.0))
    c = 0.8
    np.testing.assert_allclose(f3[0], (1.0 * hg_eval(g0, c) + 0.2 * hg_eval(g1, c)) / 1.2, rtol=1e-6)


# ------------------------------------------------------------------------------ validation

ONES = np.ones((2, 2, 2), np.float32)


@pytest.mark.parametrize(
    "medium, field",
    [
        (Medium("m", sigma_a=(-1.0, 0, 0)), "media[0].sigma_a"),
        (Medium("m", sigma_s=(0, float("nan"), 0)), "media[0].sigma_s"),
        (Medium("m", g=1.0), "media[0].g"),
        (Medium("m", g=-1.5), "media[0].g"),
        (Medium("m", scale=-2.0), "media[0].scale"),
        (Medium("m", type="fog"), "media[0].type"),
        (Medium("m", type="grid"), "media[0].density"),
        (Medium("m", type="grid", density=np.full((2, 2, 2), -1.0, np.float32)), "media[0].density"),
        (Medium("m", type="grid", density=np.full((2, 2, 2), np.nan, np.float32)), "media[0].density"),
        (Medium("m", type="grid", density=ONES, p1=(1.0, 0.0, 1.0)), "media[0].p1"),
        (Medium("m", type="grid", density=ONES, to_world=np.diag([1.0, 0.0, 1.0, 1.0])), "media[0].to_world"),
        (Medium("m", type="grid", density=ONES, temperature=-np.ones((1, 1, 1))), "media[0].temperature"),
        (Medium("m", density=ONES), "media[0].density"),
    ],
)  # fmt: skip
def test_bad_media_raise_scene_error(medium, field):
    with pytest.raises(SceneError) as err:
        compile_media([homogeneous((0, 0, 0), (1, 1, 1)), homogeneous((0, 0, 0), (1, 1, 1)), medium])
    field = field.replace("media[0]", "media[2]")
    assert err.value.path == field
    assert str(err.value).startswith(field + ":")
