"""Closure inputs driven by shader programs: the registers a closure handler binds to lobe
fields (colour, roughness) and the per-point weights of a Mix Shader whose factor varies.
The handlers in node_closures call these; the graph's ProgramBuilder emits the operations."""

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
    # Emission cannot vary (the light table is constant): it takes the socket's own value.
    f0 = min(max(float(graph.unlinked_value(node.inputs[0], 1)[0, 0]), 0.0), 1.0)
    first = [_scaled(t, g, 1.0 - f0) for t in graph.closure(node.inputs[1], scope)]
    second = [_scaled(t, f, f0) for t in graph.closure(node.inputs[2], scope)]
    if any(t.kind == "emission" for t in first + second):
        graph.warn_node(node, "emission cannot vary over a surface yet: it is mixed by the Fac "
                              "socket's own value")
    return first + second


def factor_pair(p, factor) -> tuple:
    """Registers of clamp(factor, 0, 1) and 1 - that (a mix's two weights)."""
    f = p.emit("clamp", 1, factor, p.const(0.0), p.const(1.0))
    return f, p.emit("math", 1, p.const(1.0), f, p.const(0.0), i0=MATH_OPS.index("SUBTRACT"))


def _scaled(term, reg, constant: float):
    if term.kind == "emission":
        return replace(term, weight=term.weight * constant)
    return replace(term, scales=term.scales + (reg,))


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
