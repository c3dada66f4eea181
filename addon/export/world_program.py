"""A world whose Background varies with direction through nodes programs compile (a gradient
sky from Texture Coordinate or Geometry, a Color Ramp of it, Math, Mix...): the Background's
Color x Strength compiles to a shader program, evaluated at export at the pixel centres of an
equirectangular grid into an environment map (renderer.lights.environment), which lights
the scene by importance sampling and MIS as an HDRI does, and which escaped rays read with
bilinear interpolation (not the program itself: between pixel centres the map interpolates).

Environment Textures (equirectangular) inside such a program are image lookups at the
direction's equirectangular coordinates (Cycles' direction_to_equirectangular), so an HDRI
times a colour, a Mix of an HDRI and a gradient, or of two HDRIs, become one map.

As Cycles sets up the background's shading point (geom/shader_data.h,
shader_setup_from_background), the position is the ray direction D and the normal -D:
Texture Coordinate Generated and Object give D, Normal -D; Geometry Position D, Normal -D.
"""

from __future__ import annotations

import numpy as np

from renderer.scene import CornerAttribute, Environment, Lobe, Material, Mesh
from renderer.shading.names import MATH_OPS, VECTOR_OPS

from .node_values import FRONT
from .nodes import ShaderGraph
from .program_builder import Reg
from .world_map import follow

MAP_WIDTH, MAP_HEIGHT = 1024, 512  # 0.35 degrees per pixel


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
    """Environment Texture (equirectangular): the image at u = 1/2 - atan2(y, x) / 2 pi,
    v = 1 - acos(z) / pi of the normalised vector (the direction when unlinked), with
    Cycles' Repeat extension."""
    p = graph.program
    alpha = output.identifier == "Alpha"
    if node.image is None:
        graph.warn_node(node, "has no image; rendered as Cycles' magenta")
        return p.const(1.0 if alpha else (1.0, 0.0, 1.0))
    if node.projection != "EQUIRECTANGULAR":
        graph.warn_node(node, "Mirror Ball projection is not supported inside a world program")
        return None
    if node.interpolation not in ("Closest", "Linear"):
        graph.warn_node(node, f"{node.interpolation} interpolation is rendered as Linear")
    name = graph.add_image(node.image)
    if name is None:
        return None
    socket = node.inputs["Vector"]
    d = graph.operand(socket, scope) if graph.link_source(socket) is not None else p.emit("position", 3)
    zero = p.const(0.0)
    d = p.emit("vector_math", 3, d, zero, zero, p.const(1.0), i0=VECTOR_OPS.index("NORMALIZE"))
    x, y, z = (p.component(d, k) for k in range(3))
    math = {op: MATH_OPS.index(op) for op in ("ARCTAN2", "ARCCOSINE", "MULTIPLY_ADD")}
    phi = p.emit("math", 1, y, x, zero, i0=math["ARCTAN2"])
    u = p.emit("math", 1, phi, p.const(-0.5 / np.pi), p.const(0.5), i0=math["MULTIPLY_ADD"])
    theta = p.emit("math", 1, z, zero, zero, i0=math["ARCCOSINE"])
    v = p.emit("math", 1, theta, p.const(-1.0 / np.pi), p.const(1.0), i0=math["MULTIPLY_ADD"])
    uv = p.emit("combine", 3, u, v, zero)
    out = p.emit("image", 4, uv, i0=p.image(name), i1=int(node.interpolation != "Closest"), i2=0)
    return Reg(out.index + 3, 1) if alpha else Reg(out.index, 3)


WORLD_HANDLERS = {"ShaderNodeTexCoord": world_tex_coord, "ShaderNodeNewGeometry": world_geometry,
                  "ShaderNodeTexEnvironment": world_environment_texture}
WORLD_SOURCES = {"ShaderNodeTexEnvironment"}  # vary with direction by themselves


def grid_directions(width: int, height: int) -> np.ndarray:
    """(H, W, 3) unit directions at the pixel centres of an equirectangular map, row 0 at
    the bottom (renderer.lights.environment_lookup's mapping)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
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
    pixels = evaluate_on_grid(p.build([]), radiance.index, graph.images)
    return Environment(radiance=(1.0, 1.0, 1.0), radiance_map=pixels, interpolation="linear",
                       projection="equirectangular")


def evaluate_on_grid(program, register: int, images) -> np.ndarray:
    """(H, W, 3) float32 radiance >= 0: the program's registers register..+2 at every pixel
    centre's direction D (position D, normal -D)."""
    from renderer.shading.evaluate import evaluate_program
    from renderer.shading.table import build_shading_tables

    directions = grid_directions(MAP_WIDTH, MAP_HEIGHT).reshape(-1, 3)
    # No surface: one dummy triangle carries the (unused) corner attributes.
    attributes = [CornerAttribute(name, np.zeros((1, 3, 3), np.float32)) for name in program.attributes]
    mesh = Mesh("world", np.zeros((3, 3), np.float32), np.array([[0, 1, 2]], np.int32), ["world"],
                attributes=attributes)
    material = Material("world", lobes=[Lobe("diffuse")], program=program)
    tables = build_shading_tables([material], [mesh], images.list() if images is not None else [], 1)
    count = directions.shape[0]
    bary = np.tile(np.array([1.0, 0.0, 0.0], np.float32), (count, 1))
    triangles = np.zeros(count, np.int32)
    values = evaluate_program(tables, 0, register, 3, triangles, bary, directions, -directions)
    values = np.where(np.isfinite(values), np.maximum(values, 0.0), 0.0)
    return values.reshape(MAP_HEIGHT, MAP_WIDTH, 3).astype(np.float32)
