"""A world whose Background varies with direction through nodes programs compile (a gradient
sky from Texture Coordinate or Geometry, a Color Ramp of it, Math, Mix...): the Background's
Color x Strength compiles to a shader program, evaluated at export at the pixel centres of an
equirectangular grid into an environment map (renderer.lights.environment), which lights
the scene by importance sampling and MIS as an HDRI does, and which escaped rays read with
bilinear interpolation (not the program itself: between pixel centres the map interpolates).

Environment Textures inside such a program are image lookups at the direction's
equirectangular or mirror-ball coordinates (Cycles' direction_to_*), so an HDRI
times a colour, a Mix of an HDRI and a gradient, or of two HDRIs, become one map.

As Cycles sets up the background's shading point (geom/shader_data.h,
shader_setup_from_background), the position is the ray direction D and the normal -D:
Texture Coordinate Generated and Object give D, Normal -D; Geometry Position D, Normal -D.
"""

from __future__ import annotations

import numpy as np

from renderer.scene import CornerAttribute, Environment, Lobe, Material, Mesh
from renderer.shading.names import MATH_OPS, VECTOR_OPS

from .node_program import interpolation_index
from .node_values import FRONT
from .nodes import ShaderGraph
from .program_builder import Reg
from .world_map import follow

MAP_WIDTH, MAP_HEIGHT = 1024, 512  # 0.35 degrees per pixel: the map of a world without images
# The largest map (an Environment Texture's own resolution, up to this): 64 MiB of float32
# RGB, plus the importance-sampling tables built from it.
MAX_MAP_WIDTH = 4096
ROWS_PER_BLOCK = 64  # rows of a 1024-wide map evaluated at once (fewer for wider maps)


def world_tex_coord(graph, node, output, scope):
    name = output.identifier
    if name in ("Generated", "Object") and (name == "Generated" or node.object is None):
        return graph.program.emit("position", 3)
    if name == "Normal":
        return graph.program.emit("normal", 3)
    return None


def world_geometry(graph, node, output, scope):
    if output.identifier in ("Position", "Incoming"):
        return graph.program.emit("position" if output.identifier == "Position" else "normal", 3)
    if output.identifier == "Normal":
        return graph.program.emit("normal", 3)
    return None


def world_environment_texture(graph, node, output, scope):
    """Environment Texture: the image at the equirectangular (u = 1/2 - atan2(y, x) / 2 pi,
    v = 1 - acos(z) / pi) or mirror-ball coordinates of the normalised vector (the direction
    when unlinked), with Cycles' Repeat extension (svm_node_tex_environment)."""
    p = graph.program
    alpha = output.identifier == "Alpha"
    if node.image is None:
        graph.warn_node(node, "has no image; rendered as Cycles' magenta")
        return p.const(1.0 if alpha else (1.0, 0.0, 1.0))
    name = graph.add_image(node.image)
    if name is None:
        return None
    socket = node.inputs["Vector"]
    d = graph.operand(socket, scope) if graph.link_source(socket) is not None else p.emit("position", 3)
    zero = p.const(0.0)
    d = p.emit("vector_math", 3, d, zero, zero, p.const(1.0), i0=VECTOR_OPS.index("NORMALIZE"))
    mirror_ball = node.projection == "MIRROR_BALL"
    u, v = mirror_ball_uv(p, d) if mirror_ball else equirectangular_uv(p, d)
    uv = p.emit("combine", 3, u, v, zero)
    out = p.emit("image", 4, uv, i0=p.image(name), i1=interpolation_index(node.interpolation), i2=0)
    return Reg(out.index + 3, 1) if alpha else Reg(out.index, 3)


def _math(p, op: str, a: Reg, b: Reg, c: Reg | None = None) -> Reg:
    return p.emit("math", 1, a, b, c if c is not None else p.const(0.0), i0=MATH_OPS.index(op))


def equirectangular_uv(p, d: Reg) -> tuple[Reg, Reg]:
    """Cycles' direction_to_equirectangular of the unit vector d."""
    x, y, z = (p.component(d, k) for k in range(3))
    zero = p.const(0.0)
    phi = _math(p, "ARCTAN2", y, x)
    u = _math(p, "MULTIPLY_ADD", phi, p.const(-0.5 / np.pi), p.const(0.5))
    theta = _math(p, "ARCCOSINE", z, zero)
    return u, _math(p, "MULTIPLY_ADD", theta, p.const(-1.0 / np.pi), p.const(1.0))


def mirror_ball_uv(p, d: Reg) -> tuple[Reg, Reg]:
    """Cycles' direction_to_mirrorball of the unit vector d: (x, z) / (2 sqrt((1 - y) / 2))
    mapped to [0, 1]. Where the divisor is 0 (d = +Y) x = z = 0, which Math's safe Divide
    also gives."""
    x, y, z = (p.component(d, k) for k in range(3))
    half, zero = p.const(0.5), p.const(0.0)
    h = _math(p, "MAXIMUM", _math(p, "MULTIPLY_ADD", y, p.const(-0.5), half), zero)  # -0.5 (y - 1)
    div = _math(p, "MULTIPLY", _math(p, "SQRT", h, zero), p.const(2.0))
    u = _math(p, "MULTIPLY_ADD", _math(p, "DIVIDE", x, div), half, half)
    return u, _math(p, "MULTIPLY_ADD", _math(p, "DIVIDE", z, div), half, half)


WORLD_HANDLERS = {"ShaderNodeTexCoord": world_tex_coord, "ShaderNodeNewGeometry": world_geometry,
                  "ShaderNodeTexEnvironment": world_environment_texture}
WORLD_SOURCES = {"ShaderNodeTexEnvironment"}  # vary with direction by themselves


def grid_directions(width: int, height: int, first: int = 0, last: int | None = None) -> np.ndarray:
    """(rows, W, 3) unit directions at the pixel centres of rows first..last - 1 (all by
    default) of an equirectangular map, row 0 at the bottom (renderer.lights.
    environment_lookup's mapping)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(first, height if last is None else last) + 0.5) / height
    theta = np.pi * (1.0 - v)[:, None]
    phi = np.pi * (1.0 - 2.0 * u)[None, :]
    return np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                        np.cos(theta)), axis=-1)


def world_program_map(graph: ShaderGraph, surface_socket) -> Environment | None:
    """The map of a Background whose Color or Strength a program computes; None when the
    Surface is not a Background or neither input varies (or cannot be compiled)."""
    source = follow(graph, surface_socket)
    if source is None or source[0].bl_idname != "ShaderNodeBackground" or source[0].mute:
        return None
    background = source[0]
    color_reg = graph.input_varying(background.inputs["Color"])
    strength_reg = graph.input_varying(background.inputs["Strength"])
    if color_reg is None and strength_reg is None:
        return None
    p = graph.program
    inputs = background.inputs
    color = color_reg if color_reg is not None else p.const(graph.input_value(inputs["Color"])[FRONT])
    strength = p.widen(strength_reg if strength_reg is not None else
                       p.const(graph.input_value(inputs["Strength"])[FRONT]))
    multiply = VECTOR_OPS.index("MULTIPLY")
    radiance = p.emit("vector_math", 3, color, strength, color, p.const(1.0), i0=multiply)
    program = p.build([])
    width, height = map_size(program, graph.images)
    pixels = evaluate_on_grid(program, radiance.index, graph.images, width, height)
    return Environment(radiance=(1.0, 1.0, 1.0), radiance_map=pixels, interpolation="linear",
                       projection="equirectangular")


def map_size(program, images) -> tuple[int, int]:
    """(width, height) of the map a world program is evaluated on: MAP_WIDTH x MAP_HEIGHT, or
    as fine as the program's largest W x H image, max(W, 2 H) wide (an equirectangular
    image's own resolution; twice a square mirror ball's), capped at MAX_MAP_WIDTH, so a
    sharp HDRI seen directly is not blurred by a coarser map."""
    textures = {t.name: t for t in images.list()} if images is not None else {}
    width = MAP_WIDTH
    for name in program.images:
        if name in textures:
            h, w = textures[name].pixels.shape[:2]
            width = max(width, w, 2 * h)
    width = min(width, MAX_MAP_WIDTH)
    width += width % 2
    return width, width // 2


def evaluate_on_grid(program, register: int, images, width: int = MAP_WIDTH,
                     height: int = MAP_HEIGHT) -> np.ndarray:
    """(H, W, 3) float32 radiance >= 0: the program's registers register..+2 at every pixel
    centre's direction D (position D, normal -D)."""
    from renderer.shading.evaluate import evaluate_program
    from renderer.shading.table import build_shading_tables

    # No surface: one dummy triangle carries the (unused) corner attributes.
    attributes = [CornerAttribute(name, np.zeros((1, 3, 3), np.float32)) for name in program.attributes]
    mesh = Mesh("world", np.zeros((3, 3), np.float32), np.array([[0, 1, 2]], np.int32), ["world"],
                attributes=attributes)
    material = Material("world", lobes=[Lobe("diffuse")], program=program)
    tables = build_shading_tables([material], [mesh], images.list() if images is not None else [], 1)
    out = np.empty((height, width, 3), np.float32)
    rows = max(1, ROWS_PER_BLOCK * MAP_WIDTH // width)
    for first in range(0, height, rows):  # in blocks of rows: peak memory stays near the map's
        directions = grid_directions(width, height, first, min(height, first + rows)).reshape(-1, 3)
        count = directions.shape[0]
        bary = np.tile(np.array([1.0, 0.0, 0.0], np.float32), (count, 1))
        triangles = np.zeros(count, np.int32)
        values = evaluate_program(tables, 0, register, 3, triangles, bary, directions, -directions)
        values = np.where(np.isfinite(values), np.maximum(values, 0.0), 0.0)
        out[first:first + rows] = values.reshape(-1, width, 3)
    return out
