"""A world lit by an image: Background <- Environment Texture [<- Mapping] [<- Texture Coordinate].

The pattern artists use for an HDRI. What it exports is an Environment with a radiance
map (renderer.lights.environment): the image's pixels in linear Rec.709 with its projection
(equirectangular or mirror ball), the Background's Strength as the map's tint, and the
Mapping node's rotation (or its inverse for the Texture type) as the map's frame. Anything
else in that chain (a texture feeding Strength, a translation or an unequal scale on the
direction, cubic interpolation) is warned about once, naming the world and node, with what is rendered
instead. A tree that is not this pattern is folded to a constant as before (world.py).

The pixels are read with `image.pixels.foreach_get` into a new array: the user's image,
its path and its settings are never changed.
"""

from __future__ import annotations

import numpy as np

from renderer.scene import Environment

from .nodes import ShaderGraph

# Cycles renders a missing image magenta (TEX_IMAGE_MISSING_R/G/B).
MISSING_IMAGE = (1.0, 0.0, 1.0)
# Colour spaces whose pixels are linear Rec.709 as read; byte images in sRGB are decoded.
LINEAR_SPACES = {"Linear Rec.709", "Non-Color", "Linear", "Raw", "Linear CIE-XYZ E"}


def follow(graph: ShaderGraph, socket):
    """(node, output) feeding `socket`, through reroutes; None when unlinked."""
    source = graph.link_source(socket)
    while source is not None and source[0].bl_idname == "NodeReroute":
        source = graph.link_source(source[0].inputs[0])
    return source


def environment_map(graph: ShaderGraph, surface_socket) -> Environment | None:
    """The world's map if its Surface is Background <- Environment Texture; else None."""
    source = follow(graph, surface_socket)
    if source is None or source[0].bl_idname != "ShaderNodeBackground" or source[0].mute:
        return None
    background = source[0]
    texture = follow(graph, background.inputs["Color"])
    if texture is None or texture[0].bl_idname != "ShaderNodeTexEnvironment" or texture[0].mute:
        return None
    node = texture[0]
    if texture[1].name != "Color":
        return None  # the Alpha output: left to the constant folding (which warns)
    strength = float(graph.input_value(background.inputs["Strength"])[0, 0])
    pixels = image_pixels(graph, node)
    if pixels is None:
        return Environment(radiance=tuple(strength * c for c in MISSING_IMAGE))
    interpolation = "closest" if node.interpolation == "Closest" else "linear"
    if node.interpolation not in ("Closest", "Linear"):
        graph.warn_node(node, f"{node.interpolation} interpolation is rendered as Linear")
    to_world = np.eye(4)
    to_world[:3, :3] = direction_transform(graph, node.inputs["Vector"]).T  # world -> map, inverted
    projection = "mirror_ball" if node.projection == "MIRROR_BALL" else "equirectangular"
    return Environment(radiance=(strength, strength, strength), radiance_map=pixels,
                       interpolation=interpolation, projection=projection, to_world=to_world)


def image_pixels(graph: ShaderGraph, node) -> np.ndarray | None:
    """(H, W, 3) float32 linear Rec.709 radiance of the node's image, row 0 at the bottom;
    None (warned) when there is no image or it has no pixels."""
    image = node.image
    if image is None:
        graph.warn_node(node, "has no image; the background is magenta, as in Cycles")
        return None
    width, height = image.size
    channels = image.channels
    if width == 0 or height == 0 or channels == 0:
        graph.warn_node(node, f"image '{image.name}' has no pixels (missing file?); "
                              "the background is magenta")
        return None
    flat = np.empty(width * height * channels, np.float32)
    image.pixels.foreach_get(flat)
    rgb = flat.reshape(height, width, channels)[..., :3] if channels >= 3 else np.repeat(
        flat.reshape(height, width, channels)[..., :1], 3, axis=2)
    space = image.colorspace_settings.name
    if not image.is_float and space not in LINEAR_SPACES:
        if space != "sRGB":
            graph.warn_node(node, f"colour space {space} of an 8-bit image is read as sRGB")
        rgb = srgb_to_linear(rgb)  # (float images hold scene-linear pixels once loaded)
    rgb = np.nan_to_num(np.maximum(rgb, 0.0), nan=0.0, posinf=0.0)
    return np.ascontiguousarray(rgb, np.float32)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function's inverse (Blender's and Cycles' for 8-bit sRGB images)."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def direction_transform(graph: ShaderGraph, vector_socket) -> np.ndarray:
    """(3, 3) world -> map linear map the texture coordinate goes through: identity for the
    default (the ray direction, = Generated for a world), a Mapping node's rotation (and
    sign of its uniform scale) otherwise."""
    source = follow(graph, vector_socket)
    if source is None:
        return np.eye(3)
    node, output = source
    if node.bl_idname == "ShaderNodeTexCoord":
        direction = output.name == "Generated" or (output.name == "Object" and node.object is None)
        if not direction:
            graph.warn_node(node, f"{output.name} coordinates on a world are rendered as Generated "
                                  "(the direction)")
        return np.eye(3)
    if node.bl_idname != "ShaderNodeMapping" or node.mute:
        graph.warn_unsupported(node)
        return np.eye(3)
    inner = direction_transform(graph, node.inputs["Vector"])
    return mapping_matrix(graph, node) @ inner


def mapping_matrix(graph: ShaderGraph, node) -> np.ndarray:
    """A Mapping node's action on directions (Cycles' svm_mapping): Point and Vector rotate
    the scaled vector, Texture applies the inverse, Normal rotates the vector divided by the
    scale. A direction's length does not matter, so only a uniform scale's sign is kept."""
    from mathutils import Euler  # Blender's own XYZ Euler matrix, as Cycles' euler_to_transform

    rotation = np.array(Euler(graph.input_value(node.inputs["Rotation"])[0].tolist(), "XYZ").to_matrix())
    scale = graph.input_value(node.inputs["Scale"])[0] if "Scale" in node.inputs else np.ones(3)
    location = graph.input_value(node.inputs["Location"])[0] if "Location" in node.inputs else np.zeros(3)
    kind = node.vector_type
    if kind in ("POINT", "TEXTURE") and np.any(location != 0.0):
        graph.warn_node(node, "a Location on a world direction is ignored")
    if not np.allclose(np.abs(scale), abs(scale[0])) or scale[0] == 0.0:
        graph.warn_node(node, "an unequal or zero Scale on a world direction is ignored")
        scale = np.ones(3)
    sign = float(np.sign(scale[0]))
    if kind == "TEXTURE":
        return sign * rotation.T
    return sign * rotation
