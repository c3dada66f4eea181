"""Cycles' Multiscatter GGX: the energy compensation of a GGX reflection lobe.

A single-scattering GGX lobe loses the light that bounces between microfacets more than
once: its directional albedo E(roughness, mu) with white Fresnel is below 1 (mu = wo.z).
Cycles' "Multiscatter GGX" (closure/bsdf_microfacet.h, microfacet_ggx_preserve_energy, after
Kulla and Conty, "Revisiting Physically Based Shading at Imageworks") scales the lobe by

    1 + Fms (1 - E) / E,    Fms = Fss E_avg / (1 - Fss (1 - E_avg))

per channel, a factor of wo alone: with white Fresnel (Fss = 1) it brings the albedo back
to 1; a coloured Fresnel, whose hemispherical average is Fss, gets the saturation of its
repeated bounces. E_avg(roughness) = 2 * integral of E mu dmu.

E is tabulated as Cycles tabulates ggx_E: 32 x 32 nodes uniform in roughness (x) and mu
(y), here from our own deterministic visible-normal quadrature (E = mean of G2 / G1(wo)
over visible normals whose mirror direction is above the horizon), roughness and mu clamped
to >= 1e-4 at the nodes; E_avg on the same 32 roughness nodes. Compared with the tables in
the bpy 5.0.1 wheel's binary, E agrees within 1.5e-3 (mean 1e-4), E_avg within 2e-3. Both are read with
Cycles' linear interpolation (lookup_table_read, _2D). Regenerate with
`python -m renderer.bsdfs.multiscatter` (then touch this file: the tables are frozen into
the compiled kernels).
"""

import math

import numpy as np

from renderer.bsdfs import baked
from renderer.bsdfs.microfacet import ggx_G1, ggx_G2, ggx_sample_visible_normal, reflect
from renderer.kernels import inline_kernel, kernel

N_NODES = 32
_N_QUAD = 256  # visible-normal quadrature per node, _N_QUAD^2 points
_N_MU = 128  # midpoint rule in mu for E_avg
_TABLE_PATH = baked.table_path(__file__, "ggx_energy")


@kernel
def ggx_albedo(rough, mu, n):
    """E: directional albedo of the GGX lobe with white Fresnel, n x n quadrature."""
    alpha = rough * rough
    wo = (math.sqrt(max(0.0, 1.0 - mu * mu)), 0.0, mu)
    g1 = ggx_G1(alpha, wo)
    acc = 0.0
    for a in range(n):
        for b in range(n):
            h = ggx_sample_visible_normal(alpha, wo, (a + 0.5) / n, (b + 0.5) / n)
            wi = reflect(wo, h)
            if wi[2] > 0.0:
                acc += ggx_G2(alpha, wo, wi) / g1
    return acc / (n * n)


@kernel
def build_tables(e, e_avg, n_quad, n_mu):
    """Fill e (N_NODES, N_NODES) [mu, roughness] and e_avg (N_NODES,) [roughness]."""
    n1 = N_NODES - 1.0
    for x in range(N_NODES):
        rough = max(x / n1, 1e-4)
        for y in range(N_NODES):
            e[y, x] = ggx_albedo(rough, max(y / n1, 1e-4), n_quad)
        acc = 0.0
        for k in range(n_mu):
            mu = (k + 0.5) / n_mu
            acc += ggx_albedo(rough, mu, n_quad // 2) * mu
        e_avg[x] = 2.0 * acc / n_mu


if __name__ == "__main__":
    _e, _avg = np.zeros((N_NODES, N_NODES)), np.zeros(N_NODES)
    build_tables(_e, _avg, _N_QUAD, _N_MU)
    baked.save(_TABLE_PATH, E=_e, E_avg=_avg)
else:
    # Global arrays are frozen into the kernels below as constants when they compile.
    GGX_E, GGX_E_AVG = baked.load(_TABLE_PATH, {"E": (N_NODES, N_NODES), "E_avg": (N_NODES,)})


@inline_kernel
def _cell(x):
    """Cycles' lookup_table_read coordinates: lower node, upper node, weight of the upper."""
    x = min(max(x, 0.0), 1.0) * (N_NODES - 1)
    i = min(int(x), N_NODES - 1)
    return i, min(i + 1, N_NODES - 1), x - i


@kernel
def ggx_energy(roughness, mu):
    """(E(roughness, mu), E_avg(roughness)) read from the tables."""
    x0, x1, tx = _cell(roughness)
    y0, y1, ty = _cell(mu)
    e = ((1.0 - ty) * ((1.0 - tx) * GGX_E[y0, x0] + tx * GGX_E[y0, x1])
         + ty * ((1.0 - tx) * GGX_E[y1, x0] + tx * GGX_E[y1, x1]))
    return e, (1.0 - tx) * GGX_E_AVG[x0] + tx * GGX_E_AVG[x1]


@inline_kernel
def _channel(fss, missing, e_avg):
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return 1.0 + fms * missing


@kernel
def energy_factor(fss, roughness, mu):
    """(3,) factor Cycles' Multiscatter GGX multiplies the lobe by, for a Fresnel whose
    hemispherical average is fss (rgb), seen from mu = wo.z."""
    e, e_avg = ggx_energy(roughness, mu)
    missing = (1.0 - e) / e if e > 0.0 else 0.0
    return (_channel(fss[0], missing, e_avg), _channel(fss[1], missing, e_avg),
            _channel(fss[2], missing, e_avg))


@kernel
def dielectric_fss(eta):
    """Cycles' fit of the hemispherical average of the dielectric Fresnel (fresnel_dielectric_Fss)."""
    if eta < 1.0:
        return 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    return (eta - 1.0) / (4.08567 + 1.00071 * eta)
