"""Directional albedo E(mu) of a GGX dielectric coat, tabulated offline and loaded at import.

E(mu; roughness, eta) = integral of f_spec(wo, wi) cos(wi) dwi for wo.z = mu, where f_spec
is the coat's single-scattering GGX reflection with the exact dielectric Fresnel. The
plastic lobe uses it as a floor under Cycles' own (coarser) albedo estimate of its specular
layer (renderer.bsdfs.spec_albedo), which keeps its albedo <= 1 where that estimate falls
below E; E_avg (the cosine-weighted mean) is tabulated too but no lobe uses it now.

The table is computed offline (it needs ~1e8 GGX evaluations for 1e-4 accuracy, because
the visible-normal map has square-root edges that slow the quadrature down) and stored next
to this file; regenerate with `python -m renderer.bsdfs.coat_albedo` (then touch this file:
numba's cache keys on the source, and the table is frozen into the compiled kernels).

The table is trilinear in (roughness, s, mu) with s = (eta - 1) / (eta + 1) = sqrt(F0)
(F0 is nearly quadratic in eta near 1); the nodes of all three crowd toward grazing, smooth
and eta = 1, where E changes fastest.
E_avg = 2 integral E(mu) mu dmu is integrated exactly for the piecewise-linear interpolant in
mu, so the diffuse part's albedo uses the same E as the tabulated lookup (no mismatch
between the two). Roughness 0 holds the exact smooth-interface Fresnel.

Accuracy (tests/test_bsdfs.py): within 4e-3 of a fine quadrature between the nodes, the
worst case being grazing angles on nearly smooth coats with eta near 1 (where Fresnel at
grazing jumps from 0 at eta = 1 to 1 for any eta > 1); below 1e-3 away from grazing.
"""

import math

import numpy as np

from renderer.bsdfs import baked
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.microfacet import ggx_G1, ggx_G2, ggx_sample_visible_normal, reflect
from renderer.kernels import kernel

COAT_ETA_MAX = 4.0  # plastic clamps its coat index to [1, COAT_ETA_MAX]
N_MU = 32
N_S = 32
N_ROUGH = 24
_S_MAX = (COAT_ETA_MAX - 1.0) / (COAT_ETA_MAX + 1.0)
_N_QUAD = 384  # midpoint visible-normal quadrature, _N_QUAD^2 points per entry
_TABLE_PATH = baked.table_path(__file__, "coat_albedo")


@kernel
def _coat_albedo_quadrature(mu, alpha, eta, n):
    """E(mu) by midpoint quadrature over the visible-normal distribution.

    With h ~ D_wo the reflected estimator is F(wo.h) G2 / G1(wo) (see rough_conductor).
    """
    mu = max(mu, 1e-4)
    wo = (math.sqrt(max(0.0, 1.0 - mu * mu)), 0.0, mu)
    g1 = ggx_G1(alpha, wo)
    acc = 0.0
    for a in range(n):
        for b in range(n):
            h = ggx_sample_visible_normal(alpha, wo, (a + 0.5) / n, (b + 0.5) / n)
            wi = reflect(wo, h)
            if wi[2] <= 0.0:
                continue
            cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
            acc += fresnel_dielectric(cos_oh, eta)[0] * ggx_G2(alpha, wo, wi) / g1
    return acc / (n * n)


@kernel
def _mu_node(k):
    """mu at node k: the nodes crowd toward grazing (mu = x^2, x uniform), where E changes
    fastest (Fresnel near eta = 1, shadowing at low roughness)."""
    x = k / (N_MU - 1)
    return x * x


@kernel
def _s_node(i):
    """s at node i, crowded toward eta = 1 (s = _S_MAX z^2): near grazing E depends on
    mu / sqrt(eta^2 - 1) ~ mu / sqrt(s), steep in s as the index approaches 1."""
    z = i / (N_S - 1)
    return _S_MAX * z * z


@kernel
def _rough_node(j):
    """Roughness at node j, crowded toward 0 (roughness = y^2): at grazing angles a little
    roughness already shadows much of the coat."""
    y = j / (N_ROUGH - 1)
    return y * y


@kernel
def build_tables(n_quad):
    e = np.zeros((N_ROUGH, N_S, N_MU))
    e_avg = np.zeros((N_ROUGH, N_S))
    for r in range(N_ROUGH):
        rough = _rough_node(r)
        for si in range(N_S):
            s = _s_node(si)
            eta = (1.0 + s) / (1.0 - s)
            for k in range(N_MU):
                mu = _mu_node(k)
                if r == 0:
                    e[r, si, k] = fresnel_dielectric(mu, eta)[0]
                else:
                    e[r, si, k] = _coat_albedo_quadrature(mu, rough * rough, eta, n_quad)
            # 2 * integral of (E linear in mu on each [mu_k, mu_k+1]) * mu, exactly.
            acc = 0.0
            for k in range(N_MU - 1):
                m0 = _mu_node(k)
                m1 = _mu_node(k + 1)
                e0 = e[r, si, k]
                e1 = e[r, si, k + 1]
                acc += (m1 - m0) * (e0 * (2.0 * m0 + m1) + e1 * (m0 + 2.0 * m1)) / 6.0
            e_avg[r, si] = 2.0 * acc
    return e, e_avg


if __name__ == "__main__":
    _e, _e_avg = build_tables(_N_QUAD)
    baked.save(_TABLE_PATH, e=_e, e_avg=_e_avg)
else:
    # Global arrays are frozen into the kernels below as constants when they compile.
    COAT_E, COAT_E_AVG = baked.load(_TABLE_PATH, {"e": (N_ROUGH, N_S, N_MU), "e_avg": (N_ROUGH, N_S)})


@kernel
def coat_eta(ior):
    """The coat's relative index, >= 1 (a coat is seen from outside) and clamped to the table."""
    eta = ior if ior >= 1.0 else 1.0 / max(ior, 1e-6)
    return min(eta, COAT_ETA_MAX)


@kernel
def _lower_node(x, n):
    """Index of the node at or below x in [0, 1] on a grid of n uniform nodes (last cell closed)."""
    return min(int(min(max(x, 0.0), 1.0) * (n - 1)), n - 2)


@kernel
def _coords(roughness, eta):
    s = (eta - 1.0) / (eta + 1.0)
    roughness = min(max(roughness, 0.0), 1.0)
    ri = _lower_node(math.sqrt(roughness), N_ROUGH)
    r0 = _rough_node(ri)
    rf = (roughness - r0) / (_rough_node(ri + 1) - r0)
    s = min(max(s, 0.0), _S_MAX)
    si = _lower_node(math.sqrt(s / _S_MAX), N_S)
    s0 = _s_node(si)
    sf = (s - s0) / (_s_node(si + 1) - s0)
    return ri, rf, si, sf


@kernel
def coat_albedo(mu, roughness, eta):
    """Tabulated E(mu) of the coat (eta >= 1, roughness in [0, 1])."""
    ri, rf, si, sf = _coords(roughness, eta)
    mu = min(max(mu, 0.0), 1.0)
    ki = _lower_node(math.sqrt(mu), N_MU)
    m0 = _mu_node(ki)
    kf = (mu - m0) / (_mu_node(ki + 1) - m0)  # linear in mu, as E_avg assumes
    acc = 0.0
    for dr in range(2):
        wr = rf if dr else 1.0 - rf
        for ds in range(2):
            ws = sf if ds else 1.0 - sf
            row = COAT_E[ri + dr, si + ds]
            acc += wr * ws * ((1.0 - kf) * row[ki] + kf * row[ki + 1])
    return acc


@kernel
def coat_albedo_avg(roughness, eta):
    """E_avg = 2 integral E(mu) mu dmu of the same interpolant coat_albedo uses."""
    ri, rf, si, sf = _coords(roughness, eta)
    return ((1.0 - rf) * ((1.0 - sf) * COAT_E_AVG[ri, si] + sf * COAT_E_AVG[ri, si + 1])
            + rf * ((1.0 - sf) * COAT_E_AVG[ri + 1, si] + sf * COAT_E_AVG[ri + 1, si + 1]))
