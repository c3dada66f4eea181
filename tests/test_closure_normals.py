"""Per-closure normals on a bumped surface (renderer.bsdfs.closure_normals): each lobe on its own
normal, the mixture's sampling consistent with its evaluation, and the unbumped case unchanged.

Fixed seeds; tolerances as tests/test_bsdfs.py's (5 standard errors, chi-square p > 1e-3,
quadrature error from halving the step).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from test_bsdfs import N_PHI, N_THETA, P_MIN, assert_mean, chi_square_p, direction, histogram

from renderer.bsdfs import DIFFUSE, FRESNEL_CONSTANT, PLASTIC, ROUGH_CONDUCTOR
from renderer.bsdfs.closure_normals import specular_normal
from renderer.bsdfs.coat_albedo import coat_eta
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.lobe import lobe_eval, lobe_eval_bumped
from renderer.bsdfs.material import (
    EVENT_ABSORB,
    EVENT_DELTA,
    EVENT_SCATTER,
    bsdf_eval,
    bsdf_eval_bumped,
    bsdf_sample_bumped,
)
from renderer.bsdfs.table import build_material_table
from renderer.scene import Lobe, Material
from renderer.shading.normals import bump_shadowing

N_SAMPLES = 200_000
SUB = 24
WHITE = (1.0, 1.0, 1.0)
COLOR = (0.6, 0.5, 0.4)

MATERIALS = [
    Material("plastic", [Lobe("plastic", color=COLOR, roughness=0.35)]),
    Material("smooth plastic", [Lobe("plastic", color=COLOR, roughness=0.0)]),
    Material("diffuse + metal", [Lobe("diffuse", color=COLOR, weight=(0.5, 0.5, 0.5)),
                                 Lobe("rough_conductor", color=(0.9, 0.6, 0.4), roughness=0.3,
                                      weight=(0.5, 0.5, 0.5))]),
]
MT = build_material_table(MATERIALS)


def unit(v) -> tuple[float, float, float]:
    v = np.asarray(v, float)
    return tuple(float(x) for x in v / np.linalg.norm(v))


# The program's normal tilted 35 degrees off the frame's z, the mesh's own 12 degrees another way
# (a flat mesh: the specular normal lies between them). On a smooth mesh (SAME_SIDE) the mesh's
# normal may lean the program's way, and the base then reflects below the layer's horizon.
N_MAP = direction(35, 60)
N_MESH = direction(12, 250)
BUMP = (N_MAP, N_MESH)
SAME_SIDE = (direction(50, 0), direction(20, 0))


# Not cache=True: numba would key the cache by this file alone, and reuse stale copies of the
# renderer kernels these loops compile in.
@njit
def _sample(mt, m, front, bump, wo, n, seed):
    np.random.seed(seed)
    wi = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    pdf = np.zeros(n)
    event = np.zeros(n, np.int64)
    for k in range(n):
        d, w, p, e = bsdf_sample_bumped(mt, m, front, bump, wo, np.random.random(), np.random.random(),
                                        np.random.random(), np.random.random())
        wi[k, 0], wi[k, 1], wi[k, 2] = d
        weight[k, 0], weight[k, 1], weight[k, 2] = w
        pdf[k] = p
        event[k] = e
    return wi, weight, pdf, event


@njit
def _eval_at(mt, m, front, bump, wo, wi):
    n = wi.shape[0]
    f = np.zeros((n, 3))
    pdf = np.zeros(n)
    for k in range(n):
        fk, pk = bsdf_eval_bumped(mt, m, front, bump, wo, (wi[k, 0], wi[k, 1], wi[k, 2]))
        f[k, 0], f[k, 1], f[k, 2] = fk
        pdf[k] = pk
    return f, pdf


@njit
def _quadrature(mt, m, front, bump, wo, n_theta, n_phi, sub):
    """Midpoint quadrature over (theta, phi): the pdf integrated over each bin, and the
    integral of f cos (bsdf_eval_bumped's f already holds the cosines)."""
    bins = np.zeros((n_theta, n_phi))
    albedo = np.zeros(3)
    nt, npp = n_theta * sub, n_phi * sub
    dt, dp = math.pi / nt, 2.0 * math.pi / npp
    for i in range(nt):
        theta = (i + 0.5) * dt
        st, ct = math.sin(theta), math.cos(theta)
        dw = st * dt * dp
        for j in range(npp):
            phi = (j + 0.5) * dp
            f, pdf = bsdf_eval_bumped(mt, m, front, bump, wo, (st * math.cos(phi), st * math.sin(phi), ct))
            bins[i // sub, j // sub] += pdf * dw
            for c in range(3):
                albedo[c] += f[c] * dw
    return bins, albedo


def _back(w):
    return (w[0], w[1], -w[2])


CASES = [  # (material, front, wo, bump)
    (0, True, direction(40, 10), BUMP),
    (0, True, direction(75, 240), BUMP),  # the view below the program's normal: the base still reflects
    (0, False, _back(direction(50, 120)), BUMP),
    (0, True, direction(80, 180), SAME_SIDE),
    (1, True, direction(30, 200), BUMP),
    (2, True, direction(60, 300), BUMP),
    (2, False, _back(direction(20, 80)), BUMP),
    (2, True, direction(80, 180), SAME_SIDE),
]


@pytest.mark.parametrize("m, front, wo, bump", CASES)
def test_bumped_mixture(m, front, wo, bump):
    """bsdf_sample_bumped's non-delta directions follow bsdf_eval_bumped's mixture pdf (the
    parts' pdfs in their own frames), their weights are its f cos / pdf, and E[weight] is the
    integral of its f cos plus the smooth layer's mirror reflection."""
    wi, weight, pdf, event = _sample(MT, m, front, bump, wo, N_SAMPLES, 5)
    assert set(np.unique(event)) <= {EVENT_ABSORB, EVENT_SCATTER, EVENT_DELTA}
    scatter = event == EVENT_SCATTER
    f, pdf_eval = _eval_at(MT, m, front, bump, wo, wi[scatter])
    np.testing.assert_allclose(pdf[scatter], pdf_eval, rtol=1e-12)
    np.testing.assert_allclose(weight[scatter], f / pdf_eval[:, None], rtol=1e-12)

    bins, albedo = _quadrature(MT, m, front, bump, wo, N_THETA, N_PHI, 2 * SUB)
    _, albedo1 = _quadrature(MT, m, front, bump, wo, N_THETA, N_PHI, SUB)
    observed = np.append(histogram(wi[scatter]).ravel(), np.count_nonzero(~scatter))
    expected = N_SAMPLES * np.append(bins.ravel(), max(0.0, 1.0 - bins.sum()))
    p = chi_square_p(observed, expected)
    assert p > P_MIN, f"chi-square p = {p:.2e}"

    mirror = 0.0
    if MATERIALS[m].name == "smooth plastic":  # the mirror: F for the view, in the layer's frame
        assert np.any(event == EVENT_DELTA)
        mirror = fresnel_dielectric(abs(wo[2]), coat_eta(1.5))[0]
    assert_mean(weight, albedo + mirror, np.abs(albedo - albedo1), "bumped mixture albedo")


@pytest.mark.parametrize("m", range(len(MATERIALS)))
def test_unbumped_normals_give_the_unbumped_bsdf(m):
    """With the program's and the mesh's normal both the frame's z, bsdf_eval_bumped is
    bsdf_eval times the cosine."""
    up = (0.0, 0.0, 1.0)
    rng = np.random.default_rng(2)
    for _ in range(200):
        wo, wi = unit(rng.normal(size=3)), unit(rng.normal(size=3))
        front = wo[2] > 0.0
        f, pdf = bsdf_eval(MT, m, front, wo, wi)
        fb, pdfb = bsdf_eval_bumped(MT, m, front, (up, up), wo, wi)
        np.testing.assert_allclose(fb, np.multiply(f, abs(wi[2])), rtol=1e-12, atol=1e-300)
        assert pdfb == pytest.approx(pdf, rel=1e-12, abs=1e-300)


def test_each_closure_on_its_own_normal():
    """Cycles' rule: the diffuse closure on the program's normal with the bump shadowing term;
    a specular closure on the frame's (corrected) normal, unsoftened; plastic's layer as the
    specular closure and its base as the diffuse one, weighted for the view by the layer."""
    plain = (FRESNEL_CONSTANT, WHITE, False)
    wo = direction(50, 30)
    shadows = []
    for wi in (direction(20, 100), direction(70, 200), direction(85, 60), direction(60, 250)):
        shadow = bump_shadowing(N_MESH, N_MAP, wi)
        shadows.append(shadow)
        cos_map = max(float(np.dot(N_MAP, wi)), 0.0)
        f, _ = lobe_eval_bumped(DIFFUSE, COLOR, 0.0, 1.5, *plain, BUMP, wo, wi)
        np.testing.assert_allclose(f, np.multiply(COLOR, cos_map * shadow / math.pi), rtol=1e-12)

        visible = float(np.dot(N_MESH, wi) * N_MESH[2] * wi[2] >= 0.0)
        f, _ = lobe_eval_bumped(ROUGH_CONDUCTOR, COLOR, 0.3, 1.5, *plain, BUMP, wo, wi)
        spec = lobe_eval(ROUGH_CONDUCTOR, COLOR, 0.3, 1.5, *plain, wo, wi)[0]
        np.testing.assert_allclose(f, np.multiply(spec, wi[2] * visible), rtol=1e-12)

        f, _ = lobe_eval_bumped(PLASTIC, COLOR, 0.35, 1.5, *plain, BUMP, wo, wi)
        layer = np.array(lobe_eval(PLASTIC, (0.0, 0.0, 0.0), 0.35, 1.5, *plain, wo, wi)[0])
        base = np.array(lobe_eval(PLASTIC, COLOR, 0.35, 1.5, *plain, wo, wi)[0]) - layer
        np.testing.assert_allclose(f, layer * wi[2] * visible + base * cos_map * shadow, rtol=1e-9)
    assert min(shadows) == 0.0 and 0.0 < max(shadows) < 1.0  # through the mesh; softened


def test_specular_normal():
    """The specular closures' normal keeps the view's mirror reflection above the geometric
    normal, leaves a valid normal as it is, and is the same seen from either side."""
    ng = (0.0, 0.0, 1.0)
    d = tuple(-x for x in direction(70, 0))  # toward the surface
    valid = direction(10, 0)  # tilted toward the viewer
    assert specular_normal(valid, ng, d, True) == valid
    n_map = direction(40, 180)  # tilted away from the viewer: its mirror reflection dips below
    n = np.array(specular_normal(n_map, ng, d, True))
    wi = -np.array(d)
    r = 2.0 * np.dot(n, wi) * n - wi
    assert abs(np.linalg.norm(n) - 1.0) < 1e-12 and np.dot(ng, r) >= 0.0
    # The same seen from below: normals are handed over, and come back, on the front side.
    below = np.array([1.0, 1.0, -1.0])
    n_back = specular_normal(tuple(-below * n_map), ng, tuple(below * d), False)
    np.testing.assert_allclose(n_back, -below * n, atol=1e-15)
