"""The surface stage: shade the closest hit of every path still PATH_ACTIVE after the
medium stage.

Per path: emission found by the ray (environment and sun discs for an escaped ray, an
emitting triangle otherwise, MIS-weighted against light sampling), then at a surface with
lobes next-event estimation, BSDF sampling and Russian roulette; a surface without lobes is
an interface the path crosses without scattering. Crossing a surface's geometric side
enters or leaves its medium (the path's medium stack).

The stage holds no medium code, so a scene without media runs only this kernel per bounce:
a single kernel holding both stages measured 36% slower on the surface Cornell box.
"""

import math

from ..bsdfs.closure_normals import specular_normal
from ..bsdfs.material import (
    EVENT_ABSORB,
    EVENT_PASS_THROUGH,
    EVENT_SCATTER,
    bsdf_eval,
    bsdf_eval_bumped,
    bsdf_has_lobes,
    bsdf_sample,
    bsdf_sample_bumped,
)
from ..kernels import inline_kernel, kernel
from ..kernels.rng import uniform
from ..kernels.vecmath import add, dot, madd, max3, mul, neg, normalize, onb, scale, sub, to_local, to_world
from ..lights.environment import connect_light_env, escaped_radiance_env
from ..lights.sample import (
    light_pmf,
    light_point,
    pick_light,
    triangle_emission,
    triangle_light_pdf,
)
from .aovs import (
    aov_after_medium,
    aov_background,
    aov_colors,
    aov_emission,
    aov_emission_pass,
    aov_past_limit,
    aov_scattered_emission,
    aov_surface,
    shadow_pass_column,
)
from .config import (
    CFG_AOVS,
    CFG_FILM_TRANSPARENT,
    CFG_LIGHT_AOVS,
    CFG_MAX_BOUNCES,
    CFG_RR_DEPTH,
    CFG_SAMPLING,
    SAMPLING_BSDF,
    SAMPLING_NEE,
)
from .dims import BSDF_DIMS, NEE_DIMS, SHADOW_DIMS
from .media_api import stack_push, stack_remove
from .paths import (
    ALPHA,
    AOV_DATA_DONE,
    AOV_FEAT_DONE,
    PATH_ACTIVE,
    PATH_DEAD,
    RAY_FAR,
    add_weighted_radiance,
    emit_shadow,
    hit_weight,
    light_sample_weight,
    load3,
    offset_origin,
    russian_roulette,
    store3,
)

MAX_CROSSINGS = 256  # interfaces a path may pass before it is ended (guards open meshes)
_NO_BUMP = ((0.0, 0.0, 1.0), (0.0, 0.0, 1.0))  # `bump` of an unbumped surface (unused there)


@kernel
def shade_surface(n, batch, hits, scene, materials, env, cfg, s):
    """Shade the closest hits of paths 0..n-1 that are PATH_ACTIVE (hits.prim -1 = escaped;
    ps.tmax holds the hit distance): emission, next-event estimation, BSDF sampling, Russian
    roulette. Writes new rays into the batch's paths, kills finished paths, appends shadow
    rays to its shadows from index s. env: the environment map's tables, None for a
    constant world. The scene's camera and mist serve the Mist pass. materials.override[i]
    >= 0 (program_stage, only in scenes with shader programs; empty otherwise) is the row of
    materials.table to shade path i with instead of its triangle's material;
    materials.out[i, 0:3] scales the radiance of the emitter it hit and out[i, 3:6], when
    not zero, is its shading normal (then the surface is bumped: its lobes have their own
    normals, renderer.bsdfs.closure_normals). Returns the number of shadow rays written in
    all."""
    ps, sh, L = batch.paths, batch.shadows, batch.L
    prim, bu, bv = hits.prim, hits.bu, hits.bv
    geo, lt, cam, mist = scene.geometry, scene.lights, scene.camera, scene.mist
    mt, override, program_out = materials.table, materials.override, materials.out
    max_bounces = cfg[CFG_MAX_BOUNCES]
    sampling = cfg[CFG_SAMPLING]
    transparent = cfg[CFG_FILM_TRANSPARENT] != 0
    aovs = cfg[CFG_AOVS] != 0  # render passes requested (integrator.aovs); else no pass work at all
    light_aovs = cfg[CFG_LIGHT_AOVS] != 0  # and the light and colour passes
    cdf = lt.cdf  # what pick_light searches: L + 1 entries
    for i in range(n):
        if ps.alive[i] != PATH_ACTIVE:
            continue
        pid = ps.pid[i]
        key = ps.key[i]
        dim = ps.dim[i]
        d = load3(ps.d, i)
        beta = load3(ps.beta, i)
        depth = ps.depth[i]
        p = prim[i]
        stack = ps.stack[i]
        # Pass work only while the path still has a pass to write (its first hits).
        aov_open = aovs and (L[pid, AOV_FEAT_DONE] == 0.0 or (depth == 0 and L[pid, AOV_DATA_DONE] == 0.0))
        if aov_open:
            aov_after_medium(L, pid, depth)

        # --- escaped: environment and sun discs ------------------------------------------
        if p < 0:
            env_row = lt.env_light
            if depth == 0 and transparent:
                # Cycles' transparent background: a camera ray that reaches the world having
                # only passed through (interfaces, transparent lobes, media unscattered)
                # leaves the world out and counts its mean throughput as transparency
                # (alpha = 1 - transparency); sun discs stay visible, as Cycles' distant lights.
                L[pid, ALPHA] += (beta[0] + beta[1] + beta[2]) / 3.0
                env_row = -1
            le, pdf_light = escaped_radiance_env(lt, env_row, lt.sun_rows, env, d)
            if max3(le) > 0.0:
                w = hit_weight(ps.mis_pdf[i], pdf_light, sampling)
                add_weighted_radiance(L, pid, beta, le, w)
                if aov_open:
                    aov_emission(L, pid, beta, le, w)
                if light_aovs and depth > 0:
                    aov_scattered_emission(L, pid, depth, beta, le, w)
            if aov_open:
                aov_background(L, pid)
            ps.alive[i] = PATH_DEAD
            continue

        # --- surface hit ---------------------------------------------------------------
        b1 = float(bu[i])
        b2 = float(bv[i])
        b0 = 1.0 - b1 - b2
        v0 = load3(geo.v0, p)
        x = madd(madd(v0, load3(geo.e1, p), b1), load3(geo.e2, p), b2)
        ng = load3(geo.ng, p)
        front = dot(d, ng) < 0.0
        m = geo.material[p]
        programmed = i < override.shape[0] and override[i] >= 0
        if programmed:
            m = override[i]

        light = geo.light[p]
        if light >= 0:
            le = triangle_emission(lt, light, front)
            if programmed:
                le = mul(le, load3(program_out, i))
            if max3(le) > 0.0:
                w = 1.0
                if ps.mis_pdf[i] > 0.0 or sampling == SAMPLING_NEE:
                    pdf_light = triangle_light_pdf(lt, light, load3(ps.mis_o, i), x, dot(d, ng))
                    w = hit_weight(ps.mis_pdf[i], pdf_light, sampling)
                add_weighted_radiance(L, pid, beta, le, w)
                if aov_open:
                    aov_emission(L, pid, beta, le, w)
                if light_aovs:
                    if depth == 0:
                        aov_emission_pass(L, pid, beta, le, w)
                    else:
                        aov_scattered_emission(L, pid, depth, beta, le, w)

        if not bsdf_has_lobes(mt, m, front):
            if light >= 0:
                # A pure emitter (Cycles' Emission shader): black, opaque.
                if aov_open:
                    sn = _shading_normal(geo, p, b0, b1, b2, ng)
                    facing = sn if front else neg(sn)
                    aov_surface(L, pid, mt, m, front, x, facing, abs(dot(d, sn)), depth, beta, cam, mist)
                ps.alive[i] = PATH_DEAD
                continue
            # An invisible interface: cross it without scattering.
            _cross_interface(ps, i, geo, p, front, x, ng, d, beta)
            ps.dim[i] = dim
            continue
        sn = _shading_normal(geo, p, b0, b1, b2, ng)
        sn_mesh = sn
        n_map = sn
        bumped = programmed and (program_out[i, 3] != 0.0 or program_out[i, 4] != 0.0 or
                                 program_out[i, 5] != 0.0)
        if bumped:  # a program's normal (Normal Map, Bump into a BSDF's Normal)
            n_map = normalize((float(program_out[i, 3]), float(program_out[i, 4]), float(program_out[i, 5])))
            sn = specular_normal(n_map, ng, d, front)  # the frame: the specular lobes' normal
        if aov_open:
            if depth > max_bounces:
                aov_past_limit(L, pid)
            else:
                aov_surface(L, pid, mt, m, front, x, sn if front else neg(sn), abs(dot(d, sn)), depth, beta,
                            cam, mist)
        if light_aovs and depth == 0:
            aov_colors(L, pid, mt, m, front, abs(dot(d, sn)), beta)
        if depth > max_bounces:
            ps.alive[i] = PATH_DEAD
            continue

        ts, tt = onb(sn)
        wo = to_local(neg(d), ts, tt, sn)
        bump = _NO_BUMP
        if bumped:
            bump = (to_local(n_map, ts, tt, sn), to_local(sn_mesh, ts, tt, sn))

        # Dimensions: the light sample's, then the BSDF sample's, then a shadow ray's block
        # when one is traced, so that the first bounce's light and lobe choices both fall
        # in the stratified dimensions (kernels.rng.STRATIFIED_DIMS).
        nee = sampling != SAMPLING_BSDF and cdf.shape[0] > 1
        bsdf_dim = dim + NEE_DIMS if nee else dim
        next_dim = bsdf_dim + BSDF_DIMS
        if nee:
            col = shadow_pass_column(L, pid, depth, False, light_aovs)
            s, traced = _surface_nee(lt, env, mt, m, front, x, ng, wo, ts, tt, sn, beta, sampling, pid, key,
                                     dim, next_dim, stack, sh, s, col, bump, bumped)
            if traced:
                next_dim += SHADOW_DIMS

        # BSDF sampling
        u_sel, u1, u2, u3 = (uniform(key, bsdf_dim), uniform(key, bsdf_dim + 1), uniform(key, bsdf_dim + 2),
                             uniform(key, bsdf_dim + 3))
        if bumped:
            wil, w, pdf, event = bsdf_sample_bumped(mt, m, front, bump, wo, u_sel, u1, u2, u3)
        else:
            wil, w, pdf, event = bsdf_sample(mt, m, front, wo, u_sel, u1, u2, u3)
        dim = next_dim
        if event == EVENT_ABSORB or max3(w) <= 0.0:
            ps.alive[i] = PATH_DEAD
            continue
        beta = mul(beta, w)
        if event == EVENT_PASS_THROUGH:
            _cross_interface(ps, i, geo, p, front, x, ng, d, beta)
            ps.dim[i] = dim
            continue
        wi = normalize(to_world(wil, ts, tt, sn))
        # Crossing to the other side of the geometric surface enters or leaves its medium.
        if (dot(wi, ng) > 0.0) != front:
            _update_stack(ps, i, geo, p, front)
        store3(ps.beta, i, beta)
        ps.depth[i] = depth + 1
        # A delta lobe has no pdf to weigh emission it finds against light sampling.
        ps.mis_pdf[i] = pdf if event == EVENT_SCATTER else 0.0
        store3(ps.mis_o, i, x)
        _spawn(ps, i, x, ng, wi)
        alive, dim = russian_roulette(ps, i, key, dim, cfg[CFG_RR_DEPTH])
        ps.alive[i] = PATH_ACTIVE if alive else PATH_DEAD
        ps.dim[i] = dim
    return s


@inline_kernel
def _surface_nee(lt, env, mt, m, front, x, ng, wo, ts, tt, sn, beta, sampling, pid, key, dim, shadow_dim,
                 stack, sh, s, col, bump, bumped):
    """Next-event estimation at surface point x: pick a light and a point on it (dimensions
    dim .. dim + NEE_DIMS - 1), weigh the connection by the BSDF and MIS, and write its
    shadow ray at index s when it carries light (its tracking from shadow_dim on; and to
    light pass column col). Returns (next shadow index, whether a shadow ray was written).
    bumped: a program set the normal, and the lobes see their own normals (bump, in the
    frame (ts, tt, sn); renderer.bsdfs.closure_normals)."""
    cdf = lt.cdf  # what pick_light searches: L + 1 entries
    light = pick_light(cdf, uniform(key, dim))
    lp = light_point(lt, light, uniform(key, dim + 1), uniform(key, dim + 2))
    wi, dist, le, pdf, is_delta = connect_light_env(lt, env, light, lp, x, uniform(key, dim + 3),
                                                    uniform(key, dim + 4))
    p_light = pdf * light_pmf(lt, light)
    if p_light > 0.0 and max3(le) > 0.0:
        wil = to_local(wi, ts, tt, sn)
        if bumped:  # f holds each lobe's own cosine (and bump factor)
            f, pdf_bsdf = bsdf_eval_bumped(mt, m, front, bump, wo, wil)
            cos = 1.0
        else:
            f, pdf_bsdf = bsdf_eval(mt, m, front, wo, wil)
            cos = abs(wil[2])
        w = light_sample_weight(p_light, pdf_bsdf, is_delta, sampling)
        c = scale(mul(mul(beta, f), le), cos * w / p_light)
        if max3(c) > 0.0:
            xo = offset_origin(x, ng, wi)
            ws = wi
            if dist < RAY_FAR:
                # Aim from the offset origin itself at the light point x + wi dist: with wi
                # from x, the ray meets the light's plane up to ~2e-4 short of the point and
                # the light occludes itself (measured: 97% of such shadow rays were lost).
                # (Not lp: triangles are sampled by solid angle, lp serves only the area
                # fallback.)
                to = sub(madd(x, wi, dist), xo)
                dist = math.sqrt(dot(to, to))
                ws = scale(to, 1.0 / dist)
                dist *= 0.9999
            gap = max(0.0, dot(sub(xo, x), ws))
            emit_shadow(sh, s, xo, ws, dist, c, pid, key, shadow_dim, stack, gap, col)
            return s + 1, True
    return s, False


@inline_kernel
def _shading_normal(geo, p, b0, b1, b2, ng):
    sn0 = load3(geo.sn[p], 0)
    sn1 = load3(geo.sn[p], 1)
    sn2 = load3(geo.sn[p], 2)
    n = normalize(add(add(scale(sn0, b0), scale(sn1, b1)), scale(sn2, b2)))
    # Shading normals live on the front side of the geometric normal.
    if dot(n, ng) < 0.0:
        n = neg(n)
    return n


@inline_kernel
def _spawn(ps, i, x, ng, direction):
    """Next ray of path i from surface point x: origin pushed off the surface, the push
    remembered as the gap media integrate over."""
    o = offset_origin(x, ng, direction)
    store3(ps.o, i, o)
    store3(ps.d, i, direction)
    ps.tmax[i] = RAY_FAR
    ps.gap[i] = max(0.0, dot(sub(o, x), direction))


@inline_kernel
def _update_stack(ps, i, geo, p, front):
    med = geo.medium[p]
    if med >= 0:
        _enter_or_leave(ps.stack[i], med, front)


@kernel
def _enter_or_leave(stack, med, front):
    """Push medium med onto the stack (entering through the front) or remove it (leaving):
    a call, not inlined, since shade_surface reaches it at three places and only at the
    surfaces of medium meshes."""
    if front:
        stack_push(stack, med)
    else:
        stack_remove(stack, med)


@inline_kernel
def _cross_interface(ps, i, geo, p, front, x, ng, d, beta):
    """Continue straight through the surface at x, entering or leaving its medium."""
    _update_stack(ps, i, geo, p, front)
    ps.crossings[i] += 1
    if ps.crossings[i] > MAX_CROSSINGS:
        ps.alive[i] = PATH_DEAD
        return
    store3(ps.beta, i, beta)
    _spawn(ps, i, x, ng, d)
    ps.alive[i] = PATH_ACTIVE
