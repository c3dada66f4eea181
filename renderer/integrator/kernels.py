"""The wavefront volumetric path tracer's kernels: everything between two Embree calls.

Per bounce the Python driver (renderer.integrator.wavefront) makes one closest-hit call for
the live paths and one occlusion call (or an interface walk) for their shadow rays; these
kernels do the rest, per path, as scalar code:

  start_paths     camera rays and initial medium stacks
  shade_media     media along the segment: emission, next-event vertex, free flight,
                  phase sampling (run only when the scene has media)
  shade_surface   emission, next-event estimation, BSDF sampling, Russian roulette; no
                  medium code, so a scene without media pays nothing for media (a single
                  kernel holding both measured 36% slower on the surface Cornell box)
  shadow_media    transmittance of shadow rays through their media
  resolve_shadows add unoccluded shadow contributions
  walk_shadows    one step of shadow rays through interfaces and media
  compact_*       move live rows to the front
  splat           add finished paths to the film

Conventions: `max_bounces` counts scattering events exactly like Cycles: the vertex a path
is shading has index `depth` (the number of earlier scattering events); next-event
estimation and emission found by BSDF sampling at that vertex belong to paths of `depth`
bounces, so a vertex is shaded only while depth <= max_bounces. Passing through an
interface (a surface with no lobes, or a transparent lobe) is not a bounce.

cfg (int64 array): see CFG_* indices.
"""

import math

import numpy as np

from ..bsdfs import TRANSPARENT
from ..bsdfs.material import L_COLOR, L_KIND, L_SIDES, L_WEIGHT, bsdf_eval, bsdf_has_lobes, bsdf_sample
from ..camera import camera_ray
from ..kernels import inline_kernel, kernel
from ..kernels.rng import path_key, uniform
from ..kernels.vecmath import add, dot, madd, max3, mul, neg, normalize, onb, scale, sub, to_local, to_world
from ..lights.sample import (
    connect_light,
    escaped_radiance,
    light_has_point,
    light_point,
    pick_light,
    triangle_light_pdf,
)
from . import nee_batch
from .dims import MEDIUM_NEE_DIMS, SEG_SHADOW, SHADOW_DIMS
from .media_api import (
    EMPTY,
    channel_probabilities,
    nee_vertex_on,
    phase_eval,
    phase_g,
    sample_distance,
    sample_phase,
    sample_segment,
    segment,
    segment_emission,
    stack_has_grid,
    stack_is_empty,
    stack_push,
    stack_remove,
    stack_sigma,
    transmittance,
)

CFG_MAX_BOUNCES = 0
CFG_RR_DEPTH = 1
CFG_SAMPLING = 2  # 0 mis, 1 nee only, 2 bsdf only
CFG_DELTA_TR = 3  # shadow transmittance by delta tracking (else ratio)
CFG_UNIFORM_CHANNEL = 4  # distance sampling picks channels uniformly (else by throughput)
CFG_EQUIANGULAR = 5
CFG_HAS_MEDIA = 6
CFG_WALK_SHADOWS = 7
CFG_NEE_BATCH = 8  # homogeneous next-event vertices in SIMD batches (nee_batch); 0 = scalar
CFG_SIZE = 9

SAMPLING_MIS, SAMPLING_NEE, SAMPLING_BSDF = 0, 1, 2
MAX_CROSSINGS = 256  # interfaces a path may pass before it is ended (guards open meshes)
RAY_FAR = 1e30


@inline_kernel
def offset_origin(x, ng, direction):
    """Move x off its surface to the side `direction` leaves on (Embree has no tnear)."""
    eps = 1e-4 * (1.0 + max(abs(x[0]), max(abs(x[1]), abs(x[2]))))
    if dot(direction, ng) < 0.0:
        eps = -eps
    return madd(x, ng, eps)


@inline_kernel
def power_heuristic(a, b):
    a2 = a * a
    b2 = b * b
    if a2 + b2 <= 0.0:
        return 0.0
    return a2 / (a2 + b2)


@inline_kernel
def _vec(a, i):
    """Row i of an (n, 3) array as a float64 3-tuple (float() would keep float32 in numba)."""
    return (np.float64(a[i, 0]), np.float64(a[i, 1]), np.float64(a[i, 2]))


@inline_kernel
def _put(a, i, v):
    a[i, 0] = v[0]
    a[i, 1] = v[1]
    a[i, 2] = v[2]


@kernel
def start_paths(ps, pixel_of_pid, cam, width, height, seed, first, n, sample_base, init_stack):
    """Camera rays for linear sample indices first .. first + n - 1 of a pass: index k is
    pixel k % (width * height), sample sample_base + k // (width * height)."""
    to_world_m, tan_half, shift, clip = cam
    npix = width * height
    for i in range(n):
        k = first + i
        pixel = k % npix
        sample = sample_base + k // npix
        key = path_key(seed, pixel, sample)
        o, d = camera_ray(to_world_m, tan_half, shift, pixel % width, pixel // width, width, height,
                          uniform(key, 0), uniform(key, 1))
        _put(ps.o, i, madd(o, d, clip[0]))
        _put(ps.d, i, d)
        ps.tmax[i] = clip[1] - clip[0]
        ps.gap[i] = 0.0
        _put(ps.beta, i, (1.0, 1.0, 1.0))
        ps.pid[i] = i
        ps.key[i] = key
        ps.dim[i] = 2
        ps.depth[i] = 0
        ps.crossings[i] = 0
        ps.mis_pdf[i] = 0.0
        _put(ps.mis_o, i, o)
        for j in range(init_stack.shape[0]):
            ps.stack[i, j] = init_stack[j]
        ps.alive[i] = 1
        pixel_of_pid[i] = pixel


@inline_kernel
def _emit_shadow(sh, s, x, wi, dist, contrib, pid, key, dim, stack, gap):
    _put(sh.o, s, x)
    _put(sh.d, s, wi)
    sh.tmax[s] = dist
    sh.gap[s] = gap
    _put(sh.contrib, s, contrib)
    sh.pid[s] = pid
    sh.key[s] = key
    sh.dim[s] = dim
    for j in range(stack.shape[0]):
        sh.stack[s, j] = stack[j]
    sh.alive[s] = 1


@inline_kernel
def _light_sample_weight(lt, light, pdf_light, pdf_scatter, is_delta, sampling):
    """MIS weight of a light sample; pdf_light already includes the selection probability."""
    if is_delta or sampling == SAMPLING_NEE:
        return 1.0
    return power_heuristic(pdf_light, pdf_scatter)


@inline_kernel
def _hit_weight(mis_pdf, pdf_light, sampling):
    """MIS weight of emission found by BSDF/phase sampling (mis_pdf 0 = camera or delta)."""
    if mis_pdf <= 0.0 or sampling == SAMPLING_BSDF:
        return 1.0
    if sampling == SAMPLING_NEE:
        return 0.0
    return power_heuristic(mis_pdf, pdf_light)


@inline_kernel
def _medium_nee(ps, i, md, lt, cfg, x, d, beta, key, dim, sh, s, light, lp, weight):
    """Next-event estimation from medium point x (with path weight `weight` to reach it).
    Uses dimensions dim .. dim + MEDIUM_NEE_DIMS - 1 whether or not it emits a shadow ray
    (so the batched next-event vertex, nee_batch, keeps the same random numbers)."""
    pmf = lt[7]
    wi, dist, le, pdf, is_delta = connect_light(lt, light, lp, x, uniform(key, dim), uniform(key, dim + 1))
    stack = ps.stack[i]
    p_light = pdf * pmf[light]
    if p_light <= 0.0 or max3(le) <= 0.0:
        return s
    fph, ph = phase_eval(md, stack, x, d, wi)
    w = _light_sample_weight(lt, light, p_light, ph, is_delta, cfg[CFG_SAMPLING])
    c = scale(mul(mul(mul(beta, weight), le), fph), w / p_light)
    if max3(c) <= 0.0:
        return s
    length = dist * 0.9999 if dist < RAY_FAR else RAY_FAR
    _emit_shadow(sh, s, x, wi, length, c, ps.pid[i], key, dim + 2, stack, 0.0)
    return s + 1


@kernel
def _flush_nee_batch(count, nb, ps, cfg, sh, s):
    """Run the batched homogeneous segments 0..count-1 (nee_batch, SIMD across paths): write
    the shadow rays of next-event connections that carry light from index s, and each
    path's new state. Returns the new s."""
    # Without interfaces a shadow ray stays in its medium, so the batch applies the
    # transmittance too (SIMD) and the ray leaves with an empty stack: shadow_media skips it.
    in_batch = cfg[CFG_WALK_SHADOWS] == 0
    nee_batch.run(count, nb, cfg[CFG_SAMPLING] != SAMPLING_NEE, in_batch, cfg[CFG_UNIFORM_CHANNEL] != 0)
    _, q_key, q_dim, q_path, r = nb
    for j in range(count):
        i = q_path[j]
        x, wi, length, c = nee_batch.shadow_ray(r, j)
        if max3(c) > 0.0:
            _emit_shadow(sh, s, x, wi, length, c, ps.pid[i], q_key[j], q_dim[j] + SEG_SHADOW, ps.stack[i],
                         0.0)
            if in_batch:
                sh.stack[s, 0] = EMPTY
            s += 1
        state, dim, beta, y, wo, pdf = nee_batch.path_update(r, j)
        ps.dim[i] = dim
        if state == nee_batch.DEAD:
            ps.alive[i] = 0
            continue
        if state == nee_batch.PASSED:
            _put(ps.beta, i, beta)
            continue
        _scatter_in_medium(ps, i, beta, ps.depth[i], y, wo, pdf)
        ps.alive[i] = 2
    return s


@inline_kernel
def _scatter_in_medium(ps, i, beta, depth, x, wi, pdf):
    """Path i scattered at medium point x (its depth-th event) into wi with phase pdf `pdf`:
    its next ray starts there, with throughput beta."""
    _put(ps.beta, i, beta)
    ps.depth[i] = depth + 1
    ps.mis_pdf[i] = pdf
    _put(ps.mis_o, i, x)
    _put(ps.o, i, x)
    _put(ps.d, i, wi)
    ps.tmax[i] = RAY_FAR
    ps.gap[i] = 0.0


@inline_kernel
def _russian_roulette(ps, i, key, dim, rr_depth):
    """Survive with probability max(throughput) (capped at 1) after rr_depth bounces."""
    if ps.depth[i] < rr_depth:
        return True, dim
    beta = _vec(ps.beta, i)
    q = min(1.0, max3(beta))
    u = uniform(key, dim)
    dim += 1
    if q <= 0.0 or u >= q:
        return False, dim
    _put(ps.beta, i, scale(beta, 1.0 / q))
    return True, dim


@kernel
def shade_media(n, ps, prim, lt, md, cfg, L, sh, nb):
    """The participating media along each live path's segment [0, hit): emission, the
    next-event vertex, free-flight sampling. A path that scatters gets its next ray here
    (alive = 2); one that reaches the segment's end goes on to shade_surface (alive = 1).
    Returns the number of shadow rays written (from 0)."""
    max_bounces = cfg[CFG_MAX_BOUNCES]
    sampling = cfg[CFG_SAMPLING]
    uniform_channel = cfg[CFG_UNIFORM_CHANNEL] != 0
    s = 0
    cdf = lt[8]
    batched = cfg[CFG_NEE_BATCH] != 0
    queued = 0
    for i in range(n):
        stack = ps.stack[i]
        if stack_is_empty(stack):
            continue
        pid = ps.pid[i]
        key = ps.key[i]
        dim = ps.dim[i]
        d = _vec(ps.d, i)
        gap = np.float64(ps.gap[i])
        o = madd(_vec(ps.o, i), d, -gap)  # the surface point the ray left, not its offset origin
        beta = _vec(ps.beta, i)
        depth = ps.depth[i]
        t_hit = np.float64(ps.tmax[i]) + gap if prim[i] >= 0 else RAY_FAR
        did_nee = False
        homogeneous = not stack_has_grid(md, stack)
        wants_nee = sampling != SAMPLING_BSDF and depth <= max_bounces and cdf.shape[0] > 1
        if wants_nee and homogeneous:
            # Decoupled next-event vertex (as Cycles): a point on the segment chosen by
            # equiangular/free-flight MIS toward a light point, independent of where the
            # path itself goes on.
            light = pick_light(cdf, uniform(key, dim))
            use_eq = cfg[CFG_EQUIANGULAR] != 0 and light_has_point(lt, light)
            if batched and nee_batch.qualifies(lt, light, stack):
                # The whole segment (this vertex, the free flight, the phase sample and
                # Russian roulette) runs in the SIMD batch; only its emission is added here.
                sa, ss = stack_sigma(md, stack)
                st = add(sa, ss)
                le = segment_emission(md, stack, st, t_hit)
                if max3(le) > 0.0:
                    L[pid, 0] += beta[0] * le[0]
                    L[pid, 1] += beta[1] * le[1]
                    L[pid, 2] += beta[2] * le[2]
                nee_batch.record(nb, queued, i, key, dim, lt, light, o, d, t_hit, beta, ss, st,
                                 phase_g(md, stack[0]), use_eq, depth + 1 >= cfg[CFG_RR_DEPTH])
                queued += 1
                if queued == nee_batch.CHUNK:
                    s = _flush_nee_batch(queued, nb, ps, cfg, sh, s)
                    queued = 0
                continue
            lp = light_point(lt, light, uniform(key, dim + 1), uniform(key, dim + 2))
            dim += 3
            # Shared by the next-event vertex and the path's own free flight.
            seg = segment(md, stack, t_hit)
            tn, wn, dim = nee_vertex_on(seg, o, d, t_hit, lp, beta, key, dim, use_eq, uniform_channel)
            if max3(wn) > 0.0:
                s = _medium_nee(ps, i, md, lt, cfg, madd(o, d, tn), d, beta, key, dim, sh, s, light, lp, wn)
            dim += MEDIUM_NEE_DIMS
            did_nee = True
        if homogeneous:
            if not did_nee:
                seg = segment(md, stack, t_hit)
            p = channel_probabilities(beta, uniform_channel)
            t, scattered, w, le, dim = sample_segment(md, stack, seg, t_hit, p, key, dim)
        else:
            t, scattered, w, le, dim = sample_distance(md, stack, o, d, t_hit, beta, key, dim,
                                                       uniform_channel)
        if max3(le) > 0.0:
            L[pid, 0] += beta[0] * le[0]
            L[pid, 1] += beta[1] * le[1]
            L[pid, 2] += beta[2] * le[2]
        beta = mul(beta, w)
        ps.dim[i] = dim
        if max3(beta) <= 0.0 or (scattered and depth > max_bounces):
            ps.alive[i] = 0
            continue
        if not scattered:
            _put(ps.beta, i, beta)
            continue
        x = madd(o, d, t)
        if not did_nee and sampling != SAMPLING_BSDF and cdf.shape[0] > 1:
            light = pick_light(cdf, uniform(key, dim))
            lp = light_point(lt, light, uniform(key, dim + 1), uniform(key, dim + 2))
            dim += 3
            s = _medium_nee(ps, i, md, lt, cfg, x, d, beta, key, dim, sh, s, light, lp, (1.0, 1.0, 1.0))
            dim += MEDIUM_NEE_DIMS
        wi, pw, ph_pdf = sample_phase(md, stack, x, d, uniform(key, dim), uniform(key, dim + 1),
                                      uniform(key, dim + 2))
        dim += 3
        _scatter_in_medium(ps, i, mul(beta, pw), depth, x, wi, ph_pdf)
        alive, dim = _russian_roulette(ps, i, key, dim, cfg[CFG_RR_DEPTH])
        ps.alive[i] = 2 if alive else 0
        ps.dim[i] = dim
    if queued > 0:
        s = _flush_nee_batch(queued, nb, ps, cfg, sh, s)
    return s


@kernel
def shade_surface(n, ps, prim, bu, bv, geo, mt, lt, env_light, sun_rows, cfg, L, sh, s):
    """Shade the closest hits of paths 0..n-1 with alive == 1 (prim -1 = escaped; ps.tmax
    holds the hit distance): emission, next-event estimation, BSDF sampling, Russian
    roulette. Writes new rays into ps, kills finished paths, appends shadow rays to sh from
    index s. Holds no medium code: a scene without media runs only this kernel. Returns the
    number of shadow rays written in all."""
    max_bounces = cfg[CFG_MAX_BOUNCES]
    sampling = cfg[CFG_SAMPLING]
    cdf = lt[8]
    pmf = lt[7]
    for i in range(n):
        if ps.alive[i] != 1:
            continue
        pid = ps.pid[i]
        key = ps.key[i]
        dim = ps.dim[i]
        d = _vec(ps.d, i)
        beta = _vec(ps.beta, i)
        depth = ps.depth[i]
        p = prim[i]
        stack = ps.stack[i]

        # --- escaped: environment and sun discs ------------------------------------------
        if p < 0:
            le, pdf_light = escaped_radiance(lt, env_light, sun_rows, d)
            if max3(le) > 0.0:
                w = _hit_weight(ps.mis_pdf[i], pdf_light, sampling)
                L[pid, 0] += beta[0] * le[0] * w
                L[pid, 1] += beta[1] * le[1] * w
                L[pid, 2] += beta[2] * le[2] * w
            ps.alive[i] = 0
            continue

        # --- surface hit ---------------------------------------------------------------
        b1 = float(bu[i])
        b2 = float(bv[i])
        b0 = 1.0 - b1 - b2
        v0 = _vec(geo.v0, p)
        x = madd(madd(v0, _vec(geo.e1, p), b1), _vec(geo.e2, p), b2)
        ng = _vec(geo.ng, p)
        front = dot(d, ng) < 0.0
        m = geo.material[p]

        light = geo.light[p]
        if light >= 0:
            c = lt[4] if front else lt[5]
            le = (float(c[light, 0]), float(c[light, 1]), float(c[light, 2]))
            if max3(le) > 0.0:
                w = 1.0
                if ps.mis_pdf[i] > 0.0 or sampling == SAMPLING_NEE:
                    pdf_light = triangle_light_pdf(lt, light, _vec(ps.mis_o, i), x, dot(d, ng))
                    w = _hit_weight(ps.mis_pdf[i], pdf_light, sampling)
                L[pid, 0] += beta[0] * le[0] * w
                L[pid, 1] += beta[1] * le[1] * w
                L[pid, 2] += beta[2] * le[2] * w

        if not bsdf_has_lobes(mt, m, front):
            if light >= 0:
                # A pure emitter (Cycles' Emission shader): black, opaque.
                ps.alive[i] = 0
                continue
            # An invisible interface: cross it without scattering.
            _cross_interface(ps, i, geo, p, front, x, ng, d, beta)
            ps.dim[i] = dim
            continue
        if depth > max_bounces:
            ps.alive[i] = 0
            continue

        sn = _shading_normal(geo, p, b0, b1, b2, ng)
        ts, tt = onb(sn)
        wo = to_local(neg(d), ts, tt, sn)

        # next-event estimation
        if sampling != SAMPLING_BSDF and cdf.shape[0] > 1:
            light = pick_light(cdf, uniform(key, dim))
            lp = light_point(lt, light, uniform(key, dim + 1), uniform(key, dim + 2))
            wi, dist, le, pdf, is_delta = connect_light(lt, light, lp, x, uniform(key, dim + 3),
                                                        uniform(key, dim + 4))
            dim += 5
            p_light = pdf * pmf[light]
            if p_light > 0.0 and max3(le) > 0.0:
                wil = to_local(wi, ts, tt, sn)
                f, pdf_bsdf = bsdf_eval(mt, m, front, wo, wil)
                w = _light_sample_weight(lt, light, p_light, pdf_bsdf, is_delta, sampling)
                c = scale(mul(mul(beta, f), le), abs(wil[2]) * w / p_light)
                if max3(c) > 0.0:
                    xo = offset_origin(x, ng, wi)
                    ws = wi
                    if dist < RAY_FAR:
                        # Aim from the offset origin itself at the light point x + wi dist:
                        # with wi from x, the ray meets the light's plane up to ~2e-4 short
                        # of the point and the light occludes itself (measured: 97% of such
                        # shadow rays were lost). (Not lp: triangles are sampled by solid
                        # angle, lp serves only the area fallback.)
                        to = sub(madd(x, wi, dist), xo)
                        dist = math.sqrt(dot(to, to))
                        ws = scale(to, 1.0 / dist)
                        dist *= 0.9999
                    gap = max(0.0, dot(sub(xo, x), ws))
                    _emit_shadow(sh, s, xo, ws, dist, c, pid, key, dim, stack, gap)
                    s += 1
                    dim += SHADOW_DIMS

        # BSDF sampling
        wil, w, pdf, event = bsdf_sample(mt, m, front, wo, uniform(key, dim), uniform(key, dim + 1),
                                         uniform(key, dim + 2), uniform(key, dim + 3))
        dim += 4
        if event == 0 or max3(w) <= 0.0:
            ps.alive[i] = 0
            continue
        beta = mul(beta, w)
        if event == 3:
            _cross_interface(ps, i, geo, p, front, x, ng, d, beta)
            ps.dim[i] = dim
            continue
        wi = normalize(to_world(wil, ts, tt, sn))
        # Crossing to the other side of the geometric surface enters or leaves its medium.
        if (dot(wi, ng) > 0.0) != front:
            _update_stack(ps, i, geo, p, front)
        _put(ps.beta, i, beta)
        ps.depth[i] = depth + 1
        ps.mis_pdf[i] = pdf if event == 1 else 0.0
        _put(ps.mis_o, i, x)
        _spawn(ps, i, x, ng, wi)
        alive, dim = _russian_roulette(ps, i, key, dim, cfg[CFG_RR_DEPTH])
        ps.alive[i] = 1 if alive else 0
        ps.dim[i] = dim
    return s


@inline_kernel
def _shading_normal(geo, p, b0, b1, b2, ng):
    sn0 = _vec(geo.sn[p], 0)
    sn1 = _vec(geo.sn[p], 1)
    sn2 = _vec(geo.sn[p], 2)
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
    _put(ps.o, i, o)
    _put(ps.d, i, direction)
    ps.tmax[i] = RAY_FAR
    ps.gap[i] = max(0.0, dot(sub(o, x), direction))


@inline_kernel
def _update_stack(ps, i, geo, p, front):
    med = geo.medium[p]
    if med >= 0:
        if front:
            stack_push(ps.stack[i], med)
        else:
            stack_remove(ps.stack[i], med)


@inline_kernel
def _cross_interface(ps, i, geo, p, front, x, ng, d, beta):
    """Continue straight through the surface at x, entering or leaving its medium."""
    _update_stack(ps, i, geo, p, front)
    ps.crossings[i] += 1
    if ps.crossings[i] > MAX_CROSSINGS:
        ps.alive[i] = 0
        return
    _put(ps.beta, i, beta)
    _spawn(ps, i, x, ng, d)
    ps.alive[i] = 1


@kernel
def shadow_media(count, sh, md, cfg):
    """Multiply each shadow ray's contribution by the transmittance of its medium stack
    over its whole length (used when no interface can lie on a shadow ray, so the stack is
    constant along it; otherwise walk_shadows accumulates it piece by piece)."""
    use_delta = cfg[CFG_DELTA_TR] != 0
    for s in range(count):
        stack = sh.stack[s]
        if stack_is_empty(stack):
            continue
        gap = np.float64(sh.gap[s])
        tr, dim = transmittance(md, stack, _vec(sh.o, s), _vec(sh.d, s), -gap, np.float64(sh.tmax[s]),
                                sh.key[s], sh.dim[s], use_delta)
        sh.dim[s] = dim
        _put(sh.contrib, s, mul(_vec(sh.contrib, s), tr))


@kernel
def resolve_shadows(count, sh, occluded, L):
    """Add the contributions of shadow rays that reached their light."""
    for s in range(count):
        if not occluded[s]:
            pid = sh.pid[s]
            L[pid, 0] += sh.contrib[s, 0]
            L[pid, 1] += sh.contrib[s, 1]
            L[pid, 2] += sh.contrib[s, 2]


@kernel
def walk_shadows(count, sh, prim, thit, remaining, geo, mt, md, cfg, L):
    """One step of shadow rays that may pass interfaces. thit is the hit distance where
    prim >= 0; remaining is each ray's length left to its light. A ray that reaches its end
    adds its contribution; one that hits an opaque surface dies; one that hits an interface
    or a transparent lobe continues past it with its medium stack updated."""
    has_media = cfg[CFG_HAS_MEDIA] != 0
    for s in range(count):
        o = _vec(sh.o, s)
        d = _vec(sh.d, s)
        p = prim[s]
        t_end = float(thit[s]) if p >= 0 else float(remaining[s])
        stack = sh.stack[s]
        c = _vec(sh.contrib, s)
        if has_media and not stack_is_empty(stack):
            tr, dim = transmittance(md, stack, o, d, -np.float64(sh.gap[s]), t_end, sh.key[s], sh.dim[s],
                                    cfg[CFG_DELTA_TR] != 0)
            sh.dim[s] = dim
            c = mul(c, tr)
        if max3(c) <= 0.0:
            sh.alive[s] = 0
            continue
        if p < 0:
            pid = sh.pid[s]
            L[pid, 0] += c[0]
            L[pid, 1] += c[1]
            L[pid, 2] += c[2]
            sh.alive[s] = 0
            continue
        ng = _vec(geo.ng, p)
        front = dot(d, ng) < 0.0
        m = geo.material[p]
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
        _put(sh.o, s, xo)
        _put(sh.contrib, s, mul(c, tint))
        sh.alive[s] = 1


@inline_kernel
def _transparency(mt, m, front):
    """How much light passes straight through material m from this side: 1 for a surface
    with no lobes (an interface), the transparent lobes' weight*color otherwise."""
    if not bsdf_has_lobes(mt, m, front):
        return (1.0, 1.0, 1.0)
    mats, lobes = mt
    side = 1 if front else 2
    r, g, b = 0.0, 0.0, 0.0
    for j in range(mats[m, 0], mats[m, 0] + mats[m, 1]):
        if (int(lobes[j, L_SIDES]) & side) != 0 and int(lobes[j, L_KIND]) == TRANSPARENT:
            r += lobes[j, L_WEIGHT] * lobes[j, L_COLOR]
            g += lobes[j, L_WEIGHT + 1] * lobes[j, L_COLOR + 1]
            b += lobes[j, L_WEIGHT + 2] * lobes[j, L_COLOR + 2]
    return (min(r, 1.0), min(g, 1.0), min(b, 1.0))


@kernel
def compact_paths(n, ps):
    """Move live paths to rows 0..k-1 (stable) and return k."""
    k = 0
    for i in range(n):
        if ps.alive[i] == 0:
            continue
        if k != i:
            for c in range(3):
                ps.o[k, c] = ps.o[i, c]
                ps.d[k, c] = ps.d[i, c]
                ps.beta[k, c] = ps.beta[i, c]
                ps.mis_o[k, c] = ps.mis_o[i, c]
            ps.tmax[k] = ps.tmax[i]
            ps.gap[k] = ps.gap[i]
            ps.pid[k] = ps.pid[i]
            ps.key[k] = ps.key[i]
            ps.dim[k] = ps.dim[i]
            ps.depth[k] = ps.depth[i]
            ps.crossings[k] = ps.crossings[i]
            ps.mis_pdf[k] = ps.mis_pdf[i]
            for j in range(ps.stack.shape[1]):
                ps.stack[k, j] = ps.stack[i, j]
            ps.alive[k] = 1
        ps.alive[k] = 1
        k += 1
    return k


@kernel
def compact_shadows(n, sh, remaining):
    """Keep live shadow rays (rows 0..k-1); `remaining` (S,) float32 holds each ray's length
    left to its light and moves along."""
    k = 0
    for i in range(n):
        if sh.alive[i] == 0:
            continue
        if k != i:
            for c in range(3):
                sh.o[k, c] = sh.o[i, c]
                sh.d[k, c] = sh.d[i, c]
                sh.contrib[k, c] = sh.contrib[i, c]
            sh.pid[k] = sh.pid[i]
            sh.gap[k] = sh.gap[i]
            sh.key[k] = sh.key[i]
            sh.dim[k] = sh.dim[i]
            for j in range(sh.stack.shape[1]):
                sh.stack[k, j] = sh.stack[i, j]
            sh.alive[k] = 1
        remaining[k] = remaining[i]
        k += 1
    return k


@kernel
def splat(n, L, pixel_of_pid, film_sum, film_sq, film_n, film_nonfinite):
    """Add paths 0..n-1 of the batch to the film (per-pixel sum, sum of squares, count).
    A non-finite path value (a bug, never expected) is counted and added as 0, so one bad
    path cannot ruin an image but cannot pass unnoticed either."""
    for i in range(n):
        px = pixel_of_pid[i]
        for c in range(3):
            v = L[i, c]
            if not np.isfinite(v):
                film_nonfinite[0] += 1
                v = 0.0
            film_sum[px, c] += v
            film_sq[px, c] += v * v
        film_n[px] += 1
