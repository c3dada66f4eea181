"""Table-driven colour and value nodes, compiled into program instructions and folded to
constants with the same tables: RGB Curves, Vector Curves, Float Curve (program op
"curve") and Blackbody, Wavelength (op "spectrum").

Curves, as Cycles' blender/util.h curvemapping_*_to_array: RAMP_SIZE samples of Blender's
own CurveMapping.evaluate (so every handle type, Auto, Auto Clamped, Vector, Free and
Aligned, is Blender's), over the x range from the first to the last point of the node's
curves (all four for RGB Curves, whose table is the channel's curve of the combined curve).
An input outside the range reads the end entry (Extend Horizontal) or continues the line
through the last two entries (Extend Extrapolated), as the kernel's float_ramp_lookup.

Blackbody and Wavelength convert to the scene's working space (and clamp at 0) through
Blender's own colour management matrices (Rec.709 and CIE XYZ D65 to scene linear).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.shading.names import RAMP_SIZE
from renderer.shading.spectrum import WAVELENGTH_SCALE, blackbody_numpy, wavelength_numpy

from .node_values import VALUE_HANDLERS
from .program_builder import Reg

CURVE_NODES = {"ShaderNodeRGBCurve": 3, "ShaderNodeVectorCurve": 3, "ShaderNodeFloatCurve": 1}


def curve_table(node) -> tuple[np.ndarray, float, float, bool]:
    """(table (RAMP_SIZE, channels) float32, x min, x max, extrapolate) of a curve node."""
    mapping = node.mapping
    rgb = node.bl_idname == "ShaderNodeRGBCurve"
    channels = CURVE_NODES[node.bl_idname]
    used = list(mapping.curves)[: 4 if rgb else channels]
    lo = np.float32(min(c.points[0].location[0] for c in used))
    hi = np.float32(max(c.points[-1].location[0] for c in used))
    if not hi > lo:  # one x for all points: Cycles divides by zero; a unit range instead
        hi = np.float32(lo + 1.0)
    mapping.initialize()
    steps = np.arange(RAMP_SIZE, dtype=np.float32) / np.float32(RAMP_SIZE - 1)
    xs = (lo + steps * (hi - lo)).astype(np.float32)
    table = np.empty((RAMP_SIZE, channels), np.float32)
    curves = list(mapping.curves)
    for k, x in enumerate(xs.tolist()):
        if rgb:
            combined = mapping.evaluate(curves[3], x)
            table[k] = [mapping.evaluate(curves[ch], combined) for ch in range(3)]
        else:
            table[k] = [mapping.evaluate(curves[ch], x) for ch in range(channels)]
    return table, float(lo), float(hi), mapping.extend == "EXTRAPOLATED"


def curve_program(graph, node, output, scope) -> Reg:
    p = graph.program
    table, lo, hi, extrapolate = curve_table(node)
    channels = table.shape[1]
    fac, value = graph.operand(node.inputs[0], scope), graph.operand(node.inputs[1], scope)
    return p.emit("curve", channels, fac, value, p.const(lo), p.const(hi), i0=p.table(table), i1=channels,
                  i2=int(extrapolate))


def lookup(table: np.ndarray, f: np.ndarray, extrapolate: bool) -> np.ndarray:
    """textures.curve_lookup over arrays: f (..., C) positions in [0, 1] of C channels."""
    n = table.shape[0]
    x = np.nan_to_num(np.clip(f, 0.0, 1.0)) * (n - 1)
    i = np.clip(x.astype(np.int64), 0, n - 1)
    t = x - i
    cols = np.arange(table.shape[1])
    here, after = table[i, cols], table[np.minimum(i + 1, n - 1), cols]
    out = np.where(t > 0.0, (1.0 - t) * here + t * after, here)
    if extrapolate:
        low = table[0] + (table[0] - table[1]) * (-f) * (n - 1)
        high = table[-1] + (table[-1] - table[-2]) * (f - 1.0) * (n - 1)
        out = np.where(f < 0.0, low, np.where(f > 1.0, high, out))
    return out


def curve_value(graph, node, socket, scope: tuple) -> np.ndarray:
    table, lo, hi, extrapolate = curve_table(node)
    fac = graph.input_value(node.inputs[0], scope)
    x = graph.input_value(node.inputs[1], scope)
    return (1.0 - fac) * x + fac * lookup(table, (x - lo) / (hi - lo), extrapolate)


def working_space(kind: str) -> np.ndarray:
    """(3, 3) matrix from linear Rec.709 ("rec709") or CIE XYZ D65 ("xyz") to the scene's
    working space, from Blender's colour management."""
    from mathutils import Color

    convert = {"rec709": "from_rec709_linear_to_scene_linear", "xyz": "from_xyz_d65_to_scene_linear"}[kind]
    columns = [tuple(getattr(Color(axis), convert)()) for axis in np.eye(3).tolist()]
    return np.array(columns, np.float64).T


SPECTRA = {"ShaderNodeBlackbody": (0, "Temperature", "rec709", 1.0),
           "ShaderNodeWavelength": (1, "Wavelength", "xyz", WAVELENGTH_SCALE)}


def spectrum_program(graph, node, output, scope) -> Reg:
    kind, name, space, scale = SPECTRA[node.bl_idname]
    p = graph.program
    matrix = p.const(tuple((working_space(space) * scale).ravel()))
    return p.emit("spectrum", 3, graph.operand(node.inputs[name], scope), matrix, i0=kind)


def spectrum_value(graph, node, socket, scope: tuple) -> np.ndarray:
    kind, name, space, scale = SPECTRA[node.bl_idname]
    x = graph.input_value(node.inputs[name], scope)[:, 0]
    color = blackbody_numpy(x) if kind == 0 else wavelength_numpy(x)
    return np.maximum(color @ (working_space(space) * scale).T, 0.0)


TABLE_HANDLERS: dict[str, Callable] = {**{k: curve_program for k in CURVE_NODES},
                                       **{k: spectrum_program for k in SPECTRA}}
VALUE_HANDLERS.update({**{k: curve_value for k in CURVE_NODES}, **{k: spectrum_value for k in SPECTRA}})
