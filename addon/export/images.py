"""Blender images to the scene's ImageTextures, once per render, read from Blender's own
pixels (file, packed and generated images alike) without changing the image or its path.

Cycles shades in scene-linear Rec. 709. Byte images hold their colour space's encoded
values in `pixels`; float images hold scene-linear values already (Blender converts them
on load). A byte sRGB image keeps its encoded values and is decoded after interpolation,
as Cycles does with 8-bit sRGB images; Non-Color, Linear Rec.709 (and Linear) are used as
they are. Other colour spaces are decoded as sRGB (byte) or used as they are (float),
with a warning.
"""

from __future__ import annotations

import numpy as np

from renderer.shading.program import ImageTexture

from .messages import Messages, node_subject

RAW_SPACES = {"Non-Color", "Linear Rec.709", "Linear", "Linear CIE-XYZ E", "Raw"}


def read_pixels(image) -> np.ndarray:
    """(H, W, 4) float32 RGBA of `image`, row 0 at the bottom, from foreach_get."""
    width, height = (int(s) for s in image.size)
    channels = int(image.channels)
    buffer = np.empty(width * height * channels, np.float32)
    image.pixels.foreach_get(buffer)
    pixels = buffer.reshape(height, width, channels)
    if channels == 4:
        return pixels
    out = np.ones((height, width, 4), np.float32)
    if channels >= 3:
        out[..., :3] = pixels[..., :3]
    else:
        out[..., :3] = pixels[..., :1]
    return out


class ImageLibrary:
    """Each image converted once per render; its name in the scene is its full name."""

    def __init__(self, messages: Messages) -> None:
        self.messages = messages
        self.textures: dict[str, ImageTexture] = {}

    def add(self, image, owner: str) -> str | None:
        name = image.name_full
        if name in self.textures:
            return name
        subject = node_subject(owner, f"Image '{name}'")
        width, height = (int(s) for s in image.size)
        if width == 0 or height == 0 or not image.has_data and not self._load(image):
            self.messages.warn(subject, "has no pixels (missing file?); rendered as Cycles' magenta")
            pixels = np.array([[[1.0, 0.0, 1.0, 1.0]]], np.float32)
        else:
            pixels = self._linear(read_pixels(image), image, subject)
        srgb = not image.is_float and image.colorspace_settings.name not in RAW_SPACES
        self.textures[name] = ImageTexture(name, np.ascontiguousarray(pixels), srgb)
        return name

    @staticmethod
    def _load(image) -> bool:
        try:
            image.pixels[0]  # reading a pixel loads the image buffer
        except (IndexError, RuntimeError):
            return False
        return bool(image.has_data)

    def _linear(self, pixels: np.ndarray, image, subject: str) -> np.ndarray:
        space = image.colorspace_settings.name
        if image.alpha_mode == "NONE":
            pixels[..., 3] = 1.0
        if image.is_float or space in RAW_SPACES:
            if image.is_float and space not in RAW_SPACES and space != "sRGB":
                self.messages.warn(subject, f"colour space {space} is used as scene linear")
            return pixels
        if space != "sRGB":
            self.messages.warn(subject, f"colour space {space} is decoded as sRGB")
        return pixels  # decoded after interpolation (ImageTexture.srgb)

    def list(self) -> list[ImageTexture]:
        return list(self.textures.values())
