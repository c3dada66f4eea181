"""Copying Haze's images into Blender's render result.

Haze images are (H, W, 3) linear RGB with row 0 at the top; Blender wants a flat float32
RGBA array with row 0 at the bottom. The RGBA buffer is allocated once per render (alpha
stays 1) and each push only copies the colour channels, so showing a pass costs one copy.
"""

from __future__ import annotations

import numpy as np

_compiled_copy = None


def compiled_copy():
    """The numba copy kernel, or None without numba (then numpy does the copy)."""
    global _compiled_copy
    if _compiled_copy is None:
        try:
            from .flipcopy import flip_rgb_into_rgba
        except ImportError:
            _compiled_copy = False
        else:
            _compiled_copy = flip_rgb_into_rgba
    return _compiled_copy or None


class ResultBuffer:
    """An RGBA float32 image in Blender's pixel order, reused for every push."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.rgba = np.zeros((height, width, 4), dtype=np.float32)
        self.rgba[:, :, 3] = 1.0

    def fill(self, image: np.ndarray) -> None:
        """Take a Haze image (row 0 = top) and flip it to Blender's bottom-up order."""
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(
                f"the renderer returned a {image.shape[1]}x{image.shape[0]} image for a "
                f"{self.width}x{self.height} render"
            )
        kernel = compiled_copy()
        if kernel is not None and image.dtype == np.float32:
            kernel(self.rgba, image)
            return
        flipped = image[::-1]
        for channel in range(3):  # one channel at a time: about 1.5x faster than all three at once
            np.copyto(self.rgba[:, :, channel], flipped[:, :, channel], casting="unsafe")

    def flat(self) -> np.ndarray:
        return self.rgba.reshape(-1)


def write_result(result, buffer: ResultBuffer) -> None:
    """Store the buffer in the render result's Combined pass."""
    result.layers[0].passes["Combined"].rect.foreach_set(buffer.flat())
