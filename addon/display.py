"""Copying Haze's images into Blender's render result.

Haze images are (H, W, 3) linear RGB with row 0 at the top; Blender wants a flat float32
RGBA array with row 0 at the bottom. The RGBA buffer is allocated once per render (alpha
stays 1 unless Film > Transparent gives one) and each push only copies the colour channels
(and alpha when there is one), so showing a pass costs one copy.

With a Render Region, Blender's result is the region's size whether or not it crops: the
engine writes the region's pixels at (0, 0) and Blender places them in the frame (measured
with bpy 5.0: begin_result clamps to the region's size).
"""

from __future__ import annotations

import numpy as np


class ResultBuffer:
    """An RGBA float32 image in Blender's pixel order, reused for every push."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.rgba = np.zeros((height, width, 4), dtype=np.float32)
        self.rgba[:, :, 3] = 1.0

    def fill(self, image: np.ndarray, alpha: np.ndarray | None = None) -> None:
        """Take a Haze image (row 0 = top), and its (H, W) alpha if it has one, and flip
        them to Blender's bottom-up order."""
        if alpha is not None:
            np.copyto(self.rgba[:, :, 3], alpha[::-1], casting="unsafe")
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(
                f"the renderer returned a {image.shape[1]}x{image.shape[0]} image for a "
                f"{self.width}x{self.height} render"
            )
        # numpy, not a compiled loop: a full-HD push takes about 10 ms, far less than Blender's
        # foreach_set after it, and the add-on then imports and compiles nothing of its own
        # before the first image.
        flipped = image[::-1]
        for channel in range(3):  # one channel at a time: about 2.5x faster than all three at once
            np.copyto(self.rgba[:, :, channel], flipped[:, :, channel], casting="unsafe")

    def flat(self) -> np.ndarray:
        return self.rgba.reshape(-1)


def render_region(render, width: int, height: int) -> tuple[int, int, int, int] | None:
    """Blender's Render Region as (x, y, width, height) pixels of a width x height frame,
    row 0 at the top, or None for the whole frame.

    Blender's border is in [0, 1] from the bottom left; the window's pixel edges are the
    border times the frame size, truncated as Blender does (render_init_from_main)."""
    if render is None or not getattr(render, "use_border", False):
        return None
    x0 = min(max(int(render.border_min_x * width), 0), width)
    x1 = min(max(int(render.border_max_x * width), 0), width)
    y0 = min(max(int(render.border_min_y * height), 0), height)
    y1 = min(max(int(render.border_max_y * height), 0), height)
    if x1 - x0 < 1 or y1 - y0 < 1 or (x1 - x0, y1 - y0) == (width, height):
        return None
    return (x0, height - y1, x1 - x0, y1 - y0)


def write_result(result, buffer: ResultBuffer) -> None:
    """Store the buffer in the render result's Combined pass."""
    result.layers[0].passes["Combined"].rect.foreach_set(buffer.flat())


def write_pass(result, name: str, image: np.ndarray, alpha: np.ndarray | None = None) -> bool:
    """Store an (H, W, C) Haze image (row 0 = top) in the result's pass `name`, flipped to
    Blender's bottom-up order, with `alpha` as a fourth channel when the pass has one.
    Returns False when the result has no such pass (Blender made it from the passes the
    engine registered for the view layer)."""
    render_pass = result.layers[0].passes.get(name)
    if render_pass is None:
        return False
    channels = int(render_pass.channels)
    h, w = image.shape[:2]
    out = np.ones((h, w, channels), np.float32)
    out[:, :, :min(channels, image.shape[2])] = image[:, :, :channels]
    if alpha is not None and channels == 4:
        out[:, :, 3] = alpha
    render_pass.rect.foreach_set(out[::-1].reshape(-1))
    return True
