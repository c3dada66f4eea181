"""The next-event-estimation vertex of a homogeneous segment (decoupled, as Cycles does).

For direct light on a ray segment [0, tmax) inside a homogeneous stack we need

    integral_0^tmax T(t) sigma_s L_direct(t) dt,

and L_direct(t) peaks near the light while T(t) sigma_s favours small t. One point is
drawn by one-sample MIS (balance heuristic) between equiangular sampling toward the light
and free-flight sampling truncated to [0, tmax) (itself a spectral-MIS mixture over
channels), each technique picked with probability 1/2:

    pdf(t) = 1/2 pdf_equiangular(t) + 1/2 sum_c p_c pdf_c(t),  weight = T(t) sigma_s / pdf(t).

The integrator multiplies the weight by phase * light / light_pdf and the shadow-ray
transmittance. The vertex is independent of where the path continues.

nee_vertex_simd is the same vertex without branches, for the SIMD batch of homogeneous
segments (renderer.integrator.nee_batch).
"""

from renderer.kernels import inline_kernel, kernel
from renderer.kernels.rng import hashed_uniform
from renderer.media.equiangular import (
    equiangular_frame,
    equiangular_frame_simd,
    frame_pdf,
    frame_pdf_simd,
    frame_sample,
    frame_sample_simd,
)
from renderer.media.homogeneous import (
    beer,
    beer_simd,
    sample_truncated,
    sample_truncated_simd,
    segment,
    truncated_pdf,
)
from renderer.media.spectral import channel_probabilities, channel_value, pick_channel


@inline_kernel
def nee_vertex(mt, stack, o, d, tmax, light_p, throughput, key, dim, use_equiangular, uniform_channel):
    """(t, weight3, dim) for a HOMOGENEOUS stack: a point on [0, tmax) and its weight
    T(t) sigma_s / pdf(t). Consumes 3 dimensions. Plain truncated free flight when
    use_equiangular is False (light_p is then unused)."""
    return nee_vertex_on(segment(mt, stack, tmax), o, d, tmax, light_p, throughput, key, dim, use_equiangular,
                         uniform_channel)


@kernel
def nee_vertex_on(seg, o, d, tmax, light_p, throughput, key, dim, use_equiangular, uniform_channel):
    """nee_vertex given the segment's constants (homogeneous.segment), so that the path's
    own free-flight sampling on the same segment can reuse them."""
    _, ss, st, _, miss = seg
    p = channel_probabilities(throughput, uniform_channel)
    u_technique = hashed_uniform(key, dim)
    u_channel = hashed_uniform(key, dim + 1)
    u_t = hashed_uniform(key, dim + 2)
    dim += 3
    if not (ss[0] > 0.0 or ss[1] > 0.0 or ss[2] > 0.0) or not tmax > 0.0:
        return 0.0, (0.0, 0.0, 0.0), dim
    if use_equiangular:
        frame = equiangular_frame(o, d, light_p, tmax)
        if u_technique < 0.5:
            t = frame_sample(frame, tmax, u_t)
        else:
            c = pick_channel(p, u_channel)
            t = sample_truncated(st[c], tmax, miss[c], u_t)
    else:
        c = pick_channel(p, u_channel)
        t = sample_truncated(st[c], tmax, miss[c], u_t)
    tr = beer(st, t)
    pdf = (
        p[0] * truncated_pdf(st[0], tmax, miss[0], tr[0])
        + p[1] * truncated_pdf(st[1], tmax, miss[1], tr[1])
        + p[2] * truncated_pdf(st[2], tmax, miss[2], tr[2])
    )
    if use_equiangular:
        pdf = 0.5 * pdf + 0.5 * frame_pdf(frame, tmax, t)
    return t, (tr[0] * ss[0] / pdf, tr[1] * ss[1] / pdf, tr[2] * ss[2] / pdf), dim


@inline_kernel
def nee_vertex_simd(o, d, tmax, sigma_s, sigma_t, miss, p, light_p, use_equiangular, u_technique, u_channel,
                    u_t):
    """(t, weight3, valid) of nee_vertex_on without branches, given the segment's sigma_s,
    sigma_t and 1 - T(tmax) and the channel probabilities p; the three uniforms are the
    ones nee_vertex_on draws. valid False: no vertex (the weight is then meaningless)."""
    st0, st1, st2 = sigma_t
    m0, m1, m2 = miss
    p0, p1, p2 = p
    frame = equiangular_frame_simd(o, d, light_p, tmax)
    t_eq = frame_sample_simd(frame, tmax, u_t)
    c = pick_channel(p, u_channel)
    t_ff = sample_truncated_simd(channel_value(c, st0, st1, st2), tmax, channel_value(c, m0, m1, m2), u_t)
    t = t_eq if (use_equiangular and u_technique < 0.5) else t_ff
    tr0, tr1, tr2 = beer_simd(sigma_t, t)
    pdf = (p0 * truncated_pdf(st0, tmax, m0, tr0) + p1 * truncated_pdf(st1, tmax, m1, tr1)
           + p2 * truncated_pdf(st2, tmax, m2, tr2))
    pdf = 0.5 * pdf + 0.5 * frame_pdf_simd(frame, tmax, t) if use_equiangular else pdf
    ss0, ss1, ss2 = sigma_s
    valid = (ss0 > 0.0 or ss1 > 0.0 or ss2 > 0.0) and tmax > 0.0
    inv = 1.0 / pdf
    return t, (tr0 * ss0 * inv, tr1 * ss1 * inv, tr2 * ss2 * inv), valid
