"""The medium stage: what happens to each live path along its segment [0, hit) before the
surface stage shades the hit (run only when the scene has media).

Per path in a medium: the medium's emission, the decoupled next-event vertex (a point on
the segment toward a light point, as Cycles), the path's own free flight and, where it
scatters, the phase sample and Russian roulette. A homogeneous segment toward a triangle
light goes to the SIMD batch (nee_batch) instead: shade_media records it there and
flush_nee_batch writes back the shadow rays and path states of a full batch. Every other
segment (grids, overlapping media, other lights, the last bounce) runs the scalar path
here, drawing the same random numbers (dims.SEG_*).

A path that scatters leaves with its next ray (PATH_SCATTERED); one that reaches the end of
its segment stays PATH_ACTIVE for the surface stage.
"""

import numpy as np

from ..kernels import inline_kernel, kernel
from ..kernels.rng import hashed_uniform
from ..kernels.vecmath import add, madd, max3, mul, scale
from ..lights.environment import connect_light_env
from ..lights.sample import light_has_point, light_pmf, light_point, pick_light
from . import nee_batch
from .aovs import (
    aov_after_medium,
    aov_emission_pass,
    aov_first_scatter,
    aov_medium_segment,
    aov_scattered_emission,
    shadow_pass_column,
)
from .config import (
    CFG_AOVS,
    CFG_EQUIANGULAR,
    CFG_LIGHT_AOVS,
    CFG_MAX_BOUNCES,
    CFG_NEE_BATCH,
    CFG_RR_DEPTH,
    CFG_SAMPLING,
    CFG_UNIFORM_CHANNEL,
    CFG_WALK_SHADOWS,
    SAMPLING_BSDF,
    SAMPLING_NEE,
)
from .dims import MEDIUM_NEE_DIMS, SEG_SHADOW
from .media_api import (
    EMPTY,
    channel_probabilities,
    grid_sample_distance,
    nee_vertex_on,
    phase_eval,
    phase_g,
    sample_phase,
    sample_segment,
    segment,
    segment_emission,
    stack_has_grid,
    stack_is_empty,
    stack_sigma,
)
from .paths import (
    AOV_FEAT_DONE,
    PATH_DEAD,
    PATH_SCATTERED,
    RAY_FAR,
    add_radiance,
    emit_shadow,
    light_sample_weight,
    load3,
    russian_roulette,
    store3,
)


@inline_kernel
def _scatter_in_medium(ps, i, beta, depth, x, wi, pdf):
    """Path i scattered at medium point x (its depth-th event) into wi with phase pdf `pdf`:
    its next ray starts there, with throughput beta."""
    store3(ps.beta, i, beta)
    ps.depth[i] = depth + 1
    ps.mis_pdf[i] = pdf
    store3(ps.mis_o, i, x)
    store3(ps.o, i, x)
    store3(ps.d, i, wi)
    ps.tmax[i] = RAY_FAR
    ps.gap[i] = 0.0


@kernel
def _connect_light(lt, env, light, lp, x, u1, u2):
    """connect_light compiled once for both of _medium_nee's places in shade_media (inlined,
    it compiled twice there); shade_surface inlines its own copy, hot on surfaces. env: the
    environment map's tables, None for a constant world."""
    return connect_light_env(lt, env, light, lp, x, u1, u2)


@inline_kernel
def _medium_nee(ps, i, md, lt, env, cfg, x, d, beta, key, dim, sh, s, light, lp, weight, col):
    """Next-event estimation from medium point x (with path weight `weight` to reach it);
    its shadow ray also adds to light pass column col.
    Uses dimensions dim .. dim + MEDIUM_NEE_DIMS - 1 whether or not it emits a shadow ray
    (so the batched next-event vertex, nee_batch, keeps the same random numbers)."""
    wi, dist, le, pdf, is_delta = _connect_light(lt, env, light, lp, x, hashed_uniform(key, dim),
                                                 hashed_uniform(key, dim + 1))
    stack = ps.stack[i]
    p_light = pdf * light_pmf(lt, light)
    if p_light <= 0.0 or max3(le) <= 0.0:
        return s
    fph, ph = phase_eval(md, stack, x, d, wi)
    w = light_sample_weight(p_light, ph, is_delta, cfg[CFG_SAMPLING])
    c = scale(mul(mul(mul(beta, weight), le), fph), w / p_light)
    if max3(c) <= 0.0:
        return s
    length = dist * 0.9999 if dist < RAY_FAR else RAY_FAR
    emit_shadow(sh, s, x, wi, length, c, ps.pid[i], key, dim + 2, stack, 0.0, col)
    return s + 1


@inline_kernel
def _volume_emission_passes(L, pid, depth, beta, le):
    """A medium's emission along a path's segment: the Emission pass before the path
    scattered, its category's light pass after."""
    if depth == 0:
        aov_emission_pass(L, pid, beta, le, 1.0)
    else:
        aov_scattered_emission(L, pid, depth, beta, le, 1.0)


@kernel
def flush_nee_batch(count, nb, ps, cfg, sh, s, L):
    """Run the batched homogeneous segments 0..count-1 (nee_batch, SIMD across paths): write
    the shadow rays of next-event connections that carry light from index s, and each
    path's new state (and the light passes' category in L). Returns the new s."""
    # Without interfaces a shadow ray stays in its medium, so the batch applies the
    # transmittance too (SIMD) and the ray leaves with an empty stack: shadow_media skips it.
    in_batch = cfg[CFG_WALK_SHADOWS] == 0
    nee_batch.run(count, nb, cfg[CFG_SAMPLING] != SAMPLING_NEE, in_batch, cfg[CFG_UNIFORM_CHANNEL] != 0)
    light_aovs = cfg[CFG_LIGHT_AOVS] != 0
    _, q_key, q_dim, q_path, r = nb
    for j in range(count):
        i = q_path[j]
        pid = ps.pid[i]
        x, wi, length, c = nee_batch.shadow_ray(r, j)
        if max3(c) > 0.0:
            col = shadow_pass_column(L, pid, ps.depth[i], True, light_aovs)
            emit_shadow(sh, s, x, wi, length, c, pid, q_key[j], q_dim[j] + SEG_SHADOW, ps.stack[i], 0.0, col)
            if in_batch:
                sh.stack[s, 0] = EMPTY
            s += 1
        state, dim, beta, y, wo, pdf = nee_batch.path_update(r, j)
        ps.dim[i] = dim
        if state == nee_batch.DEAD:
            ps.alive[i] = PATH_DEAD
            continue
        if state == nee_batch.PASSED:
            store3(ps.beta, i, beta)
            continue
        if light_aovs:
            aov_first_scatter(L, pid, ps.depth[i], True)
        _scatter_in_medium(ps, i, beta, ps.depth[i], y, wo, pdf)
        ps.alive[i] = PATH_SCATTERED
    return s


@kernel
def shade_media(n, batch, hits, scene, env, md, cfg, nb, grid_md):
    """The participating media along each live path's segment [0, hit): emission, the
    next-event vertex, free-flight sampling. A path that scatters gets its next ray here
    (PATH_SCATTERED); one that reaches the segment's end goes on to shade_surface
    (PATH_ACTIVE). Returns the number of shadow rays written (from 0). grid_md: md when the
    scene has grid media, None otherwise (then no grid tracker is compiled). env: the
    environment map's tables, None for a constant world. nb: the SIMD batch's arrays
    (nee_batch.NeeBatch)."""
    ps, sh, L = batch.paths, batch.shadows, batch.L
    prim, lt = hits.prim, scene.lights
    max_bounces = cfg[CFG_MAX_BOUNCES]
    sampling = cfg[CFG_SAMPLING]
    uniform_channel = cfg[CFG_UNIFORM_CHANNEL] != 0
    # int64, not the literal 0: numba compiles a callee once per argument type it meets while
    # typing, so a literal would compile flush_nee_batch (and the SIMD batch) twice over.
    s = np.int64(0)
    cdf = lt.cdf  # what pick_light searches: L + 1 entries
    batched = cfg[CFG_NEE_BATCH] != 0
    aovs = cfg[CFG_AOVS] != 0  # render passes requested (integrator.aovs)
    light_aovs = cfg[CFG_LIGHT_AOVS] != 0  # and the light passes (Emission: depth 0)
    queued = np.int64(0)
    for i in range(n):
        stack = ps.stack[i]
        if stack_is_empty(stack):
            continue
        pid = ps.pid[i]
        key = ps.key[i]
        dim = ps.dim[i]
        d = load3(ps.d, i)
        gap = np.float64(ps.gap[i])
        o = madd(load3(ps.o, i), d, -gap)  # the surface point the ray left, not its offset origin
        beta = load3(ps.beta, i)
        depth = ps.depth[i]
        t_hit = np.float64(ps.tmax[i]) + gap if prim[i] >= 0 else RAY_FAR
        did_nee = False
        homogeneous = not stack_has_grid(md, stack)
        if aovs and L[pid, AOV_FEAT_DONE] == 0.0:  # only while the denoising features are open
            if homogeneous:
                sa, ss = stack_sigma(md, stack)
                aov_medium_segment(L, pid, depth, beta, sa, ss, t_hit)
            else:
                aov_after_medium(L, pid, depth)
        wants_nee = sampling != SAMPLING_BSDF and depth <= max_bounces and cdf.shape[0] > 1
        if wants_nee and homogeneous:
            # Decoupled next-event vertex (as Cycles): a point on the segment chosen by
            # equiangular/free-flight MIS toward a light point, independent of where the
            # path itself goes on.
            light = pick_light(cdf, hashed_uniform(key, dim))
            use_eq = cfg[CFG_EQUIANGULAR] != 0 and light_has_point(lt, light)
            if batched and nee_batch.qualifies(lt, light, stack):
                # The whole segment (this vertex, the free flight, the phase sample and
                # Russian roulette) runs in the SIMD batch; only its emission is added here.
                sa, ss = stack_sigma(md, stack)
                st = add(sa, ss)
                le = segment_emission(md, stack, st, t_hit)
                if max3(le) > 0.0:
                    add_radiance(L, pid, beta, le)
                    if light_aovs:
                        _volume_emission_passes(L, pid, depth, beta, le)
                nee_batch.record(nb, queued, i, key, dim, lt, light, o, d, t_hit, beta, ss, st,
                                 phase_g(md, stack[0]), use_eq, depth + 1 >= cfg[CFG_RR_DEPTH])
                queued += 1
                if queued == nee_batch.CHUNK:
                    s = flush_nee_batch(queued, nb, ps, cfg, sh, s, L)
                    queued = np.int64(0)
                continue
            lp = light_point(lt, light, hashed_uniform(key, dim + 1), hashed_uniform(key, dim + 2))
            dim += 3
            # Shared by the next-event vertex and the path's own free flight.
            seg = segment(md, stack, t_hit)
            tn, wn, dim = nee_vertex_on(seg, o, d, t_hit, lp, beta, key, dim, use_eq, uniform_channel)
            if max3(wn) > 0.0:
                col = shadow_pass_column(L, pid, depth, True, light_aovs)
                s = _medium_nee(ps, i, md, lt, env, cfg, madd(o, d, tn), d, beta, key, dim, sh, s, light, lp,
                                wn, col)
            dim += MEDIUM_NEE_DIMS
            did_nee = True
        if homogeneous:
            if not did_nee:
                seg = segment(md, stack, t_hit)
            p = channel_probabilities(beta, uniform_channel)
            t, scattered, w, le, dim = sample_segment(md, stack, seg, t_hit, p, key, dim)
        else:
            t, scattered, w, le, dim = grid_sample_distance(grid_md, stack, o, d, t_hit, beta, key, dim,
                                                            uniform_channel)
        if max3(le) > 0.0:
            add_radiance(L, pid, beta, le)
            if light_aovs:
                _volume_emission_passes(L, pid, depth, beta, le)
        beta = mul(beta, w)
        ps.dim[i] = dim
        if max3(beta) <= 0.0 or (scattered and depth > max_bounces):
            ps.alive[i] = PATH_DEAD
            continue
        if not scattered:
            store3(ps.beta, i, beta)
            continue
        x = madd(o, d, t)
        if not did_nee and sampling != SAMPLING_BSDF and cdf.shape[0] > 1:
            light = pick_light(cdf, hashed_uniform(key, dim))
            lp = light_point(lt, light, hashed_uniform(key, dim + 1), hashed_uniform(key, dim + 2))
            dim += 3
            col = shadow_pass_column(L, pid, depth, True, light_aovs)
            s = _medium_nee(ps, i, md, lt, env, cfg, x, d, beta, key, dim, sh, s, light, lp, (1.0, 1.0, 1.0),
                            col)
            dim += MEDIUM_NEE_DIMS
        wi, pw, ph_pdf = sample_phase(md, stack, x, d, hashed_uniform(key, dim), hashed_uniform(key, dim + 1),
                                      hashed_uniform(key, dim + 2))
        dim += 3
        if light_aovs:
            aov_first_scatter(L, pid, depth, True)
        _scatter_in_medium(ps, i, mul(beta, pw), depth, x, wi, ph_pdf)
        alive, dim = russian_roulette(ps, i, key, dim, cfg[CFG_RR_DEPTH])
        ps.alive[i] = PATH_SCATTERED if alive else PATH_DEAD
        ps.dim[i] = dim
    if queued > 0:
        s = flush_nee_batch(queued, nb, ps, cfg, sh, s, L)
    return s
