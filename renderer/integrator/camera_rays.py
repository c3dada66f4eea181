"""The first stage of a batch: one camera ray per path, with its random key and the media
the camera sits in.

Sample indices are linear over a pass of a tile, so a batch may hold the tail of one sample
of every pixel and the head of the next: index k is the tile's pixel k % (width * rows),
sample sample_base + k // (width * rows), where the tile is rows first_row ..
first_row + rows - 1 of the rendered window (the whole frame without a Render Region) and
width its width. A path's random key and pixel stratification are those of its pixel in
the full frame, so a window or a tile renders the same pixels as the whole frame does.
"""

from ..camera import RASTER_WIDTH, RASTER_X0, RASTER_Y0, camera_ray
from ..kernels import kernel
from ..kernels.rng import path_key, uniform
from ..kernels.sobol import stratified
from ..kernels.vecmath import madd
from .dims import CAMERA_DIMS, LENS_DIM
from .paths import PATH_ACTIVE, PATH_DEAD, store3


@kernel
def start_paths(n, first, tile, ps, slots, cam, init_stack):
    """Camera rays for linear sample indices first .. first + n - 1 of a pass over a tile
    (records.Tile), into rows 0..n-1 (row i owns radiance slot i), each starting in the
    media of init_stack; slots.pixel gets the tile's pixel, slots.half the sample's half
    (kernels.rng.SAMPLE_HALVES: 1 for odd samples)."""
    width, rows, first_row = tile.width, tile.rows, tile.first_row
    seed, sample_base = tile.seed, tile.sample_base
    pixel_of_pid, half_of_pid = slots.pixel, slots.half
    raster = cam.raster
    npix = width * rows
    for i in range(n):
        k = first + i
        pixel = k % npix
        sample = sample_base + k // npix
        # The pixel's place in the full frame.
        px = int(raster[RASTER_X0]) + pixel % width
        py = int(raster[RASTER_Y0]) + first_row + pixel // width
        frame_pixel = py * int(raster[RASTER_WIDTH]) + px
        key = path_key(seed, frame_pixel, sample)
        # Stratified within the pixel over its half's samples: the randomised Sobol pair
        # of "dimensions" -1 and 0 (kernels.sobol.stratified), always, whatever
        # STRATIFIED_DIMS; dimensions 0 and 1 of the key stay reserved for it.
        u, v = stratified(key, -1), stratified(key, 0)
        o, d, near, length, ok = camera_ray(cam, px, py, u, v,
                                            uniform(key, LENS_DIM), uniform(key, LENS_DIM + 1))
        # Rays start at the near clip distance and end at the far one.
        store3(ps.o, i, madd(o, d, near))
        store3(ps.d, i, d)
        ps.tmax[i] = length
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
        # No ray (outside a fisheye's circle): a black sample, as in Cycles.
        ps.alive[i] = PATH_ACTIVE if ok else PATH_DEAD
        pixel_of_pid[i] = pixel
        half_of_pid[i] = sample & 1
