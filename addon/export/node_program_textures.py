"""Procedural texture nodes compiled into program instructions (program_builder), with
Cycles' semantics: Noise Texture of every dimension and type (renderer.shading.fractal),
White Noise (white_noise), Voronoi (voronoi).

Handlers follow node_program's convention (graph, node, output, scope) -> Reg | None;
TEXTURE_HANDLERS and TEXTURE_SOURCES are merged into node_program's registry.
"""

from __future__ import annotations

from collections.abc import Callable

from renderer.shading.fractal import TYPES as NOISE_TYPES
from renderer.shading.patterns import BANDS_DIRECTIONS, RINGS_DIRECTIONS, WAVE_PROFILES, WAVE_TYPES
from renderer.shading.program import NOISE_NO_COLOR, NOISE_NORMALIZE
from renderer.shading.voronoi_cells import FEATURES, METRICS

from .program_builder import Reg

DIMENSIONS = {"1D": 1, "2D": 2, "3D": 3, "4D": 4}


def by_id(node, identifier: str):
    return next(s for s in node.inputs if s.identifier == identifier)


def texture_vector(graph, node, scope) -> Reg:
    """A procedural texture's Vector input; unlinked, Cycles' default: Generated."""
    socket = node.inputs["Vector"]
    if graph.link_source(socket) is not None:
        return graph.operand(socket, scope)
    return graph.program.attribute("generated", 3)


def block(graph, node, scope, names: tuple[str, ...], extra: tuple[Reg, ...] = ()) -> Reg:
    """The inputs `names`, then the registers `extra`, copied into consecutive registers (an
    instruction's parameter block)."""
    p = graph.program
    sources = [graph.operand(by_id(node, name), scope) for name in names] + list(extra)
    out = p.alloc(len(sources))
    for k, source in enumerate(sources):
        p.emit("copy", 1, source, i0=1, dst=Reg(out.index + k, 1))
    return out


def noise(graph, node, output, scope) -> Reg | None:
    """Noise Texture: Fac in [0, 1] for normalized fBM (see fractal.py for the others' ranges),
    Color = (Fac, two more seeds)."""
    dim = DIMENSIONS[node.noise_dimensions]
    p = graph.program
    v = texture_vector(graph, node, scope) if dim > 1 else p.const((0.0, 0.0, 0.0))
    params = block(graph, node, scope, ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain",
                                        "Distortion"))
    # The colour costs two more fractals: only for a linked Color output, as Cycles.
    color = output.identifier != "Fac" or node.outputs["Color"].is_linked
    flags = (NOISE_NORMALIZE if node.normalize else 0) | (0 if color else NOISE_NO_COLOR)
    out = p.emit("noise_nd", 4, v, params, i0=dim, i1=NOISE_TYPES.index(node.noise_type), i2=flags)
    return Reg(out.index, 1) if output.identifier == "Fac" else Reg(out.index + 1, 3)


def white_noise(graph, node, output, scope) -> Reg | None:
    """White Noise Texture: Value and Color in [0, 1], hashes of the input's float32 bits."""
    dim = DIMENSIONS[node.noise_dimensions]
    p = graph.program
    v = texture_vector(graph, node, scope) if dim > 1 else p.const((0.0, 0.0, 0.0))
    w = graph.operand(by_id(node, "W"), scope) if dim in (1, 4) else p.const(0.0)
    out = p.emit("white_noise", 4, v, w, i0=dim)
    return Reg(out.index, 1) if output.identifier == "Value" else Reg(out.index + 1, 3)


VORONOI_OUTPUTS = {"Distance": (0, 1), "Color": (1, 3), "Position": (4, 3), "W": (7, 1), "Radius": (8, 1)}


def voronoi(graph, node, output, scope) -> Reg | None:
    """Voronoi Texture (ranges in renderer.shading.voronoi)."""
    dim = DIMENSIONS[node.voronoi_dimensions]
    p = graph.program
    v = texture_vector(graph, node, scope) if dim > 1 else p.const((0.0, 0.0, 0.0))
    params = block(graph, node, scope, ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Smoothness",
                                        "Exponent", "Randomness"))
    flags = METRICS.index(node.distance) + 4 * int(node.normalize)
    out = p.emit("voronoi", 9, v, params, i0=dim, i1=FEATURES.index(node.feature), i2=flags)
    first, width = VORONOI_OUTPUTS[output.identifier]
    return Reg(out.index + first, width)


def wave(graph, node, output, scope) -> Reg:
    """Wave Texture: Fac in [0, 1], Color its grey."""
    p = graph.program
    params = block(graph, node, scope, ("Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness",
                                        "Phase Offset"))
    bands = node.wave_type == "BANDS"
    direction = (BANDS_DIRECTIONS.index(node.bands_direction) if bands
                 else RINGS_DIRECTIONS.index(node.rings_direction))
    f = p.emit("wave", 1, texture_vector(graph, node, scope), params, i0=WAVE_TYPES.index(node.wave_type),
               i1=direction, i2=WAVE_PROFILES.index(node.wave_profile))
    return f if output.identifier == "Fac" else p.widen(f)


def magic(graph, node, output, scope) -> Reg:
    """Magic Texture: Color in [0, 1] (see patterns.py), Fac its average."""
    p = graph.program
    params = block(graph, node, scope, ("Scale", "Distortion"))
    out = p.emit("magic", 4, texture_vector(graph, node, scope), params, i0=int(node.turbulence_depth))
    return Reg(out.index + 3, 1) if output.identifier == "Fac" else Reg(out.index, 3)


def brick(graph, node, output, scope) -> Reg:
    """Brick Texture: Color between Color1, Color2 and Mortar; Fac (the mortar) in [0, 1]."""
    p = graph.program
    shifts = (p.const(float(node.offset)), p.const(float(node.squash)))  # properties, not sockets
    params = block(graph, node, scope, ("Scale", "Mortar Size", "Mortar Smooth", "Bias", "Brick Width",
                                        "Row Height"), shifts)
    colors = [graph.operand(node.inputs[k], scope) for k in ("Color1", "Color2", "Mortar")]
    out = p.emit("brick", 4, texture_vector(graph, node, scope), params, *colors,
                 i0=int(node.offset_frequency), i1=int(node.squash_frequency))
    return Reg(out.index + 3, 1) if output.identifier == "Fac" else Reg(out.index, 3)


TEXTURE_HANDLERS: dict[str, Callable] = {
    "ShaderNodeTexNoise": noise,
    "ShaderNodeTexWhiteNoise": white_noise,
    "ShaderNodeTexVoronoi": voronoi,
    "ShaderNodeTexWave": wave,
    "ShaderNodeTexMagic": magic,
    "ShaderNodeTexBrick": brick,
}
TEXTURE_SOURCES = set(TEXTURE_HANDLERS)
