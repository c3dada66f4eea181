"""Closure inputs driven by shader programs: the registers a closure handler binds to lobe
fields (colour, roughness, IOR), varying emission, and the per-point weights of a Mix
Shader whose factor varies (or of Principled's Alpha). The handlers in node_closures and
node_principled call these; the graph's ProgramBuilder emits the operations."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from renderer.shading.names import MATH_OPS, VECTOR_OPS

# node_closures (Inputs, Term, ClosureGraph) imports this module, so they are typed Any here.
Inputs = ClosureGraph = Any


def mix_by_program(graph: ClosureGraph, node, scope: tuple, factor) -> list:
    """A Mix Shader whose factor varies: each side's weights are scaled per shading point
    by the program's clamped factor f (second input) and 1 - f (first input)."""
    f, g = factor_pair(graph.program, factor)
    first, second = graph.closure(node.inputs[1], scope), graph.closure(node.inputs[2], scope)
    return scaled_by(first, g) + scaled_by(second, f)


def factor_pair(p, factor) -> tuple:
    """Registers of clamp(factor, 0, 1) and 1 - that (a mix's two weights)."""
    f = p.emit("clamp", 1, factor, p.const(0.0), p.const(1.0))
    return f, p.emit("math", 1, p.const(1.0), f, p.const(0.0), i0=MATH_OPS.index("SUBTRACT"))


def scaled_by(terms: list, reg) -> list:
    """The terms with their weights scaled per shading point by scalar register reg."""
    return [replace(t, scales=t.scales + (reg,)) for t in terms]


def emission_binds(read: Inputs, color: str, strength: str) -> tuple:
    """(("emission", register of colour x strength),) when a program drives either input,
    else () (the term's weight is then the constant radiance)."""
    color_reg, strength_reg = read.varying(color), read.varying(strength)
    if color_reg is None and strength_reg is None:
        return ()
    p = read.program
    c = color_reg if color_reg is not None else p.const(read(color)[:3])
    s = p.widen(strength_reg if strength_reg is not None else p.const(read(strength)))
    one = p.const(1.0)
    return (("emission", p.emit("vector_math", 3, c, s, c, one, i0=VECTOR_OPS.index("MULTIPLY"))),)


def normal_bind(read: Inputs) -> tuple:
    """(("normal", register),) when a program drives the BSDF's Normal input (a Normal Map):
    the shading normal of the material's lobes per shading point."""
    reg = read.varying("Normal")
    return () if reg is None else (("normal", reg),)


def ior_bind(read: Inputs, name: str = "IOR") -> tuple:
    reg = read.varying(name)
    return () if reg is None else (("ior", reg),)


def color_binds(read: Inputs, name: str = "Color") -> tuple:
    reg = read.varying(name)
    return () if reg is None else (("color", reg),)


def roughness_bind(read: Inputs, name: str = "Roughness") -> tuple:
    reg = read.varying(name)
    return () if reg is None else (("roughness", reg),)


def capped_color(read: Inputs, reg, exponent: float = 1.0):
    """min(colour, 1) ** exponent computed by the program."""
    p = read.program
    one = p.const((1.0, 1.0, 1.0))
    capped = p.emit("vector_math", 3, reg, one, one, p.const(1.0), i0=VECTOR_OPS.index("MINIMUM"))
    if exponent == 1.0:
        return capped
    e = p.const((exponent,) * 3)
    return p.emit("vector_math", 3, capped, e, one, p.const(1.0), i0=VECTOR_OPS.index("POWER"))
