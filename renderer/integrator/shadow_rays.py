"""Shadow rays: the connections to lights that the medium and surface stages wrote, traced
to their lights.

Two ways, chosen per scene by the driver. When no interface can lie on a shadow ray (no
mesh without lobes, no transparent lobe), its medium stack is constant along it:
shadow_media multiplies in the stack's transmittance over the whole length, one occlusion
test per ray decides, and resolve_shadows adds what arrived. Otherwise walk_shadows steps
each ray from surface to surface (one closest-hit call per step), updating its stack at
interfaces and tinting it by transparent lobes, until it reaches its light or is stopped.
"""

import numpy as np

from ..bsdfs import SIDE_BACK, SIDE_FRONT, TRANSPARENT
from ..bsdfs.layout import L_COLOR, L_KIND, L_SIDES, L_WEIGHT, M_COUNT, M_FIRST
from ..bsdfs.material import bsdf_has_lobes
from ..kernels import inline_kernel, kernel
from ..kernels.vecmath import dot, madd, max3, mul, sub
from .config import CFG_DELTA_TR, CFG_HAS_MEDIA
from .media_api import homogeneous_transmittance, stack_is_empty, stack_push, stack_remove, transmittance
from .paths import load3, offset_origin, store3


@kernel
def shadow_media(count, sh, md, cfg, grid_md):
    """Multiply each shadow ray's contribution by the transmittance of its medium stack
    over its whole length (used when no interface can lie on a shadow ray, so the stack is
    constant along it; otherwise walk_shadows accumulates it piece by piece). grid_md: md
    when the scene has grid media, None otherwise (then no grid tracker is compiled)."""
    use_delta = cfg[CFG_DELTA_TR] != 0
    for s in range(count):
        stack = sh.stack[s]
        if stack_is_empty(stack):
            continue
        gap = np.float64(sh.gap[s])
        if grid_md is None:
            tr = homogeneous_transmittance(md, stack, -gap, np.float64(sh.tmax[s]))
        else:
            tr, dim = transmittance(grid_md, stack, load3(sh.o, s), load3(sh.d, s), -gap,
                                    np.float64(sh.tmax[s]), sh.key[s], sh.dim[s], use_delta)
            sh.dim[s] = dim
        store3(sh.contrib, s, mul(load3(sh.contrib, s), tr))


@inline_kernel
def _arrive(sh, s, c, L):
    """Shadow ray s reached its light with contribution c: add it to its path's radiance,
    and to its light pass too when it carries one (sh.col)."""
    pid = sh.pid[s]
    col = sh.col[s]
    for k in range(3):
        L[pid, k] += c[k]
        if col >= 0:
            L[pid, col + k] += c[k]


@kernel
def resolve_shadows(count, sh, occluded, L):
    """Add the contributions of shadow rays that reached their light."""
    for s in range(count):
        if not occluded[s]:
            _arrive(sh, s, load3(sh.contrib, s), L)


@kernel
def walk_shadows(count, batch, hits, remaining, scene, materials, md, cfg, grid_md):
    """One step of the batch's shadow rays that may pass interfaces. hits.t is the hit
    distance where hits.prim >= 0; remaining is each ray's length left to its light. A ray
    that reaches its end adds its contribution; one that hits an opaque surface dies; one
    that hits an interface or a transparent lobe continues past it with its medium stack
    updated. grid_md: as for shadow_media. materials.override[s] >= 0 (scenes with shader
    programs, program_stage.shadow_programs; empty otherwise): the row of materials.table
    to read ray s's hit material from."""
    sh, L = batch.shadows, batch.L
    prim, thit = hits.prim, hits.t
    geo, mt, override = scene.geometry, materials.table, materials.override
    has_media = cfg[CFG_HAS_MEDIA] != 0
    for s in range(count):
        o = load3(sh.o, s)
        d = load3(sh.d, s)
        p = prim[s]
        t_end = float(thit[s]) if p >= 0 else float(remaining[s])
        stack = sh.stack[s]
        c = load3(sh.contrib, s)
        if has_media and not stack_is_empty(stack):
            if grid_md is None:
                tr = homogeneous_transmittance(md, stack, -np.float64(sh.gap[s]), t_end)
            else:
                tr, dim = transmittance(grid_md, stack, o, d, -np.float64(sh.gap[s]), t_end, sh.key[s],
                                        sh.dim[s], cfg[CFG_DELTA_TR] != 0)
                sh.dim[s] = dim
            c = mul(c, tr)
        if max3(c) <= 0.0:
            sh.alive[s] = 0
            continue
        if p < 0:
            _arrive(sh, s, c, L)
            sh.alive[s] = 0
            continue
        ng = load3(geo.ng, p)
        front = dot(d, ng) < 0.0
        m = geo.material[p]
        if s < override.shape[0] and override[s] >= 0:
            m = override[s]
        # A pure emitter (no lobes) is opaque; anything else lets through its transparent part.
        opaque_emitter = geo.light[p] >= 0 and not bsdf_has_lobes(mt, m, front)
        tint = (0.0, 0.0, 0.0) if opaque_emitter else _transparency(mt, m, front)
        if max3(tint) <= 0.0:
            sh.alive[s] = 0
            continue
        med = geo.medium[p]
        if med >= 0:
            if front:
                stack_push(stack, med)
            else:
                stack_remove(stack, med)
        x = madd(o, d, t_end)
        xo = offset_origin(x, ng, d)
        remaining[s] = max(0.0, remaining[s] - dot(sub(xo, o), d))
        sh.gap[s] = max(0.0, dot(sub(xo, x), d))
        store3(sh.o, s, xo)
        store3(sh.contrib, s, mul(c, tint))
        sh.alive[s] = 1


@inline_kernel
def _transparency(mt, m, front):
    """How much light passes straight through material m from this side: 1 for a surface
    with no lobes (an interface), the transparent lobes' weight*color otherwise."""
    if not bsdf_has_lobes(mt, m, front):
        return (1.0, 1.0, 1.0)
    mats, lobes = mt
    side = SIDE_FRONT if front else SIDE_BACK
    r, g, b = 0.0, 0.0, 0.0
    start = mats[m, M_FIRST]
    for j in range(start, start + mats[m, M_COUNT]):
        if (int(lobes[j, L_SIDES]) & side) != 0 and int(lobes[j, L_KIND]) == TRANSPARENT:
            r += lobes[j, L_WEIGHT] * lobes[j, L_COLOR]
            g += lobes[j, L_WEIGHT + 1] * lobes[j, L_COLOR + 1]
            b += lobes[j, L_WEIGHT + 2] * lobes[j, L_COLOR + 2]
    return (min(r, 1.0), min(g, 1.0), min(b, 1.0))
