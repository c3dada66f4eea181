"""What every stage of the wavefront does to a path or a shadow ray: read and write its
rows, weigh its samples by MIS, hand a shadow ray on, play Russian roulette.

Path states (Paths.alive), as the stages hand a path on within one bounce:
  PATH_DEAD       finished; compaction drops it
  PATH_ACTIVE     its ray's closest hit (or escape) is the next thing to shade
  PATH_SCATTERED  it scattered in a medium before that hit and already holds its next ray,
                  so the surface stage leaves it alone this bounce
Compaction turns every live path back to PATH_ACTIVE.
"""

import numpy as np

from ..kernels import inline_kernel
from ..kernels.rng import uniform
from ..kernels.vecmath import dot, madd, max3, scale
from ..layout import Layout
from .config import SAMPLING_BSDF, SAMPLING_NEE

PATH_DEAD = 0
PATH_ACTIVE = 1
PATH_SCATTERED = 2

RAY_FAR = 1e30  # "no hit" length of a ray, and the distance of lights at infinity

# The batch's radiance array L, one row per path slot (pid), float64 columns. Three widths,
# each a prefix of RADIANCE: L_COLUMNS without render passes (RGB, then the path's
# transparency: Film > Transparent's throughput with which it reached the world directly,
# which splat turns into alpha = 1 - transparency); L_COLUMNS_AOV with passes requested
# (CFG_AOVS): the AOV_COUNT columns the film sums (renderer.passes turns them into Blender's
# passes), then per-path scratch the surface stage keeps between bounces (not summed);
# L_COLUMNS_LIGHT_AOV with the light and colour passes too (CFG_LIGHT_AOVS): LIGHT_AOV_COUNT
# more summed columns, which the film sums after the AOV_COUNT, and one more scratch.
RADIANCE = Layout("radiance", [
    ("rgb", 3),
    ("transparency", 1),
    # passes (summed)
    ("hit0", 1),  # 1 when the pixel's sample 0 hit a surface: Depth and Position are then valid
    ("position", 3),  # sample 0's first non-transparent hit, world space (Cycles overwrites on sample 0)
    ("normal", 3),  # shading normal (facing the ray) of the first non-transparent hit, every sample
    ("denoise_albedo", 3),  # feature throughput x diffuse-like albedo (or emission seen)
    ("denoise_normal", 3),  # world space (renderer.passes turns it into camera space)
    ("denoise_normal_volume", 1),  # weight of Cycles' volume denoising normal, (0, 0, -1) in camera space
    ("mist", 1),  # (1 - mist) x mean throughput at the data passes' hit; Mist = 1 - its mean
    # passes' scratch (not summed)
    ("sample0", 1),  # 1 for sample 0 of its pixel (set by the wavefront)
    ("data_done", 1),  # the data passes (position, normal) were written
    ("feature_done", 1),  # the denoising features were written
    ("feature_throughput", 3),  # product of the specular albedos passed
    ("feature_depth", 1),  # the path's depth after the last surface the features looked at
    # light and colour passes (summed)
    ("emission", 3),  # emission the camera path found before scattering (Cycles' Emit)
    ("diffuse_color", 3),  # throughput x diffuse albedo at each hit before scattering
    ("glossy_color", 3),  # throughput x glossy albedo at each hit before scattering
    ("volume_direct", 3),  # light reaching the camera through a first scatter in a volume: its
    ("volume_indirect", 3),  # next-event rays and the emission right after it; the rest of it
    ("transmission_color", 3),  # throughput x transmission albedo at each hit before scattering
    # light passes' scratch
    ("first_kind", 1),  # how the path first scattered (KIND_*), set at that event
])
ALPHA = RADIANCE.offset("transparency")
L_COLUMNS = RADIANCE.offset("hit0")
AOV_FIRST = AOV_HIT0 = RADIANCE.offset("hit0")
AOV_POSITION = RADIANCE.offset("position")
AOV_NORMAL = RADIANCE.offset("normal")
AOV_DALBEDO = RADIANCE.offset("denoise_albedo")
AOV_DNORMAL = RADIANCE.offset("denoise_normal")
AOV_DNORMAL_VOLUME = RADIANCE.offset("denoise_normal_volume")
AOV_MIST = RADIANCE.offset("mist")
AOV_COUNT = RADIANCE.offset("sample0") - AOV_FIRST
AOV_SAMPLE0 = RADIANCE.offset("sample0")
AOV_DATA_DONE = RADIANCE.offset("data_done")
AOV_FEAT_DONE = RADIANCE.offset("feature_done")
AOV_FEAT_T = RADIANCE.offset("feature_throughput")
AOV_FEAT_DEPTH = RADIANCE.offset("feature_depth")
L_COLUMNS_AOV = LIGHT_AOV_FIRST = RADIANCE.offset("emission")
AOV_EMISSION = RADIANCE.offset("emission")
AOV_DIFFUSE_COLOR = RADIANCE.offset("diffuse_color")
AOV_GLOSSY_COLOR = RADIANCE.offset("glossy_color")
AOV_VOLUME_DIRECT = RADIANCE.offset("volume_direct")
AOV_VOLUME_INDIRECT = RADIANCE.offset("volume_indirect")
AOV_TRANSMISSION_COLOR = RADIANCE.offset("transmission_color")
LIGHT_AOV_COUNT = RADIANCE.offset("first_kind") - LIGHT_AOV_FIRST
AOV_FIRST_KIND = RADIANCE.offset("first_kind")
L_COLUMNS_LIGHT_AOV = RADIANCE.size
# Cycles' render pass categories (PATH_RAY_SURFACE_PASS / VOLUME_PASS): what a path's first
# scattering event was. Only the volume's passes are written, so surfaces leave KIND_NONE.
KIND_NONE = 0.0
KIND_VOLUME = 2.0
NO_PASS = -1  # a shadow ray's pass column when its light goes to no light pass


@inline_kernel
def load3(a, i):
    """Row i of an (n, 3) array as a float64 3-tuple (float() would keep float32 in numba)."""
    return (np.float64(a[i, 0]), np.float64(a[i, 1]), np.float64(a[i, 2]))


@inline_kernel
def store3(a, i, v):
    a[i, 0] = v[0]
    a[i, 1] = v[1]
    a[i, 2] = v[2]


@inline_kernel
def add_radiance(L, pid, beta, le):
    """L[pid] += beta * le, per channel."""
    L[pid, 0] += beta[0] * le[0]
    L[pid, 1] += beta[1] * le[1]
    L[pid, 2] += beta[2] * le[2]


@inline_kernel
def add_weighted_radiance(L, pid, beta, le, w):
    """L[pid] += beta * le * w, per channel."""
    L[pid, 0] += beta[0] * le[0] * w
    L[pid, 1] += beta[1] * le[1] * w
    L[pid, 2] += beta[2] * le[2] * w


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
def light_sample_weight(pdf_light, pdf_scatter, is_delta, sampling):
    """MIS weight of a light sample; pdf_light already includes the selection probability."""
    if is_delta or sampling == SAMPLING_NEE:
        return 1.0
    return power_heuristic(pdf_light, pdf_scatter)


@inline_kernel
def hit_weight(mis_pdf, pdf_light, sampling):
    """MIS weight of emission found by BSDF/phase sampling (mis_pdf 0 = camera or delta)."""
    if mis_pdf <= 0.0 or sampling == SAMPLING_BSDF:
        return 1.0
    if sampling == SAMPLING_NEE:
        return 0.0
    return power_heuristic(mis_pdf, pdf_light)


@inline_kernel
def emit_shadow(sh, s, x, wi, dist, contrib, pid, key, dim, stack, gap, col):
    """Write shadow ray s: from x along wi for dist, carrying contrib to path slot pid if it
    arrives; it starts in the media of `stack` and tracks through them from dimension dim.
    col: the light pass column of L it also adds to (NO_PASS: none)."""
    store3(sh.o, s, x)
    store3(sh.d, s, wi)
    sh.tmax[s] = dist
    sh.gap[s] = gap
    store3(sh.contrib, s, contrib)
    sh.pid[s] = pid
    sh.key[s] = key
    sh.dim[s] = dim
    sh.col[s] = col
    for j in range(stack.shape[0]):
        sh.stack[s, j] = stack[j]
    sh.alive[s] = 1


@inline_kernel
def russian_roulette(ps, i, key, dim, rr_depth):
    """Survive with probability max(throughput) (capped at 1) after rr_depth bounces.
    Returns (survived, next dimension)."""
    if ps.depth[i] < rr_depth:
        return True, dim
    beta = load3(ps.beta, i)
    q = min(1.0, max3(beta))
    u = uniform(key, dim)
    dim += 1
    if q <= 0.0 or u >= q:
        return False, dim
    store3(ps.beta, i, scale(beta, 1.0 / q))
    return True, dim
