"""The first stage of a batch: one camera ray per path, with its random key and the media
the camera sits in.

Sample indices are linear over a pass, so a batch may hold the tail of one sample of every
pixel and the head of the next: index k is pixel k % (width * height), sample
sample_base + k // (width * height).
"""

from ..camera import camera_ray
from ..kernels import kernel
from ..kernels.rng import path_key, uniform
from ..kernels.vecmath import madd
from .dims import CAMERA_DIMS
from .paths import PATH_ACTIVE, store3


@kernel
def start_paths(ps, pixel_of_pid, cam, width, height, seed, first, n, sample_base, init_stack):
    """Camera rays for linear sample indices first .. first + n - 1 of a pass, into rows
    0..n-1 (row i owns radiance slot i)."""
    to_world_m, tan_half, shift, clip = cam
    npix = width * height
    for i in range(n):
        k = first + i
        pixel = k % npix
        sample = sample_base + k // npix
        key = path_key(seed, pixel, sample)
        o, d = camera_ray(to_world_m, tan_half, shift, pixel % width, pixel // width, width, height,
                          uniform(key, 0), uniform(key, 1))
        # Rays start at the near clip distance and end at the far one.
        store3(ps.o, i, madd(o, d, clip[0]))
        store3(ps.d, i, d)
        ps.tmax[i] = clip[1] - clip[0]
        ps.gap[i] = 0.0
        store3(ps.beta, i, (1.0, 1.0, 1.0))
        ps.pid[i] = i
        ps.key[i] = key
        ps.dim[i] = CAMERA_DIMS
        ps.depth[i] = 0
        ps.crossings[i] = 0
        ps.mis_pdf[i] = 0.0
        store3(ps.mis_o, i, o)
        for j in range(init_stack.shape[0]):
            ps.stack[i, j] = init_stack[j]
        ps.alive[i] = PATH_ACTIVE
        pixel_of_pid[i] = pixel
