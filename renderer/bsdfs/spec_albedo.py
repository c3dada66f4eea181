"""Cycles' albedo estimate of a GGX dielectric specular layer, tabulated offline.

Cycles' Principled BSDF puts a GGX specular layer over its diffuse base and gives the base
the weight 1 - E(wo), where E is the layer's *estimated* albedo for the view direction
alone (svm/closure.h: `closure_layering_weight(bsdf_albedo(...))`; closure/
bsdf_microfacet.h: `bsdf_microfacet_estimate_albedo`). The estimate is

    E(mu) = F0 + (1 - F0) s(roughness, mu, eta),   F0 = ((eta - 1) / (eta + 1))^2

with s the mean, over microfacet normals h drawn from the visible-normal distribution of
wo (mu = wo.z), of the Fresnel curve remapped to [0, 1], (F(wo.h, eta) - F0) / (1 - F0),
counting 0 for normals whose mirror direction falls below the horizon. Shadowing is not
weighed in (the estimate is the albedo of an energy-conserving layer), so the exact E is at
least the single-scattering albedo of the layer; but the table is coarse in mu, and near grazing
(mu < 0.15) at low roughness its linear interpolation falls below the single-scattering
albedo by up to 0.03 (renderer.bsdfs.plastic guards its energy against that).

s is tabulated exactly as Cycles defines its `ggx_gen_schlick_ior_s` table: 16 x 16 x 16
nodes uniform in roughness, mu and z = sqrt((eta - 1) / (eta + 1)) (node values computed at
roughness and mu clamped to >= 1e-4 and z clamped to [1e-4, 0.99]), read with Cycles'
trilinear interpolation (`lookup_table_read_3D`). The node values here come from our own
deterministic quadrature of that definition (Cycles' are a 2^20-sample Monte Carlo
estimate); compared with the table compiled into the bpy 5.0.1 wheel (found in its binary),
every node agrees within 1.6e-4, mean 5e-6.

The table is stored next to this file; regenerate with `python -m renderer.bsdfs.spec_albedo`
(then touch this file: numba's cache keys on the source, and the table is frozen into the
compiled kernels).
"""

import math

import numpy as np

from renderer.bsdfs import baked
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.microfacet import ggx_sample_visible_normal, reflect
from renderer.kernels import inline_kernel, kernel

N_NODES = 16  # per axis: roughness, mu, z
_N_QUAD = 512  # midpoint visible-normal quadrature, _N_QUAD^2 points per node
_TABLE_PATH = baked.table_path(__file__, "spec_albedo")


@kernel
def f0_from_eta(eta):
    r = (eta - 1.0) / (eta + 1.0)
    return r * r


@kernel
def node_params(x, y, z):
    """(roughness, mu, eta) at node (x, y, z), clamped as Cycles clamps them."""
    n1 = N_NODES - 1.0
    rough = min(max(x / n1, 1e-4), 1.0)
    mu = min(max(y / n1, 1e-4), 1.0)
    zz = min(max(z / n1, 1e-4), 0.99)
    root_f0 = zz * zz  # z^4 = F0
    if root_f0 < 6e-8:
        # Cycles computes the index in single precision, where z = 1e-4 gives exactly 1
        # (no reflection at all: s = 0 on the whole first slice).
        return rough, mu, 1.0
    return rough, mu, (1.0 + root_f0) / (1.0 - root_f0)


@kernel
def remapped_fresnel_mean(rough, mu, eta, n):
    """s: mean of (F(wo.h) - F0) / (1 - F0), clamped to [0, 1], over visible normals h of
    wo (mu = wo.z), 0 where reflect(wo, h) is below the horizon; n x n midpoint quadrature."""
    alpha = rough * rough
    wo = (math.sqrt(max(0.0, 1.0 - mu * mu)), 0.0, mu)
    f0 = f0_from_eta(eta)
    acc = 0.0
    for a in range(n):
        for b in range(n):
            h = ggx_sample_visible_normal(alpha, wo, (a + 0.5) / n, (b + 0.5) / n)
            wi = reflect(wo, h)
            if wi[2] <= 0.0:
                continue
            cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
            F = fresnel_dielectric(cos_oh, eta)[0]
            acc += min(max((F - f0) / (1.0 - f0), 0.0), 1.0)
    return min(max(acc / (n * n), 0.0), 1.0)


@kernel
def build_table(s, n_quad):
    """Fill s (N_NODES^3) with the node values, indexed [z, mu, roughness] like Cycles' table."""
    for k in range(N_NODES):
        for j in range(N_NODES):
            for i in range(N_NODES):
                rough, mu, eta = node_params(i, j, k)
                s[k, j, i] = remapped_fresnel_mean(rough, mu, eta, n_quad)


if __name__ == "__main__":
    _s = np.zeros((N_NODES, N_NODES, N_NODES))
    build_table(_s, _N_QUAD)
    baked.save(_TABLE_PATH, s=_s)
else:
    # A global array is frozen into the kernels below as a constant when they compile.
    (SPEC_S,) = baked.load(_TABLE_PATH, {"s": (N_NODES, N_NODES, N_NODES)})


@inline_kernel
def _cell(x):
    """Cycles' lookup_table_read coordinates: lower node, upper node, weight of the upper."""
    x = min(max(x, 0.0), 1.0) * (N_NODES - 1)
    i = min(int(x), N_NODES - 1)
    return i, min(i + 1, N_NODES - 1), x - i


@kernel
def remapped_fresnel_lookup(roughness, mu, eta):
    """s(roughness, mu, eta) read from the table with Cycles' trilinear interpolation."""
    x0, x1, tx = _cell(roughness)
    y0, y1, ty = _cell(mu)
    z0, z1, tz = _cell(math.sqrt(abs((eta - 1.0) / (eta + 1.0))))
    s0 = ((1.0 - ty) * ((1.0 - tx) * SPEC_S[z0, y0, x0] + tx * SPEC_S[z0, y0, x1])
          + ty * ((1.0 - tx) * SPEC_S[z0, y1, x0] + tx * SPEC_S[z0, y1, x1]))
    s1 = ((1.0 - ty) * ((1.0 - tx) * SPEC_S[z1, y0, x0] + tx * SPEC_S[z1, y0, x1])
          + ty * ((1.0 - tx) * SPEC_S[z1, y1, x0] + tx * SPEC_S[z1, y1, x1]))
    return (1.0 - tz) * s0 + tz * s1


@kernel
def spec_albedo(mu, roughness, eta):
    """Cycles' estimated albedo E(mu) of the specular layer (eta >= 1, roughness in [0, 1])."""
    f0 = f0_from_eta(eta)
    return f0 + (1.0 - f0) * remapped_fresnel_lookup(roughness, mu, eta)
