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
from renderer.media.blackbody import blackbody_emission, blackbody_emission_voxels, blackbody_rgb
from renderer.media.emission import stack_emission
from renderer.media.grid import grid_lookup
from renderer.media.layout import I_HAS_EMISSION, I_MAJ_DIMS, I_MAJ_OFFSET, P_G
from renderer.media.tracking import _sigma_at
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
        # Rounding: a float64 sum of n terms is off by at most about n * eps relative (this
        # matters when the estimator is deterministic, e.g. a medium that does not scatter).
        rounding = (n * 2.3e-16 + 1e-12) * (abs(expected[k]) + abs(mean))
        tol = Z * se + rounding + 1e-300
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
    assert list(mt.index[:, I_HAS_EMISSION]) == [1, 0]


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


@pytest.mark.parametrize("light, tmax", EQUI_CASES)
def test_equiangular_sample_inverts_the_cdf(light, tmax):
    """t(u) solves CDF(t) = u with CDF(t) = (atan((t - delta) / D) - theta_a) / theta_d, so
    the sampler (a sincos form of the tangent addition formula) has the pdf's distribution.
    The angle differences are written as one atan2 each (tangent of a difference), which
    stays accurate when both angles are near pi/2 (the light on the ray line)."""
    o, d = (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    delta = light[1]
    big_d = max(math.hypot(light[0], light[2]), 1e-7 * abs(delta), 1e-12)

    def angle_from_start(t):
        return math.atan2(big_d * t, big_d * big_d - delta * (t - delta))

    theta_d = angle_from_start(tmax)
    for u in np.linspace(0.0, 1.0 - 2.0**-24, 97):
        t, _ = equiangular_sample(o, d, light, tmax, u)
        assert abs(angle_from_start(t) / theta_d - u) < 1e-9


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
    np.testing.assert_allclose(pdf, hg_eval(float(mt.params[0, P_G]), wi[2]), rtol=1e-9)
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
    g0, g1 = float(mt.params[0, P_G]), float(mt.params[1, P_G])  # as stored (float32)
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


# ------------------------------------------------------------------------------ grids


@njit(cache=True)
def _reference(mt, stack, o, d, tmax, steps):
    """T(tmax), integral T sigma_s dt and integral T E dt per channel, by an exponential
    integrator: on each of `steps` steps the coefficients are taken at the midpoint and the
    step is integrated exactly (accurate to O(h^2) even where sigma_t h >> 1)."""
    h = tmax / steps
    tr = np.ones(3)
    scat = np.zeros(3)
    emit = np.zeros(3)
    for i in range(steps):
        t = (i + 0.5) * h
        x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
        sa, ss = _sigma_at(mt, stack, x)
        e = stack_emission(mt, stack, x)
        for k in range(3):
            st = sa[k] + ss[k]
            step_len = -math.expm1(-st * h) / st if st > 0.0 else h  # integral of exp(-st s) on the step
            scat[k] += tr[k] * ss[k] * step_len
            emit[k] += tr[k] * e[k] * step_len
            tr[k] *= math.exp(-st * h)
    return tr, scat, emit


@njit(cache=True)
def _track_moments(mt, stack, o, d, tmax, throughput, uniform_channel, n, seed):
    """Rows: w [not scattered], w [scattered], Le, ratio-tracking Tr, delta-tracking Tr;
    each as (sum, sum of squares) per channel. Also counts non-finite or negative outputs."""
    out = np.zeros((10, 3))
    bad = 0
    for i in range(n):
        key = path_key(seed, i, 0)
        t, scattered, w, le, _ = sample_distance(mt, stack, o, d, tmax, throughput, key, 0, uniform_channel)
        tr_ratio, _ = transmittance(mt, stack, o, d, 0.0, tmax, key, 1000, False)
        tr_delta, _ = transmittance(mt, stack, o, d, 0.0, tmax, key, 2000, True)
        row = 2 if scattered else 0
        for k in range(3):
            for v in (w[k], tr_ratio[k], tr_delta[k]):
                if not (math.isfinite(v) and v >= 0.0):
                    bad += 1
            if not math.isfinite(le[k]):  # blackbody blue is < 0 below ~2000 K, as in Cycles
                bad += 1
            out[row, k] += w[k]
            out[row + 1, k] += w[k] * w[k]
            out[4, k] += le[k]
            out[5, k] += le[k] * le[k]
            out[6, k] += tr_ratio[k]
            out[7, k] += tr_ratio[k] * tr_ratio[k]
            out[8, k] += tr_delta[k]
            out[9, k] += tr_delta[k] * tr_delta[k]
        if not (0.0 <= t <= tmax):
            bad += 1
    return out, bad


def check_against_reference(mt, stack, o, d, tmax, n=100_000, throughput=(1.0, 0.5, 0.25), uniform=False):
    o = tuple(float(v) for v in o)
    d = tuple(float(v) for v in np.asarray(d) / np.linalg.norm(d))
    tr, scat, emit = _reference(mt, stack, o, d, tmax, 400_000)
    m, bad = _track_moments(mt, stack, o, d, tmax, throughput, uniform, n, 17)
    assert bad == 0
    assert_mean(m[0], m[1], n, tr, "free flight E[w; not scattered] = T(tmax)")
    assert_mean(m[2], m[3], n, scat, "free flight E[w; scattered] = int T sigma_s")
    assert_mean(m[4], m[5], n, emit, "emission E[Le] = int T E")
    assert_mean(m[6], m[7], n, tr, "ratio tracking E[Tr] = T")
    assert_mean(m[8], m[9], n, tr, "delta tracking E[Tr] = T")


def grid_medium(density, sigma_a, sigma_s, **kw) -> Medium:
    density = np.asarray(density, np.float32)
    return Medium("grid", type="grid", sigma_a=sigma_a, sigma_s=sigma_s, density=density, **kw)


@pytest.mark.parametrize("shape", [(1, 1, 1), (3, 4, 5)])
@pytest.mark.parametrize("use_majorant_grid", [True, False])
def test_constant_grid_equals_homogeneous(shape, use_majorant_grid):
    """Inside its box a constant grid is exactly a homogeneous medium (clamp-to-edge)."""
    sa, ss = (0.1, 0.5, 1.0), (0.4, 0.5, 0.0)
    mt = compile_media([grid_medium(np.full(shape, 2.0), sa, ss)], use_majorant_grid)
    o, d, tmax = (0.1, 0.2, 0.3), (0.3, 0.5, 0.8), 0.6
    st = 2.0 * (np.float32(sa).astype(float) + np.float32(ss))  # coefficients are stored as float32
    ref = _reference(mt, stack_of(0), o, tuple(np.divide(d, np.linalg.norm(d))), tmax, 1000)
    np.testing.assert_allclose(ref[0], np.exp(-st * tmax), rtol=1e-12)
    check_against_reference(mt, stack_of(0), o, d, tmax)


HETERO_SIGMAS = [
    ((0.5, 2.0, 0.0), (3.0, 1.0, 4.0)),
    ((0.0, 0.0, 0.0), (0.0, 1.0, 10.0)),  # sigma_t = (0, 1, 10) x density, albedo 1
    ((1e-8, 1e-3, 20.0), (0.0, 0.0, 180.0)),  # 1e-8 .. 200: contrast 2e10 between channels
]


@pytest.mark.parametrize("sigma_a, sigma_s", HETERO_SIGMAS)
@pytest.mark.parametrize("use_majorant_grid", [True, False])
def test_heterogeneous_grid_estimators(sigma_a, sigma_s, use_majorant_grid):
    """Free flight, emission, ratio and delta tracking through a random grid with density
    contrast 1e6, a flame grid and a temperature grid, all against quadrature."""
    rng = np.random.default_rng(7)
    density = 10.0 ** rng.uniform(-6.0, 0.0, (6, 7, 8))
    density[2:4, :, :] = 0.0  # an empty slab: majorant cells of 0 inside the box
    flame = rng.uniform(0.0, 1.0, (3, 3, 4))
    temperature = rng.uniform(1000.0, 3000.0, (2, 5, 3))
    to_world = np.diag([2.0, 1.0, 1.5, 1.0])
    med = grid_medium(density, sigma_a, sigma_s, p0=(-0.5, -0.5, -0.5), p1=(0.5, 0.5, 0.5), to_world=to_world)
    med.emission, med.flame, med.temperature = (1.0, 0.5, 0.2), flame, temperature
    med.blackbody_intensity = 1.0
    mt = compile_media([med], use_majorant_grid)
    check_against_reference(mt, stack_of(0), (-1.5, -0.1, -0.2), (1.0, 0.15, 0.2), 3.0, n=60_000)


def test_mixed_stack_grid_and_emitting_homogeneous():
    """Coefficients of overlapping entries add. Emission where no channel has any extinction
    (a pure emitter, or a grid emitting where its density is 0) must still be sampled: the
    emission collision rate is what makes these estimates unbiased."""
    rng = np.random.default_rng(3)
    density = rng.uniform(0.0, 1.0, (4, 4, 4))
    media = [
        grid_medium(density, (1.0, 0.5, 0.0), (1.0, 2.0, 0.0)),  # box [0, 1]^3
        homogeneous((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), emission=(0.3, 0.0, 2.0)),  # pure emitter
        Medium("hot", type="grid", density=np.zeros((2, 2, 2), np.float32), emission=(0.0, 1.0, 0.0),
               p0=(0.5, -1.0, -1.0), p1=(2.0, 2.0, 2.0)),
    ]  # fmt: skip
    mt = compile_media(media)
    o, d = (-0.5, 0.4, 0.5), (1.0, 0.1, -0.05)
    check_against_reference(mt, stack_of(0, 1, 2), o, d, 2.5, uniform=True)
    check_against_reference(mt, stack_of(2, 1), o, d, 2.5, n=20_000)
    # Nothing attenuates in the second stack: Le is the plain integral of E (in expectation).
    _, _, emit = _reference(mt, stack_of(2, 1), o, tuple(np.divide(d, np.linalg.norm(d))), 2.5, 1000)
    np.testing.assert_allclose(emit[[0, 2]], np.array([0.3, 2.0]) * 2.5, rtol=1e-6)


def test_all_zero_grid_is_exactly_transparent():
    mt = compile_media([grid_medium(np.zeros((16, 16, 16)), (1.0, 1.0, 1.0), (1.0, 1.0, 1.0))])
    s = stack_of(0)
    o, d = (-1.0, 0.5, 0.5), (1.0, 0.0, 0.0)
    for use_delta in (False, True):
        tr, dim = transmittance(mt, s, o, d, 0.0, 3.0, np.uint64(9), 0, use_delta)
        assert tr == (1.0, 1.0, 1.0)
        assert dim == 1  # the channel pick only: not one tentative collision
    t, scattered, w, le, dim = sample_distance(mt, s, (-1.0, 0.5, 0.5), (1.0, 0.0, 0.0), 3.0, (1.0, 1.0, 1.0),
                                               np.uint64(9), 0, False)  # fmt: skip
    assert (t, scattered, w, le, dim) == (3.0, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 1)


@njit(cache=True)
def _collision_counts(mt, stack, o, d, tmax, n):
    """Mean transmittance (channel 0) and mean random numbers used (~ tentative collisions)."""
    tr_sum = 0.0
    tr_sq = 0.0
    dims = 0
    for i in range(n):
        tr, dim = transmittance(mt, stack, o, d, 0.0, tmax, path_key(4, i, 0), 0, False)
        tr_sum += tr[0]
        tr_sq += tr[0] * tr[0]
        dims += dim
    return tr_sum, tr_sq, dims / n


def test_single_dense_voxel_in_large_empty_grid():
    density = np.zeros((256, 256, 256), np.float32)
    density[100, 120, 140] = 1000.0  # (z, y, x)
    med = grid_medium(density, (1.0, 1.0, 1.0), (1.0, 1.0, 1.0))
    mt = compile_media([med], True)
    s = stack_of(0)
    centre = np.array([(140 + 0.5) / 256, (120 + 0.5) / 256, (100 + 0.5) / 256])
    d = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    o = tuple(centre - 2.0 * d)
    d = tuple(d)
    # A ray far from the voxel crosses the whole grid without a single tentative collision.
    _, _, dims = _collision_counts(mt, s, (-1.0, 0.05, 0.9), (1.0, 0.0, 0.0), 3.0, 100)
    assert dims == 1.0
    # Through the voxel: tentative collisions only near it (a global majorant would spend
    # ~2000 per unit length, i.e. ~3500 on this ray); the estimate stays unbiased.
    n = 20_000
    tr_sum, tr_sq, dims = _collision_counts(mt, s, o, d, 4.0, n)
    assert dims < 200
    ref = _reference(mt, s, o, d, 4.0, 400_000)[0][0]
    assert_mean([tr_sum], [tr_sq], n, [ref], "transmittance through one dense voxel")


def _box_length(med: Medium, o, d, tmax):
    """Length of o + t d, t in [0, tmax), inside the medium's box (independent numpy maths)."""
    box = np.eye(4)
    box[:3, :3] = np.diag(np.subtract(med.p1, med.p0))
    box[:3, 3] = med.p0
    inv = np.linalg.inv(med.to_world @ box)
    uo = inv[:3, :3] @ o + inv[:3, 3]
    ud = inv[:3, :3] @ d
    with np.errstate(divide="ignore"):
        ta, tb = (0.0 - uo) / ud, (1.0 - uo) / ud
    t0 = max(0.0, np.max(np.minimum(ta, tb)))
    t1 = min(tmax, np.min(np.maximum(ta, tb)))
    return max(0.0, t1 - t0)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


TRANSFORMS = {
    "rotated": (_rotation((1, 2, 3), 0.7), (0.2, -0.1, 0.3)),
    "non-uniform": (np.diag([0.3, 2.0, 1.2]) @ _rotation((0, 1, 1), 0.4), (0.0, 0.5, 0.0)),
    "mirrored": (np.diag([-1.0, 1.0, 1.0]) @ _rotation((1, 0, 1), 1.1), (0.1, 0.0, -0.2)),
}


@pytest.mark.parametrize("name", sorted(TRANSFORMS))
@pytest.mark.parametrize("use_delta", [False, True])
def test_transformed_constant_box_optical_depth(name, use_delta):
    lin, offset = TRANSFORMS[name]
    w = np.eye(4)
    w[:3, :3] = lin
    w[:3, 3] = offset
    med = grid_medium(np.ones((3, 3, 3)), (0.3, 1.0, 0.0), (0.2, 0.5, 2.0), p0=(-0.4, 0.1, -0.3),
                      p1=(0.6, -0.7, 0.5), to_world=w)  # fmt: skip
    mt = compile_media([med])
    st = np.array([0.5, 1.5, 2.0])
    rng = np.random.default_rng(11)
    centre = (w @ np.append(0.5 * np.add(med.p0, med.p1), 1.0))[:3]
    n = 4000
    for _ in range(12):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        o = centre - 2.0 * d + rng.normal(scale=0.2, size=3)
        length = _box_length(med, o, d, 4.0)
        m = _transmittance_moments(mt, stack_of(0), tuple(o), tuple(d), 4.0, use_delta, n)
        assert_mean(m[0], m[1], n, np.exp(-st * length), f"{name}: length {length:.4f}")


@njit(cache=True)
def _transmittance_moments(mt, stack, o, d, tmax, use_delta, n):
    out = np.zeros((2, 3))
    for i in range(n):
        tr, _ = transmittance(mt, stack, o, d, 0.0, tmax, path_key(8, i, 0), 0, use_delta)
        for k in range(3):
            out[0, k] += tr[k]
            out[1, k] += tr[k] * tr[k]
    return out


# ------------------------------------------------------------------------------ majorant grid


@njit(cache=True)
def _worst_majorant_violation(mt, m, n, seed):
    """max over random unit-cube points of density - (majorant of the point's cell)."""
    np.random.seed(seed)
    cx, cy, cz = mt.index[m, I_MAJ_DIMS], mt.index[m, I_MAJ_DIMS + 1], mt.index[m, I_MAJ_DIMS + 2]
    worst = -np.inf
    for _ in range(n):
        u = (np.random.random(), np.random.random(), np.random.random())
        rho = grid_lookup(mt, m, 0, u)
        i, j, k = min(int(u[0] * cx), cx - 1), min(int(u[1] * cy), cy - 1), min(int(u[2] * cz), cz - 1)
        maj = mt.maj_data[mt.index[m, I_MAJ_OFFSET] + (k * cy + j) * cx + i, 0]
        worst = max(worst, rho - maj)
    return worst


@pytest.mark.parametrize("shape", [(1, 1, 1), (5, 3, 7), (40, 33, 70), (300, 2, 9)])
def test_majorant_bounds_trilinear_density(shape):
    rng = np.random.default_rng(5)
    density = rng.uniform(0.0, 1.0, shape) ** 8  # spiky: most voxels near 0
    mt = compile_media([grid_medium(density, (1, 1, 1), (0, 0, 0))])
    cells = mt.index[0, I_MAJ_DIMS : I_MAJ_DIMS + 3]
    assert np.all(cells <= 64) and np.all(cells >= 1)
    assert np.all(cells == [min(64, -(-n // 4)) for n in shape[::-1]])
    assert _worst_majorant_violation(mt, 0, 200_000, 1) <= 0.0
    one = compile_media([grid_medium(density, (1, 1, 1), (0, 0, 0))], use_majorant_grid=False)
    assert list(one.index[0, I_MAJ_DIMS : I_MAJ_DIMS + 3]) == [1, 1, 1]
    assert one.maj_data[0, 0] == np.float32(density.max())


# ------------------------------------------------------------------------------ blackbody

# Cycles' fitted blackbody colour (svm/math_util.h), evaluated at these temperatures.
CYCLES_BLACKBODY = {
    800.0: (5.4139, -0.2034, -0.0823),
    1000.0: (4.6014, 0.0390, -0.0900),
    1500.0: (3.2643, 0.4340, -0.0642),
    2000.0: (2.5201, 0.6469, 0.0204),
    3000.0: (1.7708, 0.8443, 0.2722),
    4000.0: (1.4141, 0.9236, 0.5337),
    6500.0: (1.0426, 0.9841, 1.0353),
    10000.0: (0.8714, 0.9949, 1.4305),
    12000.0: (0.8263, 0.9945, 1.5663),
}


@pytest.mark.parametrize("temperature", sorted(CYCLES_BLACKBODY))
def test_blackbody_matches_cycles_normalisation(temperature):
    rgb = np.array(blackbody_rgb(temperature))
    # Same normalisation as Cycles: Rec.709 luminance 1.
    assert abs(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2] - 1.0) < 1e-9
    # Same colour: Cycles' curve is a fit (to ~1e-3) of the same Planck x CIE 1931 integral.
    np.testing.assert_allclose(rgb, CYCLES_BLACKBODY[temperature], atol=3e-3, rtol=2e-3)


def test_blackbody_range_and_emission_formula():
    assert blackbody_rgb(100.0) == blackbody_rgb(800.0)
    assert blackbody_rgb(5e4) == blackbody_rgb(12000.0)
    for t in np.geomspace(100.0, 1e5, 200):
        rgb = blackbody_rgb(t)
        assert all(math.isfinite(c) for c in rgb) and rgb[0] > 0.0
        # Luminance 1 everywhere (the table is linear in 1/T between rows of luminance 1).
        assert abs(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2] - 1.0) < 1e-9
    sigma = 5.670373e-8 * 1e-6 / math.pi
    for t, b in ((1500.0, 1.0), (2500.0, 0.5), (0.0, 1.0)):
        expected = sigma * ((1.0 - b) + b * t**4) * np.array(blackbody_rgb(t))
        np.testing.assert_allclose(blackbody_emission(t, b), expected, rtol=1e-12)
    assert blackbody_emission(3000.0, 0.0) == (0.0, 0.0, 0.0)


def test_blackbody_voxels_equal_the_kernel_formula():
    rng = np.random.default_rng(5)
    temperature = np.concatenate([[0.0, 1.0, 799.0, 800.0, 12000.0, 5e4], rng.uniform(0.0, 15000.0, 200)])
    for b in (1.0, 0.5, 2.0, 0.0):
        voxels = blackbody_emission_voxels(temperature, b)
        expected = np.array([blackbody_emission(t, b) for t in temperature])
        np.testing.assert_allclose(voxels, expected, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("intensity", [1.0, 0.5])
def test_grid_blackbody_interpolates_emission_not_temperature(intensity):
    """Cycles samples a volume's grids stochastically (one voxel picked with the trilinear
    weights), so what it renders between voxels is, in expectation, the trilinear mix of the
    voxels' blackbody emission; blackbody of the mixed temperature would be darker (T^4 is
    convex) and redder."""
    temperature = np.zeros((2, 2, 3), np.float32)
    temperature[..., 0], temperature[..., 1], temperature[..., 2] = 0.0, 3000.0, 1200.0
    temperature[1, 1, 2] = 6000.0
    med = Medium("fire", type="grid", density=np.zeros((1, 1, 1), np.float32), temperature=temperature,
                 blackbody_intensity=intensity)
    mt = compile_media([med])
    voxels = blackbody_emission_voxels(temperature.astype(np.float64), intensity)
    rng = np.random.default_rng(11)
    points = [(1.0 / 3.0, 0.5, 0.5), (0.5, 0.25, 0.75)] + [tuple(rng.uniform(0.0, 1.0, 3)) for _ in range(20)]
    for u in points:
        weights = np.ones((2, 2, 3))
        for axis, n in zip((2, 1, 0), (3, 2, 2)):  # numpy axis 2 is x
            f = min(max(u[2 - axis] * n - 0.5, 0.0), n - 1.0)
            i = min(int(f), n - 2)
            along = np.zeros(n)
            along[i], along[i + 1] = 1.0 - (f - i), f - i
            shape = [1, 1, 1]
            shape[axis] = n
            weights = weights * along.reshape(shape)
        expected = (weights[..., None] * voxels).sum(axis=(0, 1, 2))
        got = np.array(stack_emission(mt, stack_of(0), u))
        np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-7 * np.abs(expected).max())


# ------------------------------------------------------------------------------ robustness

SIGMA_VALUES = [0.0, 1e-8, 1e-3, 1.0, 1e3, 1e6]


def _extreme_media():
    """Every sigma_t value in every channel (as a cyclic pattern), albedos 0, 0.5, 1 and
    |g| up to 0.9999, as homogeneous media and as grids of density contrast 1e6."""
    rng = np.random.default_rng(2)
    density = 10.0 ** rng.uniform(-6.0, 0.0, (4, 5, 6))
    media = []
    for i in range(len(SIGMA_VALUES)):
        st = np.array([SIGMA_VALUES[(i + k) % 6] for k in range(3)])
        albedo = np.array([0.0, 0.5, 1.0])[[(i + k) % 3 for k in range(3)]]
        g = (-0.9999, 0.0, 0.9999)[i % 3]
        sa, ss = tuple(st * (1.0 - albedo)), tuple(st * albedo)
        media.append(homogeneous(sa, ss, g=g))
        media.append(grid_medium(density, sa, ss, g=g, emission=(1.0, 0.0, 0.5) if i % 2 else (0, 0, 0)))
    return media


@njit(cache=True)
def _all_outputs_finite(mt, stacks, n):
    bad = 0
    for s in range(stacks.shape[0]):
        stack = stacks[s]
        for i in range(n):
            key = path_key(1, s, i)
            o, d = (-0.2, 0.3, 0.4), (0.6, 0.0, 0.8)
            for tmax in (0.5, 1e30):
                beta = (1.0, 0.3, 1e-6)
                t, sc, w, le, dim = sample_distance(mt, stack, o, d, tmax, beta, key, 0, i % 2 == 0)
                tr1, _ = transmittance(mt, stack, o, d, 0.0, min(tmax, 3.0), key, 50, False)
                tr2, _ = transmittance(mt, stack, o, d, 0.1, min(tmax, 3.0), key, 90, True)
                vals = (t, w[0], w[1], w[2], le[0], le[1], le[2])
                for v in vals + tr1 + tr2:
                    if not (math.isfinite(v) and v >= 0.0):
                        bad += 1
                if sc:
                    x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
                    wi, pw, pdf = sample_phase(mt, stack, x, d, 0.3, (i + 0.5) / n, 0.7)
                    if not (math.isfinite(wi[0] + wi[1] + wi[2] + pw[0] + pw[1] + pw[2]) and pdf > 0.0):
                        bad += 1
                if not stack_has_grid(mt, stack) and tmax < 1.0:
                    tn, wn, _ = nee_vertex(mt, stack, o, d, tmax, (0.0, 1.0, 0.5), (1.0, 1.0, 1.0), key, 7,
                                           True, False)  # fmt: skip
                    if not (math.isfinite(tn + wn[0] + wn[1] + wn[2]) and min(wn[0], wn[1], wn[2]) >= 0.0):
                        bad += 1
    return bad


def test_extreme_coefficients_give_finite_outputs():
    media = _extreme_media()
    mt = compile_media(media)
    m = len(media)
    stacks = [stack_of(i) for i in range(m)]
    stacks += [stack_of(i, (i + 3) % m) for i in range(m)]  # overlapping pairs, mixed kinds
    stacks += [stack_of(0, 2, 5, 9)]
    assert _all_outputs_finite(mt, np.array(stacks), 64) == 0


def test_instances_share_their_grids():
    """Media made from the same arrays (instances of one volume) store them once; each
    instance reads the same values through its own transform."""
    rng = np.random.default_rng(4)
    density = rng.random((6, 5, 4)).astype(np.float32)
    temperature = (1500.0 + 1000.0 * rng.random((6, 5, 4))).astype(np.float32)
    moved = np.eye(4)
    moved[:3, 3] = (3.0, 0.0, 0.0)
    kw = dict(temperature=temperature, blackbody_intensity=1.0)
    one = compile_media([grid_medium(density, (1, 1, 1), (1, 1, 1), **kw)])
    two = compile_media([grid_medium(density, (1, 1, 1), (1, 1, 1), **kw),
                         grid_medium(density, (1, 1, 1), (1, 1, 1), to_world=moved, **kw)])
    assert two.grid_data.size == one.grid_data.size
    assert two.maj_data.shape == one.maj_data.shape
    np.testing.assert_array_equal(two.index[0, I_MAJ_OFFSET], two.index[1, I_MAJ_OFFSET])
    copy = compile_media([grid_medium(density, (1, 1, 1), (1, 1, 1), **kw),
                          grid_medium(density.copy(), (1, 1, 1), (1, 1, 1), to_world=moved, **kw)])
    assert copy.grid_data.size > one.grid_data.size  # equal values, distinct arrays: stored twice
    for i in range(2):
        for u in ((0.3, 0.6, 0.2), (0.9, 0.1, 0.5)):
            assert grid_lookup(two, i, 0, u) == grid_lookup(copy, i, 0, u) > 0.0
