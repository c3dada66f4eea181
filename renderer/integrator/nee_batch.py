"""Homogeneous medium segments as SIMD loops across paths.

A path segment in a homogeneous medium does the same work in every path: the decoupled
next-event vertex (a point on the segment by equiangular/free-flight MIS, a point on a
triangle light by solid angle, the phase function and the MIS weight toward it: a chain of
about 12 square roots, 15 divisions, 3 exp, 2 atan2 and 2 sincos), then the path's own free
flight, Henyey-Greenstein direction and Russian roulette. Inside the per-path loop that
runs at the latency of the chain, with a mispredicted branch wherever a random number
decides (scatter or pass, which channel, which technique). So shade_media only records each
segment here (`record`: the ray, the medium's constants, the light's data, the random key
and the path's dimension counter), and `run` computes the batch in four loops without
branches, which LLVM vectorises (8 paths per AVX-512 instruction): `segments`, `vertices`,
`connections` and `advance`. The loops only move rows: each quantity's maths is the
branch-free form of its concept, kept beside the scalar form in media/homogeneous.py,
media/equiangular.py, media/nee.py, media/spectral.py and lights/sample.py. The random
numbers are computed inside the loops from the key and the dimension layout in dims.py, so
the scalar path in media_stage.py, which does the same maths, draws the same ones;
tests/test_nee_batch.py holds the two to 1e-11. media_stage.flush_nee_batch then writes
the shadow rays and the paths' new states.

Which segments qualify (`qualifies`; shade_media checks the rest): a homogeneous stack with
one entry (so the phase function is one Henyey-Greenstein lobe), a path that still takes a
next-event vertex (depth <= max_bounces, light sampling on) and a triangle light picked for
it. Everything else (grids, overlapping media, point, spot and distant lights, the last
segment of a path) keeps the scalar path.

Storage (NeeBatch), for CHUNK requests: q, Q_ROWS rows (the QUERY layout) of CHUNK
float64 in one flat array, row k of request j at q[k * CHUNK + j], so that each quantity is
contiguous (what SIMD loads want) and every pair of rows lies a compile-time constant
apart: LLVM then proves that the loops' loads and stores never overlap without run-time
checks (with one 2-D array per quantity set it needed hundreds of them and gave up). r:
R_ROWS rows (RESULT) the same way, the results (see shadow_ray and path_update). q_key
(CHUNK,) uint64 and q_dim (CHUNK,) int64: the path's random key and its dimension counter
at the segment's start; q_path (CHUNK,) int32: the path row.
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel
from renderer.kernels import simdmath as sm
from renderer.kernels.rng import hashed_uniform
from renderer.kernels.vecmath import dot
from renderer.layout import Layout
from renderer.lights.sample import connect_triangle_simd, triangle_point
from renderer.lights.table import TRIANGLE
from renderer.media.homogeneous import beer_simd, free_flight_segment_simd, segment_simd
from renderer.media.nee import nee_vertex_simd
from renderer.media.spectral import channel_probabilities_simd
from renderer.media.stack import EMPTY
from renderer.phase.hg import hg_direction, hg_eval

from .dims import SEG_CONNECT, SEG_FREE_FLIGHT, SEG_LIGHT, SEG_PHASE, SEG_RR, SEG_VERTEX

# A request's rows: the segment, the medium's constants, the choices made for it and the
# triangle light's data (copied in, see record). Stage 0 (segments) fills tr, miss and p.
QUERY = Layout("nee_batch request", [
    ("o", 3), ("d", 3), ("tmax", 1), ("beta", 3),
    ("sigma_t", 3), ("sigma_s", 3), ("tr", 3), ("miss", 3), ("p", 3),  # tr, miss: T(tmax), 1 - T(tmax)
    ("g", 1), ("equiangular", 1), ("roulette", 1),
    ("p0", 3), ("edge_a", 3), ("edge_b", 3), ("area", 1), ("le_front", 3), ("le_back", 3), ("pmf", 1),
])
Q_O = QUERY.offset("o")
Q_D = QUERY.offset("d")
Q_TMAX = QUERY.offset("tmax")
Q_BETA = QUERY.offset("beta")
Q_ST = QUERY.offset("sigma_t")
Q_SS = QUERY.offset("sigma_s")
Q_TR = QUERY.offset("tr")
Q_MISS = QUERY.offset("miss")
Q_P = QUERY.offset("p")
Q_G = QUERY.offset("g")
Q_EQUIANGULAR = QUERY.offset("equiangular")
Q_RR = QUERY.offset("roulette")
Q_P0 = QUERY.offset("p0")
Q_EA = QUERY.offset("edge_a")
Q_EB = QUERY.offset("edge_b")
Q_AREA = QUERY.offset("area")
Q_LE_FRONT = QUERY.offset("le_front")
Q_LE_BACK = QUERY.offset("le_back")
Q_PMF = QUERY.offset("pmf")
Q_ROWS = QUERY.size
# A request's results: its shadow ray (x, wi, length, contribution c; the light point lp on
# the way), then its path's fate (see shadow_ray and path_update).
RESULT = Layout("nee_batch result", [
    ("x", 3), ("wi", 3), ("length", 1), ("c", 3), ("lp", 3),
    ("y", 3), ("dir", 3), ("beta", 3), ("pdf", 1), ("state", 1), ("dim", 1),
])
R_X = RESULT.offset("x")
R_WI = RESULT.offset("wi")
R_LENGTH = RESULT.offset("length")
R_C = RESULT.offset("c")
R_LP = RESULT.offset("lp")
R_Y = RESULT.offset("y")
R_DIR = RESULT.offset("dir")
R_BETA = RESULT.offset("beta")
R_PDF = RESULT.offset("pdf")
R_STATE = RESULT.offset("state")
R_DIM = RESULT.offset("dim")
R_ROWS = RESULT.size
# R_STATE: what became of the path on its segment.
DEAD, PASSED, SCATTERED = 0.0, 1.0, 2.0
# Requests per SIMD pass: 1032 requests' rows (Q_ROWS + R_ROWS of them) take 0.6 MB, which
# stays in a core's 1 MB L2 cache; with 4104 (2.3 MB) two processes on this machine's two
# cores scaled 1.67x instead of 1.90x (fog box, 128x128; one process: 0.85 vs 0.87 M
# samples/s). Not a power of two: with rows exactly a power of two apart, the stores of one
# request all fell into one cache set and recording took 200 ns a request instead of a few
# (measured); one extra cache line per row spreads them over as many sets as there are rows.
CHUNK = 1024 + 8


class NeeBatch:
    """Request and result storage for CHUNK homogeneous segments (see the module)."""

    def __init__(self):
        self.q = np.zeros(Q_ROWS * CHUNK, np.float64)
        self.q_key = np.zeros(CHUNK, np.uint64)
        self.q_dim = np.zeros(CHUNK, np.int64)
        self.q_path = np.zeros(CHUNK, np.int32)
        self.r = np.zeros(R_ROWS * CHUNK, np.float64)

    def arrays(self):
        return self.q, self.q_key, self.q_dim, self.q_path, self.r


@inline_kernel
def _row3(a, row, j):
    return (a[row * CHUNK + j], a[(row + 1) * CHUNK + j], a[(row + 2) * CHUNK + j])


@inline_kernel
def _put3(a, row, j, v):
    a[row * CHUNK + j] = v[0]
    a[(row + 1) * CHUNK + j] = v[1]
    a[(row + 2) * CHUNK + j] = v[2]


@inline_kernel
def shadow_ray(r, j):
    """(x, wi, length, contribution) of request j's next-event shadow ray (contribution 0:
    none)."""
    return _row3(r, R_X, j), _row3(r, R_WI, j), r[R_LENGTH * CHUNK + j], _row3(r, R_C, j)


@inline_kernel
def path_update(r, j):
    """(state, dim, beta, y, wi, pdf) of request j's path after its segment: state DEAD,
    PASSED (reached the segment's end with throughput beta) or SCATTERED (at y, into wi with
    phase pdf `pdf`, throughput beta); dim: its next random dimension."""
    return (r[R_STATE * CHUNK + j], int(r[R_DIM * CHUNK + j]), _row3(r, R_BETA, j), _row3(r, R_Y, j),
            _row3(r, R_DIR, j), r[R_PDF * CHUNK + j])


@inline_kernel
def qualifies(lt, light, stack):
    return lt.kind[light] == TRIANGLE and stack[1] == EMPTY


@inline_kernel
def record(nb, j, path, key, dim, lt, light, o, d, tmax, beta, sigma_s, sigma_t, g, use_equiangular,
           roulette):
    """Store request j: path row `path` with random key `key` and counter `dim` at the start
    of its segment (dims.SEG_*), which picked `light`; the stack's sigma_s and sigma_t;
    roulette: whether Russian roulette applies after a scattering event here."""
    q, q_key, q_dim, q_path, _ = nb
    _put3(q, Q_O, j, o)
    _put3(q, Q_D, j, d)
    q[Q_TMAX * CHUNK + j] = tmax
    _put3(q, Q_BETA, j, beta)
    _put3(q, Q_SS, j, sigma_s)
    _put3(q, Q_ST, j, sigma_t)
    q[Q_G * CHUNK + j] = g
    q[Q_EQUIANGULAR * CHUNK + j] = 1.0 if use_equiangular else 0.0
    q[Q_RR * CHUNK + j] = 1.0 if roulette else 0.0
    q_key[j] = key
    q_dim[j] = dim
    q_path[j] = path
    # The light's data too: the SIMD loop then reads only rows at j (a gather by light index
    # would keep LLVM from bounding the loop's memory accesses, and so from vectorising it).
    pos, vec_a, vec_b, param, pmf = lt.pos, lt.vec_a, lt.vec_b, lt.param, lt.pmf
    color, color_b = lt.color, lt.color_b
    for k in range(3):
        q[(Q_P0 + k) * CHUNK + j] = pos[light, k]
        q[(Q_EA + k) * CHUNK + j] = vec_a[light, k]
        q[(Q_EB + k) * CHUNK + j] = vec_b[light, k]
        q[(Q_LE_FRONT + k) * CHUNK + j] = color[light, k]
        q[(Q_LE_BACK + k) * CHUNK + j] = color_b[light, k]
    q[Q_AREA * CHUNK + j] = param[light, 0]
    q[Q_PMF * CHUNK + j] = pmf[light]


@inline_kernel
def _u(q_key, q_dim, j, offset):
    """The request's uniform number at dimension (its segment's start + offset)."""
    return hashed_uniform(q_key[j], q_dim[j] + offset)


# The four loops below are the batch's driver: each reads a request's rows, calls the
# branch-free form of the concept it computes, which lives beside the concept's scalar form
# (homogeneous.segment_simd, spectral.channel_probabilities_simd, sample.triangle_point,
# nee.nee_vertex_simd, sample.connect_triangle_simd, homogeneous.free_flight_segment_simd,
# hg.hg_direction), and writes the results' rows. They hold no branch and no call LLVM
# cannot inline, so it vectorises them (tests/test_nee_batch.py checks the IR).


@kernel
def segments(n, nb, uniform_channel):
    """Stage 0: the segment constants of homogeneous.segment (T(tmax) and 1 - T(tmax) per
    channel) and the channel probabilities of spectral MIS."""
    q, _, _, _, _ = nb
    for j in range(n):
        tr, miss = segment_simd(_row3(q, Q_ST, j), q[Q_TMAX * CHUNK + j])
        _put3(q, Q_TR, j, tr)
        _put3(q, Q_MISS, j, miss)
        _put3(q, Q_P, j, channel_probabilities_simd(_row3(q, Q_BETA, j), uniform_channel))


@kernel
def vertices(n, nb):
    """Stage 1: the light point and the next-event vertex x of requests 0..n-1, and the
    vertex's weight (0 when none)."""
    q, q_key, q_dim, _, r = nb
    for j in range(n):
        lp = triangle_point(_row3(q, Q_P0, j), _row3(q, Q_EA, j), _row3(q, Q_EB, j),
                            _u(q_key, q_dim, j, SEG_LIGHT + 1), _u(q_key, q_dim, j, SEG_LIGHT + 2))
        o = _row3(q, Q_O, j)
        d = _row3(q, Q_D, j)
        t, wn, valid = nee_vertex_simd(o, d, q[Q_TMAX * CHUNK + j], _row3(q, Q_SS, j), _row3(q, Q_ST, j),
                                       _row3(q, Q_MISS, j), _row3(q, Q_P, j), lp,
                                       q[Q_EQUIANGULAR * CHUNK + j] != 0.0, _u(q_key, q_dim, j, SEG_VERTEX),
                                       _u(q_key, q_dim, j, SEG_VERTEX + 1),
                                       _u(q_key, q_dim, j, SEG_VERTEX + 2))
        _put3(r, R_LP, j, lp)
        _put3(r, R_X, j, (o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]))
        _put3(r, R_C, j, (wn[0] if valid else 0.0, wn[1] if valid else 0.0, wn[2] if valid else 0.0))


@kernel
def connections(n, nb, mis, with_transmittance):
    """Stage 2: the light connection of each vertex; R_C becomes the shadow ray's
    contribution. mis False = light sampling only (weight 1). with_transmittance: include the
    shadow ray's transmittance exp(-sigma_t length) (valid when no interface can lie on a
    shadow ray, so its medium is the request's all along; the integrator then leaves the
    ray out of shadow_media)."""
    q, q_key, q_dim, _, r = nb
    for j in range(n):
        d = _row3(q, Q_D, j)
        x = _row3(r, R_X, j)
        p0 = _row3(q, Q_P0, j)
        ea, eb = _row3(q, Q_EA, j), _row3(q, Q_EB, j)
        p1 = (p0[0] + ea[0], p0[1] + ea[1], p0[2] + ea[2])
        p2 = (p0[0] + eb[0], p0[1] + eb[1], p0[2] + eb[2])
        wi, dist, back, pdf = connect_triangle_simd(p0, p1, p2, _row3(r, R_LP, j), q[Q_AREA * CHUNK + j], x,
                                                    _u(q_key, q_dim, j, SEG_CONNECT),
                                                    _u(q_key, q_dim, j, SEG_CONNECT + 1))
        # A blend with weights 0 and 1 (exact), not `back ? row_b : row_f`: LLVM turns a
        # select of two loads into a load from a selected address, which it cannot vectorise.
        f = 1.0 if back else 0.0
        le0 = q[Q_LE_FRONT * CHUNK + j] * (1.0 - f) + q[Q_LE_BACK * CHUNK + j] * f
        le1 = q[(Q_LE_FRONT + 1) * CHUNK + j] * (1.0 - f) + q[(Q_LE_BACK + 1) * CHUNK + j] * f
        le2 = q[(Q_LE_FRONT + 2) * CHUNK + j] * (1.0 - f) + q[(Q_LE_BACK + 2) * CHUNK + j] * f
        p_light = pdf * q[Q_PMF * CHUNK + j]
        ph = hg_eval(q[Q_G * CHUNK + j], dot(d, wi))
        # The power heuristic of paths.light_sample_weight, as selects.
        a2 = p_light * p_light
        b2 = ph * ph
        w = (a2 / (a2 + b2) if a2 + b2 > 0.0 else 0.0) if mis else 1.0
        k = w / p_light * ph if p_light > 0.0 else 0.0
        _put3(r, R_WI, j, wi)
        length = dist * 0.9999
        r[R_LENGTH * CHUNK + j] = length
        tr0, tr1, tr2 = beer_simd(_row3(q, Q_ST, j), length) if with_transmittance else (1.0, 1.0, 1.0)
        r[R_C * CHUNK + j] = q[Q_BETA * CHUNK + j] * r[R_C * CHUNK + j] * le0 * k * tr0
        r[(R_C + 1) * CHUNK + j] = q[(Q_BETA + 1) * CHUNK + j] * r[(R_C + 1) * CHUNK + j] * le1 * k * tr1
        r[(R_C + 2) * CHUNK + j] = q[(Q_BETA + 2) * CHUNK + j] * r[(R_C + 2) * CHUNK + j] * le2 * k * tr2


@kernel
def advance(n, nb):
    """Stage 3: the path's own free flight on its segment, and where it scatters the
    Henyey-Greenstein direction and Russian roulette (media_stage.shade_media's scalar
    path)."""
    q, q_key, q_dim, _, r = nb
    for j in range(n):
        t, hit, w = free_flight_segment_simd(_row3(q, Q_SS, j), _row3(q, Q_ST, j), _row3(q, Q_TR, j),
                                             q[Q_TMAX * CHUNK + j], _row3(q, Q_P, j),
                                             _u(q_key, q_dim, j, SEG_FREE_FLIGHT),
                                             _u(q_key, q_dim, j, SEG_FREE_FLIGHT + 1))
        b0, b1, b2 = _row3(q, Q_BETA, j)
        b0, b1, b2 = b0 * w[0], b1 * w[1], b2 * w[2]
        alive = max(b0, max(b1, b2)) > 0.0
        d = _row3(q, Q_D, j)
        g = q[Q_G * CHUNK + j]
        sin_phi, cos_phi = sm.sincos(2.0 * math.pi * _u(q_key, q_dim, j, SEG_PHASE + 2))
        wi, pdf = hg_direction(g, d, _u(q_key, q_dim, j, SEG_PHASE + 1), sin_phi, cos_phi)
        # Russian roulette on the scattered path (one lobe: the phase weight is 1), as
        # paths.russian_roulette with selects.
        roulette = q[Q_RR * CHUNK + j] != 0.0
        keep = min(1.0, max(b0, max(b1, b2)))
        survives = not roulette or (keep > 0.0 and _u(q_key, q_dim, j, SEG_RR) < keep)
        inv_keep = 1.0 / keep if roulette and hit and keep > 0.0 else 1.0
        state = (SCATTERED if survives else DEAD) if hit else PASSED
        r[R_STATE * CHUNK + j] = state if alive else DEAD
        r[R_DIM * CHUNK + j] = q_dim[j] + (SEG_PHASE if not hit else (SEG_RR + 1 if roulette else SEG_RR))
        r[R_BETA * CHUNK + j] = b0 * inv_keep
        r[(R_BETA + 1) * CHUNK + j] = b1 * inv_keep
        r[(R_BETA + 2) * CHUNK + j] = b2 * inv_keep
        r[R_Y * CHUNK + j] = d[0] * t + q[Q_O * CHUNK + j]
        r[(R_Y + 1) * CHUNK + j] = d[1] * t + q[(Q_O + 1) * CHUNK + j]
        r[(R_Y + 2) * CHUNK + j] = d[2] * t + q[(Q_O + 2) * CHUNK + j]
        _put3(r, R_DIR, j, wi)
        r[R_PDF * CHUNK + j] = pdf


@kernel
def run(n, nb, mis, with_transmittance, uniform_channel):
    """All the stages for requests 0..n-1."""
    segments(n, nb, uniform_channel)
    vertices(n, nb)
    connections(n, nb, mis, with_transmittance)
    advance(n, nb)
