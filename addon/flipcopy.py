"""Compiled copy of a Haze image into Blender's RGBA buffer (numba, imported lazily).

Interleaving RGB into RGBA while flipping rows is a strided copy that numpy does at about
a third of memory speed; this loop is 2-4x faster, which keeps pushing a full-HD image to
the display well under 2 % of a render. Numba comes with the renderer; display.py falls
back to numpy when it is missing.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def flip_rgb_into_rgba(rgba, image):
    """rgba[y, x, :3] = image[height - 1 - y, x, :3]; alpha is left as it is."""
    height, width = image.shape[0], image.shape[1]
    for y in range(height):
        source = image[height - 1 - y]
        target = rgba[y]
        for x in range(width):
            target[x, 0] = source[x, 0]
            target[x, 1] = source[x, 1]
            target[x, 2] = source[x, 2]
