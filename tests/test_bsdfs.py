"""Statistical tests of the BSDF lobes and the material mixture (renderer.bsdfs).

Every random test has a fixed seed. Tolerances come from the estimator: means are compared
within 5 standard errors, sampled directions are checked with a chi-square test against the
pdf integrated over bins of the sphere (p > 1e-3), and quadrature results carry an error
estimate from halving the quadrature step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from renderer.bsdfs import (
    CONDUCTOR,
    DIELECTRIC,
    DIFFUSE,
    FRESNEL_CONSTANT,
    FRESNEL_F82,
    LOBE_KINDS,
    PLASTIC,
    ROUGH_CONDUCTOR,
    TRANSPARENT,
)
from renderer.bsdfs.coat_albedo import (
    N_MU,
    N_S,
    _coat_albedo_quadrature,
    _mu_node,
    _s_node,
    coat_albedo,
    coat_eta,
)
from renderer.bsdfs.fresnel import conductor_fresnel, fresnel_dielectric
from renderer.bsdfs.lobe import lobe_eval, lobe_is_delta, lobe_sample
from renderer.bsdfs.material import (
    EVENT_ABSORB,
    EVENT_DELTA,
    EVENT_PASS_THROUGH,
    EVENT_SCATTER,
    L_COLOR,
    L_FRESNEL,
    L_IOR,
    L_KIND,
    L_MS,
    L_ROUGH,
    L_SIDES,
    L_TINT,
    L_WEIGHT,
    bsdf_eval,
    bsdf_has_lobes,
    bsdf_sample,
)
from renderer.bsdfs.plastic import layer_albedo
from renderer.bsdfs.spec_albedo import (
    N_NODES,
    SPEC_S,
    f0_from_eta,
    node_params,
    remapped_fresnel_lookup,
    remapped_fresnel_mean,
    spec_albedo,
)
from renderer.bsdfs.table import build_material_table
from renderer.scene import Lobe, Material

N_SAMPLES = 200_000
N_THETA, N_PHI = 10, 20  # chi-square bins in (theta, phi); theta, not cos theta, so that a
SUB = 24  # narrow lobe near the pole still spans many quadrature points (SUB^2 per bin)
P_MIN = 1e-3
Z_MAX = 5.0
WHITE = (1.0, 1.0, 1.0)
# The Fresnel, tint and multiscatter arguments of lobes that have none.
PLAIN = (FRESNEL_CONSTANT, WHITE, False)


def direction(theta_deg: float, phi_deg: float = 0.0) -> tuple[float, float, float]:
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))


# ---------------------------------------------------------------------------------------------
# Kernels that generate samples and integrate over the sphere (numba loops, not Python loops).


@njit(cache=True)
def _sample_lobe(kind, color, rough, ior, fresnel, tint, ms, wo, n, seed):
    np.random.seed(seed)
    wi = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    pdf = np.zeros(n)
    delta = np.zeros(n, np.bool_)
    for k in range(n):
        d, w, p, dl = lobe_sample(kind, color, rough, ior, fresnel, tint, ms, wo, np.random.random(),
                                  np.random.random(), np.random.random())
        wi[k, 0], wi[k, 1], wi[k, 2] = d
        weight[k, 0], weight[k, 1], weight[k, 2] = w
        pdf[k] = p
        delta[k] = dl
    return wi, weight, pdf, delta


@njit(cache=True)
def _eval_lobe_at(kind, color, rough, ior, fresnel, tint, ms, wo, wi):
    n = wi.shape[0]
    f = np.zeros((n, 3))
    pdf = np.zeros(n)
    for k in range(n):
        fk, pk = lobe_eval(kind, color, rough, ior, fresnel, tint, ms, wo, (wi[k, 0], wi[k, 1], wi[k, 2]))
        f[k, 0], f[k, 1], f[k, 2] = fk
        pdf[k] = pk
    return f, pdf


@njit(cache=True)
def _sample_material(mt, m, front, wo, n, seed):
    np.random.seed(seed)
    wi = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    pdf = np.zeros(n)
    event = np.zeros(n, np.int64)
    for k in range(n):
        d, w, p, e = bsdf_sample(mt, m, front, wo, np.random.random(), np.random.random(),
                                 np.random.random(), np.random.random())
        wi[k, 0], wi[k, 1], wi[k, 2] = d
        weight[k, 0], weight[k, 1], weight[k, 2] = w
        pdf[k] = p
        event[k] = e
    return wi, weight, pdf, event


@njit(cache=True)
def _eval_material_at(mt, m, front, wo, wi):
    n = wi.shape[0]
    f = np.zeros((n, 3))
    pdf = np.zeros(n)
    for k in range(n):
        fk, pk = bsdf_eval(mt, m, front, wo, (wi[k, 0], wi[k, 1], wi[k, 2]))
        f[k, 0], f[k, 1], f[k, 2] = fk
        pdf[k] = pk
    return f, pdf


@njit(cache=True)
def _sphere_quadrature(eval_fn, args, wo, n_theta, n_phi, sub):
    """Midpoint quadrature over (theta, phi), dw = sin(theta) dtheta dphi.

    Returns the pdf integrated over each of the n_theta x n_phi bins and the integral of
    f |cos theta| over the whole sphere (the albedo for wo).
    """
    bins = np.zeros((n_theta, n_phi))
    albedo = np.zeros(3)
    nt = n_theta * sub
    npp = n_phi * sub
    dt = math.pi / nt
    dp = 2.0 * math.pi / npp
    for i in range(nt):
        theta = (i + 0.5) * dt
        st, ct = math.sin(theta), math.cos(theta)
        dw = st * dt * dp
        for j in range(npp):
            phi = (j + 0.5) * dp
            wi = (st * math.cos(phi), st * math.sin(phi), ct)
            f, pdf = eval_fn(args, wo, wi)
            bins[i // sub, j // sub] += pdf * dw
            albedo[0] += f[0] * abs(ct) * dw
            albedo[1] += f[1] * abs(ct) * dw
            albedo[2] += f[2] * abs(ct) * dw
    return bins, albedo


@njit(cache=True)
def _lobe_eval_fn(args, wo, wi):
    kind, color, rough, ior, fresnel, tint, ms = args
    return lobe_eval(kind, color, rough, ior, fresnel, tint, ms, wo, wi)


@njit(cache=True)
def _material_eval_fn(args, wo, wi):
    mt, m, front = args
    return bsdf_eval(mt, m, front, wo, wi)


@njit(cache=True)
def _coat_albedo_grid(mus, roughs, etas):
    out = np.zeros((mus.size, roughs.size, etas.size, 2))
    for a in range(mus.size):
        for b in range(roughs.size):
            for c in range(etas.size):
                out[a, b, c, 0] = coat_albedo(mus[a], roughs[b], etas[c])
                out[a, b, c, 1] = _coat_albedo_quadrature(mus[a], roughs[b] ** 2, etas[c], 400)
    return out


# ---------------------------------------------------------------------------------------------
# Statistics.


def _gamma_q(a: float, x: float) -> float:
    """Regularised upper incomplete gamma Q(a, x), by its series or its continued fraction."""
    if x <= 0.0:
        return 1.0
    log_front = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:  # series for P(a, x)
        term = total = 1.0 / a
        ap = a
        for _ in range(10_000):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * 1e-15:
                break
        return 1.0 - total * math.exp(log_front)
    # Lentz's continued fraction for Q(a, x)
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return math.exp(log_front) * h


def chi_square_p(observed: np.ndarray, expected: np.ndarray) -> float:
    """Pearson chi-square p-value; cells expected below 5 are pooled into one cell."""
    observed = np.asarray(observed, float).ravel()
    expected = np.asarray(expected, float).ravel()
    low = expected < 5.0
    obs = np.append(observed[~low], observed[low].sum())
    exp = np.append(expected[~low], expected[low].sum())
    if exp[-1] < 5.0:  # the pooled cell itself is too small: fold it into the smallest cell
        k = np.argmin(exp[:-1])
        obs[k] += obs[-1]
        exp[k] += exp[-1]
        obs, exp = obs[:-1], exp[:-1]
    if np.any((exp == 0.0) & (obs > 0.0)):
        return 0.0
    chi2 = float(np.sum((obs - exp) ** 2 / exp))
    dof = len(exp) - 1
    return _gamma_q(0.5 * dof, 0.5 * chi2)


def histogram(wi: np.ndarray) -> np.ndarray:
    theta = np.arccos(np.clip(wi[:, 2], -1.0, 1.0))
    phi = np.arctan2(wi[:, 1], wi[:, 0]) % (2.0 * np.pi)
    it = np.minimum((theta / np.pi * N_THETA).astype(int), N_THETA - 1)
    ip = np.minimum((phi / (2.0 * np.pi) * N_PHI).astype(int), N_PHI - 1)
    counts = np.zeros((N_THETA, N_PHI))
    np.add.at(counts, (it, ip), 1.0)
    return counts


def assert_mean(samples: np.ndarray, expected, extra_err=0.0, what: str = "") -> None:
    """|mean - expected| < Z_MAX standard errors (+ a known deterministic error bound)."""
    mean = samples.mean(axis=0)
    se = samples.std(axis=0) / math.sqrt(len(samples))
    bound = Z_MAX * se + extra_err
    assert np.all(np.abs(mean - expected) <= bound), f"{what}: mean {mean} expected {expected} +- {bound}"


def lobe_quadrature(kind, color, rough, ior, fresnel, tint, ms, wo):
    """Per-bin pdf integrals and albedo, with the change from halving the step as error bound."""
    args = (kind, color, rough, ior, fresnel, tint, ms)
    bins, albedo = _sphere_quadrature(_lobe_eval_fn, args, wo, N_THETA, N_PHI, SUB)
    bins2, albedo2 = _sphere_quadrature(_lobe_eval_fn, args, wo, N_THETA, N_PHI, 2 * SUB)
    return bins2, albedo2, np.abs(bins2 - bins).sum(), np.abs(albedo2 - albedo)


# ---------------------------------------------------------------------------------------------
# Lobe configurations: (kind, color, roughness, ior, wo), or with the Fresnel mode, tint and
# multiscatter flag appended: (kind, color, roughness, ior, wo, fresnel, tint[, ms]).

BACK = -1.0  # marks a wo seen from the back face

NON_DELTA_CASES = [
    (DIFFUSE, (0.8, 0.5, 0.2), 0.0, 1.5, direction(10)),
    (DIFFUSE, WHITE, 0.0, 1.5, direction(75, 40)),
    (DIFFUSE, WHITE, 0.0, 1.5, direction(130, 200)),  # back face
    (ROUGH_CONDUCTOR, (0.9, 0.6, 0.3), 0.2, 1.5, direction(5)),
    (ROUGH_CONDUCTOR, WHITE, 0.2, 1.5, direction(60, 30)),
    (ROUGH_CONDUCTOR, WHITE, 0.5, 1.5, direction(40)),
    (ROUGH_CONDUCTOR, WHITE, 0.5, 1.5, direction(85, 300)),
    (ROUGH_CONDUCTOR, WHITE, 1.0, 1.5, direction(70)),
    (ROUGH_CONDUCTOR, WHITE, 0.6, 1.5, direction(120, 10)),  # back face
    (ROUGH_CONDUCTOR, (0.9, 0.6, 0.3), 0.35, 1.5, direction(50), FRESNEL_F82, WHITE),
    (ROUGH_CONDUCTOR, WHITE, 0.5, 1.5, direction(80, 20), FRESNEL_F82, WHITE),
    (ROUGH_CONDUCTOR, (0.05, 0.4, 0.9), 0.7, 1.5, direction(70), FRESNEL_F82, (0.3, 0.6, 1.0)),
    (ROUGH_CONDUCTOR, (0.2, 0.2, 0.2), 0.3, 1.5, direction(110, 60), FRESNEL_F82, (0.0, 0.5, 1.0)),
    (PLASTIC, (0.7, 0.2, 0.1), 0.3, 1.5, direction(20)),
    (PLASTIC, WHITE, 0.3, 1.5, direction(70, 100)),
    (PLASTIC, WHITE, 0.8, 2.2, direction(45)),
    (PLASTIC, (0.1, 0.1, 0.1), 0.5, 1.33, direction(80)),
    (PLASTIC, WHITE, 0.0, 1.5, direction(30)),  # smooth coat: delta + diffuse
    (PLASTIC, (0.2, 0.4, 0.6), 0.0, 3.0, direction(80)),
    (PLASTIC, WHITE, 0.4, 1.5, direction(150, 45)),  # back face
    # Multiscatter GGX and the plastic's specular tint.
    (ROUGH_CONDUCTOR, (0.8, 0.8, 0.7), 0.7, 1.5, direction(60), FRESNEL_CONSTANT, WHITE, True),
    (ROUGH_CONDUCTOR, (0.9, 0.6, 0.3), 0.5, 1.5, direction(30), FRESNEL_F82, (0.5, 0.8, 1.0), True),
    (PLASTIC, (0.7, 0.2, 0.1), 0.5, 1.5, direction(50), FRESNEL_CONSTANT, (1.0, 0.5, 0.2), True),
    (PLASTIC, WHITE, 0.9, 1.5, direction(75, 20), FRESNEL_CONSTANT, WHITE, True),
    (PLASTIC, (0.3, 0.5, 0.7), 0.3, 1.45, direction(40), FRESNEL_CONSTANT, (0.2, 0.9, 0.6), False),
]


def unpack(case):
    """(kind, color, roughness, ior, fresnel, tint, ms, wo) of a case."""
    kind, color, rough, ior, wo = case[:5]
    fresnel, tint, ms = (tuple(case[5:]) + (False,))[:3] if len(case) > 5 else PLAIN
    return kind, color, rough, ior, fresnel, tint, ms, wo


def case_id(case) -> str:
    kind, color, rough, ior, fresnel, tint, ms, wo = unpack(case)
    name = {v: k for k, v in LOBE_KINDS.items()}[kind]
    suffix = "-f82" if fresnel == FRESNEL_F82 else ""
    suffix += ("-ms" if ms else "") + ("-tint" if tint != WHITE else "")
    return f"{name}{suffix}-r{rough}-ior{ior}-woz{wo[2]:.2f}"


@pytest.mark.parametrize("case", NON_DELTA_CASES, ids=case_id)
def test_lobe_sampling_matches_pdf(case):
    """(a) chi-square of sampled wi against the binned pdf; (b) the pdf integrates to the
    probability of a non-delta, non-failed sample; (d) E[weight] = integral of f |cos|, <= 1;
    (e) every sample's weight and pdf equal eval's f |cos| / pdf."""
    kind, color, rough, ior, fresnel, tint, ms, wo = unpack(case)
    wi, weight, pdf, delta = _sample_lobe(kind, color, rough, ior, fresnel, tint, ms, wo, N_SAMPLES, 7)
    failed = np.all(weight == 0.0, axis=1)
    scatter = ~failed & ~delta
    # Non-delta samples stay on wo's side: these lobes only reflect.
    assert np.all(np.sign(wi[scatter, 2]) == np.sign(wo[2]))
    assert np.all(pdf[failed] == 0.0)

    # (e) sample and eval agree sample by sample (float64 round-off only).
    f, pdf_eval = _eval_lobe_at(kind, color, rough, ior, fresnel, tint, ms, wo, wi[scatter])
    np.testing.assert_allclose(pdf[scatter], pdf_eval, rtol=1e-7)
    np.testing.assert_allclose(weight[scatter], f * np.abs(wi[scatter, 2:3]) / pdf_eval[:, None], rtol=1e-7)

    # (a) + (b): bins of the sphere plus one cell for "delta or failed".
    bins, albedo, bins_err, albedo_err = lobe_quadrature(kind, color, rough, ior, fresnel, tint, ms, wo)
    mass = bins.sum()
    counts = histogram(wi[scatter])
    observed = np.append(counts.ravel(), np.count_nonzero(~scatter))
    expected = N_SAMPLES * np.append(bins.ravel(), max(0.0, 1.0 - mass))
    p = chi_square_p(observed, expected)
    assert p > P_MIN, f"chi-square p = {p:.2e}"
    q = np.count_nonzero(scatter) / N_SAMPLES
    assert abs(mass - q) <= Z_MAX * math.sqrt(max(q * (1 - q), 1.0 / N_SAMPLES) / N_SAMPLES) + bins_err
    assert mass <= 1.0 + bins_err

    # (d) E[weight] = integral f |cos| + the delta part's albedo (smooth plastic coat: F).
    delta_albedo = 0.0
    if kind == PLASTIC and rough == 0.0:
        delta_albedo = fresnel_dielectric(abs(wo[2]), coat_eta(ior))[0]
    assert_mean(weight, albedo + delta_albedo, albedo_err, "albedo")

    if color == WHITE and not ms:  # (multiscatter: its table's accuracy, test_multiscatter_*)
        se = weight.std(axis=0) / math.sqrt(N_SAMPLES)
        assert np.all(weight.mean(axis=0) <= 1.0 + Z_MAX * se), weight.mean(axis=0)


def test_diffuse_is_exact():
    """Cosine sampling makes the weight exactly the colour, and the pdf is cos / pi."""
    color = (0.8, 0.5, 0.2)
    wo = direction(35, 10)
    wi, weight, pdf, delta = _sample_lobe(DIFFUSE, color, 0.0, 1.5, *PLAIN, wo, 1000, 3)
    assert not delta.any()
    np.testing.assert_allclose(weight, np.tile(color, (1000, 1)), rtol=1e-12)
    np.testing.assert_allclose(pdf, wi[:, 2] / math.pi, rtol=1e-12)
    f, _ = lobe_eval(DIFFUSE, color, 0.0, 1.5, *PLAIN, wo, direction(80, 200))
    np.testing.assert_allclose(f, np.array(color) / math.pi)
    # Opposite sides: no reflection.
    assert lobe_eval(DIFFUSE, color, 0.0, 1.5, *PLAIN, wo, direction(100))[1] == 0.0
    assert lobe_eval(DIFFUSE, color, 0.0, 1.5, *PLAIN, wo, direction(100))[0] == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("kind, rough, fresnel", [
    (DIFFUSE, 0.0, PLAIN), (ROUGH_CONDUCTOR, 0.3, PLAIN), (ROUGH_CONDUCTOR, 0.9, PLAIN),
    (ROUGH_CONDUCTOR, 0.4, (FRESNEL_F82, (0.2, 0.7, 1.0), False))])
def test_reciprocity(kind, rough, fresnel, rng):
    """(c) f(wo, wi) = f(wi, wo) for reflection lobes, on both faces. (Not plastic: Cycles'
    Principled base is weighted by 1 - E(wo) alone, see test_plastic_base_weight.)"""
    color, ior = (0.7, 0.4, 0.9), 1.5
    v = rng.normal(size=(2000, 2, 3))
    v /= np.linalg.norm(v, axis=2, keepdims=True)
    v[:, :, 2] = np.abs(v[:, :, 2]) * np.where(rng.random((2000, 1)) < 0.5, 1.0, -1.0)  # same side
    for a, b in v:
        wa, wb = tuple(a), tuple(b)
        fab = np.array(lobe_eval(kind, color, rough, ior, *fresnel, wa, wb)[0])
        fba = np.array(lobe_eval(kind, color, rough, ior, *fresnel, wb, wa)[0])
        np.testing.assert_allclose(fab, fba, rtol=1e-9, atol=0.0)
        assert np.all(fab > 0.0)


@pytest.mark.parametrize("kind, fresnel", [(DIFFUSE, PLAIN), (ROUGH_CONDUCTOR, PLAIN), (PLASTIC, PLAIN),
                                           (ROUGH_CONDUCTOR, (FRESNEL_F82, WHITE, False)),
                                           (PLASTIC, (FRESNEL_CONSTANT, (0.5, 0.5, 1.0), True))])
def test_opposite_sides_do_not_reflect(kind, fresnel):
    wo = direction(30)
    for wi in (direction(120), direction(95, 70)):
        f, pdf = lobe_eval(kind, WHITE, 0.5, 1.5, *fresnel, wo, wi)
        assert f == (0.0, 0.0, 0.0) and pdf == 0.0


def test_smooth_lobes_and_transparent():
    """Delta lobes: exact directions, weight = colour, nothing to evaluate."""
    color = (0.9, 0.5, 0.1)
    for wo in (direction(40, 30), direction(140, 210)):
        for kind, rough in ((CONDUCTOR, 0.5), (ROUGH_CONDUCTOR, 0.0), (ROUGH_CONDUCTOR, 5e-4)):
            assert lobe_is_delta(kind, rough)
            wi, w, pdf, dl = lobe_sample(kind, color, rough, 1.5, *PLAIN, wo, 0.3, 0.6, 0.9)
            assert dl and pdf == 1.0 and w == color
            np.testing.assert_allclose(wi, (-wo[0], -wo[1], wo[2]), atol=1e-15)
            assert lobe_eval(kind, color, rough, 1.5, *PLAIN, wo, wi) == ((0.0, 0.0, 0.0), 0.0)
            # F82 mode: the weight is the Fresnel curve at the mirror angle.
            tint = (0.4, 0.7, 1.0)
            wi, w, pdf, dl = lobe_sample(kind, color, rough, 1.5, FRESNEL_F82, tint, False, wo, 0.3, 0.6, 0.9)
            assert dl and pdf == 1.0
            assert w == conductor_fresnel(FRESNEL_F82, color, tint, abs(wo[2]))
        wi, w, pdf, dl = lobe_sample(TRANSPARENT, color, 0.0, 1.5, *PLAIN, wo, 0.3, 0.6, 0.9)
        assert dl and w == color and wi == (-wo[0], -wo[1], -wo[2])
    assert not lobe_is_delta(ROUGH_CONDUCTOR, 0.01)
    assert not lobe_is_delta(PLASTIC, 0.0) and not lobe_is_delta(DIFFUSE, 0.0)
    assert lobe_is_delta(DIELECTRIC, 0.0) and lobe_is_delta(TRANSPARENT, 0.0)


# ---------------------------------------------------------------------------------------------
# Dielectric.


def test_fresnel_dielectric():
    for eta in (1.33, 1.5, 2.4, 1 / 1.5):
        f0 = fresnel_dielectric(1.0, eta)[0]
        assert f0 == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-12)
        # Reciprocity of the interface: F(theta_i, eta) = F(theta_t, 1 / eta).
        for cos_i in (0.9, 0.5, 0.1):
            F, cos_t = fresnel_dielectric(cos_i, eta)
            if cos_t > 0.0:
                assert fresnel_dielectric(cos_t, 1 / eta)[0] == pytest.approx(F, rel=1e-10)
        assert fresnel_dielectric(0.0, eta)[0] == pytest.approx(1.0)
    # Brewster's angle zeroes the p polarisation: F = r_s^2 / 2 there.
    eta = 1.5
    cos_b = math.cos(math.atan(eta))
    F, cos_t = fresnel_dielectric(cos_b, eta)
    r_s = (cos_b - eta * cos_t) / (cos_b + eta * cos_t)
    assert F == pytest.approx(0.5 * r_s * r_s, rel=1e-12)
    # Total internal reflection beyond the critical angle.
    assert fresnel_dielectric(math.cos(math.radians(45)), 1 / 1.5) == (1.0, 0.0)


@pytest.mark.parametrize("ior, theta", [(1.5, 0.0), (1.5, 60.0), (1.5, 85.0), (1.33, 30.0),
                                        (1.5, 160.0), (2.4, 170.0), (0.8, 50.0)])
def test_dielectric_reflect_fraction_and_snell(ior, theta):
    """(g) reflection happens with probability F; refraction obeys Snell's law; (d) the white
    furnace: every sample's weight is its branch's tint (reflection `tint`, refraction `color`),
    so R + T averages exactly 1 for white ones."""
    wo = direction(theta, 25.0)
    color, tint = (0.9, 0.7, 0.5), (0.3, 0.6, 1.0)
    wi, weight, pdf, delta = _sample_lobe(DIELECTRIC, color, 0.0, ior, FRESNEL_CONSTANT, tint, False, wo,
                                          N_SAMPLES, 11)
    assert delta.all()
    same_side = (np.sign(wi[:, 2]) == np.sign(wo[2]))[:, None]
    np.testing.assert_allclose(weight, np.where(same_side, tint, color), rtol=0, atol=0)
    _, white, _, _ = _sample_lobe(DIELECTRIC, WHITE, 0.0, ior, *PLAIN, wo, 1000, 12)
    assert np.all(white == 1.0)
    outside = wo[2] >= 0
    eta = ior if outside else 1 / ior
    F = fresnel_dielectric(abs(wo[2]), eta)[0]
    reflected = np.sign(wi[:, 2]) == np.sign(wo[2])
    frac = reflected.mean()
    assert abs(frac - F) <= Z_MAX * math.sqrt(F * (1 - F) / N_SAMPLES) + 1e-12, (frac, F)
    np.testing.assert_allclose(pdf[reflected], F)
    np.testing.assert_allclose(pdf[~reflected], 1 - F)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=1e-12)
    r = wi[reflected]
    np.testing.assert_allclose(r, np.tile((-wo[0], -wo[1], wo[2]), (len(r), 1)), atol=1e-15)
    t = wi[~reflected]
    if len(t):
        sin_i = math.hypot(wo[0], wo[1])
        np.testing.assert_allclose(np.hypot(t[:, 0], t[:, 1]) * eta, sin_i, rtol=1e-12)
        # Refracted: on the far side, in the plane of incidence, tangent reversed.
        assert np.all(np.sign(t[:, 2]) == -np.sign(wo[2]))
        np.testing.assert_allclose(t[:, 0] * wo[1] - t[:, 1] * wo[0], 0.0, atol=1e-15)
        assert np.all(t[:, 0] * wo[0] + t[:, 1] * wo[1] <= 0.0)
    assert lobe_eval(DIELECTRIC, color, 0.0, ior, *PLAIN, wo, tuple(wi[0])) == ((0.0, 0.0, 0.0), 0.0)


def test_dielectric_total_internal_reflection():
    """From inside glass (wo.z < 0, ior 1.5) beyond the critical angle everything reflects."""
    critical = math.degrees(math.asin(1 / 1.5))
    for theta in (critical + 0.5, 60.0, 89.0):
        wo = direction(180.0 - theta, 40.0)
        wi, weight, pdf, _ = _sample_lobe(DIELECTRIC, WHITE, 0.0, 1.5, *PLAIN, wo, 2000, 5)
        assert np.all(wi[:, 2] < 0.0) and np.all(pdf == 1.0) and np.all(weight == 1.0)
    # Just inside the critical angle some light still gets out.
    wo = direction(180.0 - (critical - 2.0))
    wi, _, _, _ = _sample_lobe(DIELECTRIC, WHITE, 0.0, 1.5, *PLAIN, wo, 2000, 5)
    assert np.any(wi[:, 2] > 0.0)


# ---------------------------------------------------------------------------------------------
# Plastic's coat table.


def test_coat_albedo_table_accuracy():
    """Between its nodes the tabulated coat albedo is within the documented 4e-3 of a fine
    quadrature (1e-3 away from grazing), and on the nodes of a smooth coat it is exactly Fresnel."""
    mus = np.array([0.01, 0.03, 0.21, 0.5, 0.77, 0.99])
    roughs = np.array([0.03, 0.11, 0.37, 0.62, 0.95])
    etas = np.array([1.05, 1.2, 1.45, 2.1, 3.7])
    out = _coat_albedo_grid(mus, roughs, etas)
    err = np.abs(out[..., 0] - out[..., 1])
    assert err.max() < 4e-3, err.max()
    assert err[mus > 0.2].max() < 1e-3, err[mus > 0.2].max()
    for i in (0, 9, N_S - 1):
        s = _s_node(i)
        eta = (1 + s) / (1 - s)
        for k in range(N_MU):
            mu = _mu_node(k)
            assert coat_albedo(mu, 0.0, eta) == pytest.approx(fresnel_dielectric(mu, eta)[0], abs=1e-9)


def test_spec_albedo_table_is_cycles_definition():
    """The specular layer's albedo table: node values are the quadrature of Cycles' definition
    (checked against a finer quadrature), the lookup returns them exactly on the nodes and is
    linear between them (Cycles' lookup_table_read_3D), and E = F0 + (1 - F0) s."""
    rng = np.random.default_rng(5)
    for k, j, i in rng.integers(1, N_NODES - 1, size=(12, 3)):  # z = 1 is clamped to 0.99
        rough, mu, eta = node_params(i, j, k)
        assert abs(SPEC_S[k, j, i] - remapped_fresnel_mean(rough, mu, eta, 1024)) < 1e-4
        x, y = i / (N_NODES - 1), j / (N_NODES - 1)
        assert remapped_fresnel_lookup(x, y, eta) == pytest.approx(SPEC_S[k, j, i], abs=1e-9)
        if i < N_NODES - 1:  # halfway between two roughness nodes
            mid = remapped_fresnel_lookup(x + 0.5 / (N_NODES - 1), y, eta)
            assert mid == pytest.approx(0.5 * (SPEC_S[k, j, i] + SPEC_S[k, j, i + 1]), abs=1e-9)
        f0 = f0_from_eta(eta)
        assert spec_albedo(y, x, eta) == pytest.approx(f0 + (1 - f0) * SPEC_S[k, j, i], abs=1e-9)
    # Cycles' first z slice is index exactly 1 in single precision: nothing reflects.
    assert np.all(SPEC_S[0] < 1e-15)
    # Smooth layer (roughness node 0): s is the remapped Fresnel at the node's own angle.
    for j in (3, 8, 15):
        rough, mu, eta = node_params(0, j, 6)
        f0 = f0_from_eta(eta)
        assert SPEC_S[6, j, 0] == pytest.approx((fresnel_dielectric(mu, eta)[0] - f0) / (1 - f0), abs=1e-4)


def test_plastic_energy_floor():
    """The base weight 1 - max(E, E_ss) keeps a white plastic's albedo E_ss + (1 - max(E, E_ss))
    <= 1 within the accuracy of the E_ss table (4e-3 for mu >= 0.01, its tested range), also at
    grazing angles on nearly smooth layers, where Cycles' coarse estimate E alone falls below
    E_ss by up to 0.03."""
    worst_cycles = 0.0
    for mu in (0.01, 0.02, 0.05, 0.1, 0.15, 0.4):
        for rough in (0.03, 0.1, 0.3, 0.8):
            for eta in (1.05, 1.5, 2.4):
                e_ss = _coat_albedo_quadrature(mu, rough * rough, eta, 400)
                assert e_ss - layer_albedo(mu, rough, eta) < 4e-3, (mu, rough, eta)
                worst_cycles = max(worst_cycles, e_ss - spec_albedo(mu, rough, eta))
    assert worst_cycles > 0.01  # the floor matters: Cycles' estimate alone would gain energy


@pytest.mark.parametrize("rough, ior", [(0.0, 1.5), (0.0, 2.4), (0.25, 1.45), (0.6, 1.5)])
def test_plastic_base_weight(rough, ior):
    """Cycles' Principled BSDF: the diffuse base is color / pi (1 - E(wo)), independent of wi
    (no 1 - E(wi) factor). With a smooth layer eval holds only the base; for a rough one the
    base is what remains after subtracting the layer (the same lobe with a black base)."""
    color = (0.6, 0.3, 0.1)
    for wo in (direction(10), direction(60, 30), direction(85, 200)):
        kd = (1.0 - layer_albedo(wo[2], rough, ior)) / math.pi
        for wi in (direction(5), direction(45, 100), direction(80, 250)):
            f = np.array(lobe_eval(PLASTIC, color, rough, ior, *PLAIN, wo, wi)[0])
            f_layer = np.array(lobe_eval(PLASTIC, (0.0, 0.0, 0.0), rough, ior, *PLAIN, wo, wi)[0])
            np.testing.assert_allclose(f - f_layer, np.array(color) * kd, rtol=1e-9, atol=1e-15)
            if rough == 0.0:
                assert np.all(f_layer == 0.0)


def test_f82_fresnel():
    """Cycles' F82-tint curve: F0 at normal incidence, 1 at grazing, Schlick with a white tint,
    and Schlick x tint at cos = 1/7 (about 82 degrees); the constant mode is the colour."""
    f0 = (0.9, 0.6, 0.05)
    tint = (1.0, 0.5, 0.0)
    np.testing.assert_allclose(conductor_fresnel(FRESNEL_F82, f0, tint, 1.0), f0, atol=1e-12)
    np.testing.assert_allclose(conductor_fresnel(FRESNEL_F82, f0, tint, 0.0), 1.0, atol=1e-12)
    for c in (0.05, 1 / 7, 0.3, 0.7):
        schlick = np.array(f0) + (1 - np.array(f0)) * (1 - c) ** 5
        np.testing.assert_allclose(conductor_fresnel(FRESNEL_F82, f0, WHITE, c), schlick, rtol=1e-12)
    schlick82 = np.array(f0) + (1 - np.array(f0)) * (6 / 7) ** 5
    np.testing.assert_allclose(conductor_fresnel(FRESNEL_F82, f0, tint, 1 / 7), schlick82 * np.array(tint),
                               rtol=1e-12, atol=1e-12)
    assert conductor_fresnel(FRESNEL_CONSTANT, f0, tint, 0.2) == f0


# ---------------------------------------------------------------------------------------------
# Material mixtures.

MIXTURES = [
    Material("glossy_diffuse", [
        Lobe("diffuse", weight=(0.5, 0.5, 0.5), color=(0.8, 0.3, 0.2)),
        Lobe("rough_conductor", weight=(0.5, 0.4, 0.3), color=(0.9, 0.9, 0.6), roughness=0.35),
        Lobe("rough_conductor", weight=(0.2, 0.2, 0.2), color=(0.05, 0.02, 0.01), roughness=0.5,
             fresnel="f82", tint=(0.5, 0.8, 1.0)),
    ]),
    Material("layered", [
        Lobe("plastic", weight=(0.6, 0.6, 0.6), color=(0.2, 0.5, 0.8), roughness=0.0, ior=1.5),
        Lobe("rough_conductor", weight=(0.3, 0.3, 0.3), color=WHITE, roughness=0.7),
        Lobe("transparent", weight=(0.1, 0.2, 0.1), color=(1.0, 0.5, 1.0), sides="front"),
        Lobe("dielectric", weight=(0.2, 0.2, 0.2), color=WHITE, ior=1.4, sides="back"),
    ]),
    Material("front_only", [Lobe("diffuse", color=WHITE, sides="front")]),
    Material("empty"),
]
MT = build_material_table(MIXTURES)


def test_material_table_layout():
    mats, lobes = MT
    assert mats.dtype == np.int32 and lobes.dtype == np.float32
    assert mats.flags.c_contiguous and lobes.flags.c_contiguous
    assert mats.tolist() == [[0, 3], [3, 4], [7, 1], [8, 0]]
    assert lobes.shape[1] == 15
    assert lobes[:, L_MS].tolist() == [0.0] * 8
    assert lobes[:, L_KIND].tolist() == [DIFFUSE, ROUGH_CONDUCTOR, ROUGH_CONDUCTOR, PLASTIC, ROUGH_CONDUCTOR,
                                         TRANSPARENT, DIELECTRIC, DIFFUSE]
    assert lobes[:, L_SIDES].tolist() == [3, 3, 3, 3, 3, 1, 2, 1]
    fresnel = [FRESNEL_CONSTANT] * 8
    fresnel[2] = FRESNEL_F82
    assert lobes[:, L_FRESNEL].tolist() == fresnel
    np.testing.assert_array_equal(lobes[2, L_TINT:L_TINT + 3], np.float32((0.5, 0.8, 1.0)))
    np.testing.assert_array_equal(lobes[0, L_TINT:L_TINT + 3], np.float32(WHITE))
    lobe = MIXTURES[1].lobes[1]
    np.testing.assert_array_equal(lobes[4, L_WEIGHT:L_WEIGHT + 3], np.float32(lobe.weight))
    np.testing.assert_array_equal(lobes[4, L_COLOR:L_COLOR + 3], np.float32(lobe.color))
    assert lobes[4, L_ROUGH] == np.float32(lobe.roughness) and lobes[4, L_IOR] == np.float32(lobe.ior)
    empty = build_material_table([])
    assert empty[0].shape == (0, 2) and empty[1].shape[0] == 0
    assert bsdf_has_lobes(MT, 3, True) is False  # numba accepts the layout
    with pytest.raises(ValueError):
        build_material_table([Material("bad", [Lobe("velvet")])])
    with pytest.raises(ValueError):
        build_material_table([Material("bad", [Lobe("rough_conductor", fresnel="schlick")])])


def test_material_sides_and_pass_through():
    wo = direction(30)
    assert bsdf_has_lobes(MT, 2, True) and not bsdf_has_lobes(MT, 2, False)
    assert not bsdf_has_lobes(MT, 3, True) and not bsdf_has_lobes(MT, 3, False)
    for m, front in ((2, False), (3, True), (3, False)):
        wi, w, pdf, event = bsdf_sample(MT, m, front, wo, 0.5, 0.5, 0.5, 0.5)
        assert event == EVENT_PASS_THROUGH and w == (1.0, 1.0, 1.0) and wi == (-wo[0], -wo[1], -wo[2])
        assert bsdf_eval(MT, m, front, wo, direction(20)) == ((0.0, 0.0, 0.0), 0.0)
    f, pdf = bsdf_eval(MT, 2, True, wo, direction(20))
    assert f == pytest.approx((1 / math.pi,) * 3)
    assert pdf == pytest.approx(math.cos(math.radians(20)) / math.pi)


def _luminance(c) -> float:
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


@pytest.mark.parametrize("m, front, wo", [(0, True, direction(35, 20)), (0, False, direction(110, 70)),
                                          (1, True, direction(50, 120)), (1, False, direction(140, 300))],
                         ids=["glossy-front", "glossy-back", "layered-front", "layered-back"])
def test_material_mixture(m, front, wo):
    """(f) bsdf_sample's non-delta directions follow bsdf_eval's mixture pdf (chi-square, with
    delta and pass-through events as one extra cell); their weights are f |cos| / pdf; delta
    and pass-through events happen with the lobes' selection probabilities; E[weight] adds up
    the lobes' albedos."""
    wi, weight, pdf, event = _sample_material(MT, m, front, wo, N_SAMPLES, 21)
    scatter = event == EVENT_SCATTER
    assert set(np.unique(event)) <= {EVENT_ABSORB, EVENT_SCATTER, EVENT_DELTA, EVENT_PASS_THROUGH}
    assert np.any(event == EVENT_DELTA) == (m == 1)
    f, pdf_eval = _eval_material_at(MT, m, front, wo, wi[scatter])
    np.testing.assert_allclose(pdf[scatter], pdf_eval, rtol=1e-12)
    np.testing.assert_allclose(weight[scatter], f * np.abs(wi[scatter, 2:3]) / pdf_eval[:, None], rtol=1e-12)
    assert np.all(pdf[~scatter] == 0.0)

    args = (MT, m, front)
    bins, albedo = _sphere_quadrature(_material_eval_fn, args, wo, N_THETA, N_PHI, 2 * SUB)
    bins1, albedo1 = _sphere_quadrature(_material_eval_fn, args, wo, N_THETA, N_PHI, SUB)
    observed = np.append(histogram(wi[scatter]).ravel(), np.count_nonzero(~scatter))
    expected = N_SAMPLES * np.append(bins.ravel(), max(0.0, 1.0 - bins.sum()))
    p = chi_square_p(observed, expected)
    assert p > P_MIN, f"chi-square p = {p:.2e}"

    # Selection probabilities of the delta lobes and their albedo.
    lobes = [lobe for lobe in MIXTURES[m].lobes if lobe.sides in ("both", "front" if front else "back")]
    def selection(lb) -> float:
        if lb.kind in ("dielectric", "plastic"):
            return _luminance(lb.weight)
        color = np.array(lb.color)
        if lb.fresnel == "f82":  # mean reflectance of the F82 curve without its tint term
            color = color + (1.0 - color) / 21.0
        return _luminance(np.multiply(lb.weight, color))

    sel = np.array([selection(lb) for lb in lobes])
    sel /= sel.sum()
    delta_albedo = np.zeros(3)
    for lb, ps in zip(lobes, sel):
        if lb.kind == "transparent":
            frac = np.mean(event == EVENT_PASS_THROUGH)
            assert abs(frac - ps) <= Z_MAX * math.sqrt(ps * (1 - ps) / N_SAMPLES)
            delta_albedo += np.multiply(lb.weight, lb.color)
        elif lb.kind == "dielectric":
            delta_albedo += np.multiply(lb.weight, lb.color)  # R + T = colour
        elif lb.kind == "plastic" and lb.roughness == 0.0:
            F = fresnel_dielectric(abs(wo[2]), coat_eta(lb.ior))[0]
            delta_albedo += np.multiply(lb.weight, F)
    assert_mean(weight, albedo + delta_albedo, np.abs(albedo - albedo1), "mixture albedo")
