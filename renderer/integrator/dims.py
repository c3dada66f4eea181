"""How a path spends its random dimensions (uniform(key, dim), renderer.kernels.rng).

A path's dimension counter only grows, and every event takes a fixed block of it whether
or not it uses all of it, so that the scalar kernels and the SIMD batches (nee_batch), which
do the same work in a different order, draw the same random numbers.
"""

CAMERA_DIMS = 4  # the sample's position in its pixel, then on the lens; the path's own events follow
# (the position in the pixel comes from kernels.sobol, stratified over its half of the
# pixel's samples (kernels.rng.SAMPLE_HALVES); its two dimensions stay reserved)
LENS_DIM = 2  # the two of the point on the lens (spent by every camera, used by thin lenses)
SHADOW_DIMS = 64  # a shadow ray's own tracking through media
NEE_DIMS = 5  # a surface's light sample: the light pick, the point on it, the direction (environment)
BSDF_DIMS = 4  # a surface's BSDF sample: the lobe pick and three for the direction
MEDIUM_NEE_DIMS = 2 + SHADOW_DIMS  # a medium vertex's light connection and its shadow ray

# A homogeneous medium segment with a next-event vertex, as offsets from the path's counter
# at the start of the segment (shade_media spends them in this order):
SEG_LIGHT = 0  # the light pick, then the two of the point on it
SEG_VERTEX = 3  # the vertex: technique, channel, distance
SEG_CONNECT = 6  # the light connection's two (the MEDIUM_NEE_DIMS block starts here)
SEG_SHADOW = SEG_CONNECT + 2  # the shadow ray's
SEG_FREE_FLIGHT = SEG_CONNECT + MEDIUM_NEE_DIMS  # the path's own channel and distance
SEG_PHASE = SEG_FREE_FLIGHT + 2  # the lobe pick, then the two of the direction
SEG_RR = SEG_PHASE + 3  # Russian roulette (when it applies)
