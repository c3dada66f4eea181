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
"""

from numba import njit

from renderer.kernels.rng import uniform
from renderer.media.equiangular import equiangular_pdf, equiangular_sample
from renderer.media.homogeneous import (
    beer,
    sample_truncated_exponential,
    stack_sigma,
    truncated_exponential_pdf,
)
from renderer.media.spectral import channel_probabilities, pick_channel


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def nee_vertex(mt, stack, o, d, tmax, light_p, throughput, key, dim, use_equiangular, uniform_channel):
    """(t, weight3, dim) for a HOMOGENEOUS stack: a point on [0, tmax) and its weight
    T(t) sigma_s / pdf(t). Consumes 3 dimensions. Plain truncated free flight when
    use_equiangular is False (light_p is then unused)."""
    sa, ss = stack_sigma(mt, stack)
    st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
    p = channel_probabilities(throughput, uniform_channel)
    u_technique = uniform(key, dim)
    u_channel = uniform(key, dim + 1)
    u_t = uniform(key, dim + 2)
    dim += 3
    if not (ss[0] > 0.0 or ss[1] > 0.0 or ss[2] > 0.0) or not tmax > 0.0:
        return 0.0, (0.0, 0.0, 0.0), dim
    if use_equiangular and u_technique < 0.5:
        t, _ = equiangular_sample(o, d, light_p, tmax, u_t)
    else:
        t = sample_truncated_exponential(st[pick_channel(p, u_channel)], tmax, u_t)
    pdf = (
        p[0] * truncated_exponential_pdf(st[0], tmax, t)
        + p[1] * truncated_exponential_pdf(st[1], tmax, t)
        + p[2] * truncated_exponential_pdf(st[2], tmax, t)
    )
    if use_equiangular:
        pdf = 0.5 * pdf + 0.5 * equiangular_pdf(o, d, light_p, tmax, t)
    tr = beer(st, t)
    return t, (tr[0] * ss[0] / pdf, tr[1] * ss[1] / pdf, tr[2] * ss[2] / pdf), dim
