"""The decoupled next-event vertex of homogeneous segments, as one SIMD loop across paths.

shade_media's next-event vertex (a point on the segment by equiangular/free-flight MIS, a
point on a triangle light by solid angle, the phase function and the MIS weight toward it)
is a chain of about 12 square roots, 15 divisions, 3 exp, 2 atan2 and 2 sincos per path.
Inside the per-path loop it runs at the latency of that chain (108 ns per path, half of the
medium kernel's time in the fog Cornell box). So shade_media only records each request here
(`record`); `connect_all` then runs the same maths for the whole batch as one loop without
branches, which LLVM vectorises (8 paths per AVX-512 instruction), and `emit_all` writes the
shadow rays of the connections that carry light.

Which requests qualify (`qualifies`): a homogeneous stack with one entry (so the phase
function is one Henyey-Greenstein lobe) and a triangle light. Everything else (grids,
overlapping media, point, spot and distant lights) keeps the scalar path in kernels.py,
which computes the same thing; tests/test_nee_batch.py holds the two to 1e-12.

Storage (NeeBatch), for CHUNK requests: q, Q_ROWS rows of CHUNK float64 in one flat array,
row k of request j at q[k * CHUNK + j], so that each quantity is contiguous (what SIMD loads
want) and every pair of rows lies a compile-time constant apart: LLVM then proves that the
loops' loads and stores never overlap without run-time checks (with one 2-D array per
quantity set it needed hundreds of them and gave up). r: R_ROWS rows the same way, the
results: the vertex x, the direction wi to the light, the shadow ray's length and its
contribution (0 when none). q_path (CHUNK,) int32: the path row; q_dim (CHUNK,) int32: the
first random dimension of the shadow ray.
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel
from renderer.kernels import simdmath as sm
from renderer.kernels.vecmath import cross, dot, sub
from renderer.lights.sample import looks_near
from renderer.lights.spherical_triangle import MIN_SOLID_ANGLE, sample_spherical_triangle, unit_or_zero
from renderer.lights.table import TRIANGLE
from renderer.media.equiangular import D_FLOOR, D_MIN, MIN_THETA
from renderer.media.homogeneous import optical_depth, truncated_pdf
from renderer.media.spectral import pick_channel
from renderer.media.stack import EMPTY
from renderer.phase.hg import hg_eval

Q_O, Q_D, Q_TMAX, Q_LP, Q_BETA = 0, 3, 6, 7, 10
Q_ST, Q_SS, Q_MISS, Q_P = 13, 16, 19, 22
Q_U_TECHNIQUE, Q_U_CHANNEL, Q_U_T, Q_U1, Q_U2 = 25, 26, 27, 28, 29
Q_G, Q_EQUIANGULAR = 30, 31
Q_P0, Q_P1, Q_P2, Q_AREA, Q_LE_FRONT, Q_LE_BACK, Q_PMF = 32, 35, 38, 41, 42, 45, 48
Q_ROWS = 49
R_X, R_WI, R_LENGTH, R_C = 0, 3, 6, 7
R_ROWS = 10
# Requests per SIMD pass: 1.6 MB of request rows, which stay in cache. Not a power of two: with
# rows exactly 32 KiB apart, the 49 stores of one request all fell into one cache set and
# recording took 200 ns a request instead of a few (measured); one extra cache line per row
# spreads them over 49 sets.
CHUNK = 4096 + 8


class NeeBatch:
    """Request and result storage for CHUNK next-event vertices (see the module)."""

    def __init__(self):
        self.q = np.zeros(Q_ROWS * CHUNK, np.float64)
        self.q_path = np.zeros(CHUNK, np.int32)
        self.q_dim = np.zeros(CHUNK, np.int32)
        self.r = np.zeros(R_ROWS * CHUNK, np.float64)

    def arrays(self):
        return self.q, self.q_path, self.q_dim, self.r


@inline_kernel
def result(r, j):
    """(x, wi, length, contribution) of request j after connect_all."""
    x = (r[R_X * CHUNK + j], r[(R_X + 1) * CHUNK + j], r[(R_X + 2) * CHUNK + j])
    wi = (r[R_WI * CHUNK + j], r[(R_WI + 1) * CHUNK + j], r[(R_WI + 2) * CHUNK + j])
    c = (r[R_C * CHUNK + j], r[(R_C + 1) * CHUNK + j], r[(R_C + 2) * CHUNK + j])
    return x, wi, r[R_LENGTH * CHUNK + j], c


@inline_kernel
def qualifies(lt, light, stack):
    return lt[0][light] == TRIANGLE and stack[1] == EMPTY


@inline_kernel
def _put3(a, row, j, v):
    a[row * CHUNK + j] = v[0]
    a[(row + 1) * CHUNK + j] = v[1]
    a[(row + 2) * CHUNK + j] = v[2]


@inline_kernel
def record(nb, j, path, lt, light, o, d, tmax, lp, beta, seg, p, u, g, use_equiangular, dim):
    """Store request j. seg = homogeneous.segment's (sigma_a, sigma_s, sigma_t, T, 1 - T);
    u = (u_technique, u_channel, u_t, u1, u2); dim: the shadow ray's first dimension."""
    q, q_path, q_dim, _ = nb
    _put3(q, Q_O, j, o)
    _put3(q, Q_D, j, d)
    q[Q_TMAX * CHUNK + j] = tmax
    _put3(q, Q_LP, j, lp)
    _put3(q, Q_BETA, j, beta)
    _put3(q, Q_ST, j, seg[2])
    _put3(q, Q_SS, j, seg[1])
    _put3(q, Q_MISS, j, seg[4])
    _put3(q, Q_P, j, p)
    q[Q_U_TECHNIQUE * CHUNK + j] = u[0]
    q[Q_U_CHANNEL * CHUNK + j] = u[1]
    q[Q_U_T * CHUNK + j] = u[2]
    q[Q_U1 * CHUNK + j] = u[3]
    q[Q_U2 * CHUNK + j] = u[4]
    q[Q_G * CHUNK + j] = g
    q[Q_EQUIANGULAR * CHUNK + j] = 1.0 if use_equiangular else 0.0
    q_path[j] = path
    q_dim[j] = dim
    # The light's data too: the SIMD loop then reads only rows at j (a gather by light index
    # would keep LLVM from bounding the loop's memory accesses, and so from vectorising it).
    pos, vec_a, vec_b, color, color_b, param, pmf = lt[1], lt[2], lt[3], lt[4], lt[5], lt[6], lt[7]
    for k in range(3):
        p0 = np.float64(pos[light, k])
        q[(Q_P0 + k) * CHUNK + j] = p0
        q[(Q_P1 + k) * CHUNK + j] = p0 + np.float64(vec_a[light, k])
        q[(Q_P2 + k) * CHUNK + j] = p0 + np.float64(vec_b[light, k])
        q[(Q_LE_FRONT + k) * CHUNK + j] = color[light, k]
        q[(Q_LE_BACK + k) * CHUNK + j] = color_b[light, k]
    q[Q_AREA * CHUNK + j] = param[light, 0]
    q[Q_PMF * CHUNK + j] = pmf[light]


# The maths below is media/nee.py's nee_vertex_on and lights/sample.py's connect_light for a
# triangle, with both branches of each choice computed and one kept by a select. It calls
# the shared kernels wherever those are already free of calls (pick_channel, optical_depth,
# truncated_pdf, sample_spherical_triangle, hg_eval) and restates only what is not: the
# equiangular sampler and free flight (libm fallbacks in fastmath's log1p and atan2, which
# simdmath leaves out) and the choice between solid-angle and area sampling.


@inline_kernel
def _pick(c, a, b, e):
    return a if c == 0 else (b if c == 1 else e)


@inline_kernel
def _truncated_sample(sigma, tmax, miss, u):
    ok = sigma > 0.0 and miss > 0.0
    t = min(-sm.log1p(-u * miss) / (sigma if ok else 1.0), tmax)
    return t if ok else u * tmax


@inline_kernel
def _vertex(q, j):
    """(t, weight3, valid) of the next-event vertex on [0, tmax) (media.nee.nee_vertex_on)."""
    ox, oy, oz = q[Q_O * CHUNK + j], q[(Q_O + 1) * CHUNK + j], q[(Q_O + 2) * CHUNK + j]
    dx, dy, dz = q[Q_D * CHUNK + j], q[(Q_D + 1) * CHUNK + j], q[(Q_D + 2) * CHUNK + j]
    tmax = q[Q_TMAX * CHUNK + j]
    st0, st1, st2 = q[Q_ST * CHUNK + j], q[(Q_ST + 1) * CHUNK + j], q[(Q_ST + 2) * CHUNK + j]
    ss0, ss1, ss2 = q[Q_SS * CHUNK + j], q[(Q_SS + 1) * CHUNK + j], q[(Q_SS + 2) * CHUNK + j]
    m0, m1, m2 = q[Q_MISS * CHUNK + j], q[(Q_MISS + 1) * CHUNK + j], q[(Q_MISS + 2) * CHUNK + j]
    p0, p1, p2 = q[Q_P * CHUNK + j], q[(Q_P + 1) * CHUNK + j], q[(Q_P + 2) * CHUNK + j]
    use_eq = q[Q_EQUIANGULAR * CHUNK + j] != 0.0
    # Equiangular frame toward the light point.
    lx, ly, lz = q[Q_LP * CHUNK + j] - ox, q[(Q_LP + 1) * CHUNK + j] - oy, q[(Q_LP + 2) * CHUNK + j] - oz
    delta = lx * dx + ly * dy + lz * dz
    px, py, pz = lx - delta * dx, ly - delta * dy, lz - delta * dz
    big_d = max(math.sqrt(px * px + py * py + pz * pz), D_FLOOR * abs(delta), D_MIN)
    theta_d = sm.atan2(big_d * tmax, big_d * big_d - delta * (tmax - delta))
    degenerate = not theta_d >= MIN_THETA
    u_t = q[Q_U_T * CHUNK + j]
    sin_phi, cos_phi = sm.sincos(u_t * theta_d)
    denom = big_d * cos_phi + delta * sin_phi
    t_eq = min(max((delta * delta + big_d * big_d) * sin_phi / denom, 0.0), tmax)
    t_eq = tmax if denom <= 0.0 else t_eq
    t_eq = u_t * tmax if degenerate else t_eq
    # Truncated free flight in the channel chosen by p.
    c = pick_channel((p0, p1, p2), q[Q_U_CHANNEL * CHUNK + j])
    t_ff = _truncated_sample(_pick(c, st0, st1, st2), tmax, _pick(c, m0, m1, m2), u_t)
    t = t_eq if (use_eq and q[Q_U_TECHNIQUE * CHUNK + j] < 0.5) else t_ff
    tr0 = sm.exp_neg(optical_depth(st0, t))
    tr1 = sm.exp_neg(optical_depth(st1, t))
    tr2 = sm.exp_neg(optical_depth(st2, t))
    pdf = (p0 * truncated_pdf(st0, tmax, m0, tr0) + p1 * truncated_pdf(st1, tmax, m1, tr1)
           + p2 * truncated_pdf(st2, tmax, m2, tr2))
    x = t - delta
    pdf_eq = 1.0 / tmax if degenerate else big_d / (theta_d * (big_d * big_d + x * x))
    pdf = 0.5 * pdf + 0.5 * pdf_eq if use_eq else pdf
    valid = (ss0 > 0.0 or ss1 > 0.0 or ss2 > 0.0) and tmax > 0.0
    inv = 1.0 / pdf
    return t, (tr0 * ss0 * inv, tr1 * ss1 * inv, tr2 * ss2 * inv), valid


@inline_kernel
def _connect_triangle(q, j, x, u1, u2):
    """connect_triangle for request j's light."""
    p0 = (q[Q_P0 * CHUNK + j], q[(Q_P0 + 1) * CHUNK + j], q[(Q_P0 + 2) * CHUNK + j])
    p1 = (q[Q_P1 * CHUNK + j], q[(Q_P1 + 1) * CHUNK + j], q[(Q_P1 + 2) * CHUNK + j])
    p2 = (q[Q_P2 * CHUNK + j], q[(Q_P2 + 1) * CHUNK + j], q[(Q_P2 + 2) * CHUNK + j])
    lp = (q[Q_LP * CHUNK + j], q[(Q_LP + 1) * CHUNK + j], q[(Q_LP + 2) * CHUNK + j])
    return connect_triangle(p0, p1, p2, lp, q[Q_AREA * CHUNK + j], x, u1, u2)


@inline_kernel
def connect_triangle(p0, p1, p2, lp, area, x, u1, u2):
    """(wi, dist, back_side, pdf) of lights.sample.connect_light for the triangle light
    p0 p1 p2 of the given area (lp: its area-sampled point), without branches, so that a
    loop calling it vectorises; pdf 0 when there is no connection."""
    near = looks_near(x, p0, p1, p2)
    # Solid angle and Arvo's direction.
    a = unit_or_zero(sub(p0, x))
    b = unit_or_zero(sub(p1, x))
    c = unit_or_zero(sub(p2, x))
    omega = 2.0 * sm.atan2(abs(dot(a, cross(b, c))), 1.0 + dot(a, b) + dot(b, c) + dot(c, a))
    solid = near and omega >= MIN_SOLID_ANGLE and omega < math.inf
    w_sa = sample_spherical_triangle(a, b, c, omega, u1, u2)
    n = unit_or_zero(cross(sub(p1, p0), sub(p2, p0)))
    cos_sa = -dot(w_sa, n)
    dist_sa = ((x[0] - p0[0]) * n[0] + (x[1] - p0[1]) * n[1] + (x[2] - p0[2]) * n[2]) / (
        cos_sa if cos_sa != 0.0 else 1.0)
    ok_sa = cos_sa != 0.0 and dist_sa > 0.0 and dist_sa < math.inf
    # Area sampling toward the light point.
    tx, ty, tz = lp[0] - x[0], lp[1] - x[1], lp[2] - x[2]
    dist_a = math.sqrt(tx * tx + ty * ty + tz * tz)
    inv = 1.0 / dist_a if dist_a > 0.0 else 0.0
    w_a = (tx * inv, ty * inv, tz * inv)
    cos_a = -dot(w_a, n)
    ok_a = dist_a > 0.0 and abs(cos_a) >= 1e-8 and area > 0.0
    pdf_a = dist_a * dist_a / (area * abs(cos_a)) if ok_a else 0.0
    wi = w_sa if solid else w_a
    dist = dist_sa if solid else dist_a
    cos_l = cos_sa if solid else cos_a
    pdf = (1.0 / omega if ok_sa else 0.0) if solid else pdf_a
    return wi, dist, cos_l < 0.0, pdf


@kernel
def vertices(n, nb):
    """Stage 1: the next-event vertex x of requests 0..n-1 and its weight (0 when none)."""
    q, _, _, r = nb
    for j in range(n):
        t, wn, valid = _vertex(q, j)
        r[R_X * CHUNK + j] = q[Q_O * CHUNK + j] + t * q[Q_D * CHUNK + j]
        r[(R_X + 1) * CHUNK + j] = q[(Q_O + 1) * CHUNK + j] + t * q[(Q_D + 1) * CHUNK + j]
        r[(R_X + 2) * CHUNK + j] = q[(Q_O + 2) * CHUNK + j] + t * q[(Q_D + 2) * CHUNK + j]
        r[R_C * CHUNK + j] = wn[0] if valid else 0.0
        r[(R_C + 1) * CHUNK + j] = wn[1] if valid else 0.0
        r[(R_C + 2) * CHUNK + j] = wn[2] if valid else 0.0


@kernel
def connections(n, nb, mis, with_transmittance):
    """Stage 2: the light connection of each vertex; R_C becomes the shadow ray's
    contribution. mis False = light sampling only (weight 1). with_transmittance: include the
    shadow ray's transmittance exp(-sigma_t length) (valid when no interface can lie on a
    shadow ray, so its medium is the request's all along; the integrator then leaves the
    ray out of shadow_media)."""
    q, _, _, r = nb
    for j in range(n):
        d = (q[Q_D * CHUNK + j], q[(Q_D + 1) * CHUNK + j], q[(Q_D + 2) * CHUNK + j])
        x = (r[R_X * CHUNK + j], r[(R_X + 1) * CHUNK + j], r[(R_X + 2) * CHUNK + j])
        wi, dist, back, pdf = _connect_triangle(q, j, x, q[Q_U1 * CHUNK + j], q[Q_U2 * CHUNK + j])
        # A blend with weights 0 and 1 (exact), not `back ? row_b : row_f`: LLVM turns a
        # select of two loads into a load from a selected address, which it cannot vectorise.
        f = 1.0 if back else 0.0
        le0 = q[Q_LE_FRONT * CHUNK + j] * (1.0 - f) + q[Q_LE_BACK * CHUNK + j] * f
        le1 = q[(Q_LE_FRONT + 1) * CHUNK + j] * (1.0 - f) + q[(Q_LE_BACK + 1) * CHUNK + j] * f
        le2 = q[(Q_LE_FRONT + 2) * CHUNK + j] * (1.0 - f) + q[(Q_LE_BACK + 2) * CHUNK + j] * f
        p_light = pdf * q[Q_PMF * CHUNK + j]
        ph = hg_eval(q[Q_G * CHUNK + j], dot(d, wi))
        a2 = p_light * p_light
        b2 = ph * ph
        w = (a2 / (a2 + b2) if a2 + b2 > 0.0 else 0.0) if mis else 1.0
        k = w / p_light * ph if p_light > 0.0 else 0.0
        r[R_WI * CHUNK + j] = wi[0]
        r[(R_WI + 1) * CHUNK + j] = wi[1]
        r[(R_WI + 2) * CHUNK + j] = wi[2]
        length = dist * 0.9999
        r[R_LENGTH * CHUNK + j] = length
        tr0 = sm.exp_neg(optical_depth(q[Q_ST * CHUNK + j], length)) if with_transmittance else 1.0
        tr1 = sm.exp_neg(optical_depth(q[(Q_ST + 1) * CHUNK + j], length)) if with_transmittance else 1.0
        tr2 = sm.exp_neg(optical_depth(q[(Q_ST + 2) * CHUNK + j], length)) if with_transmittance else 1.0
        r[R_C * CHUNK + j] = q[Q_BETA * CHUNK + j] * r[R_C * CHUNK + j] * le0 * k * tr0
        r[(R_C + 1) * CHUNK + j] = q[(Q_BETA + 1) * CHUNK + j] * r[(R_C + 1) * CHUNK + j] * le1 * k * tr1
        r[(R_C + 2) * CHUNK + j] = q[(Q_BETA + 2) * CHUNK + j] * r[(R_C + 2) * CHUNK + j] * le2 * k * tr2


@kernel
def connect_all(n, nb, mis, with_transmittance):
    vertices(n, nb)
    connections(n, nb, mis, with_transmittance)
