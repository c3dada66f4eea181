"""Shader nodes to closure terms (BSDF lobes, emission, volume coefficients), with Cycles' semantics.

A closure handler reads its node's inputs on one face (Inputs: plain floats and colours) and
returns weighted terms; the graph (nodes.ShaderGraph) runs it for the front and the back
face and merges the two lists where they agree. Mix and Add Shader combine the terms of
their inputs. Closures Haze has no model for are rendered as a Diffuse BSDF of their Color
input (fallback_closure, warned).

CLOSURE_HANDLERS and COMBINE_HANDLERS map node type names to handlers (the Principled
BSDF's is in node_principled, which nodes.py adds).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from .closure_bindings import (
    color_binds,
    emission_binds,
    ior_bind,
    mix_by_program,
    normal_bind,
    roughness_bind,
)
from .node_values import BACK, FRONT, SIDE_NAMES, ValueGraph


@dataclass
class Term:
    """One weighted closure. Lobe kinds are those of renderer.scene.Lobe; the others are
    "emission" (surface or world radiance), "scatter", "absorb" and "volume_emission"
    (volume coefficients per unit length)."""

    kind: str
    weight: np.ndarray  # (3,) RGB
    sides: str = "both"
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    roughness: float = 0.0
    ior: float = 1.5
    anisotropy: float = 0.0
    fresnel: str = "constant"  # conductors: "constant" (colour) or "f82" (F0 = colour, edge tint)
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    # Shader program results (program_builder.Reg) driving lobe fields per shading point:
    # (field, register) pairs that set a field, and scalar registers scaling the weight.
    binds: tuple = ()
    scales: tuple = ()
    multiscatter: bool = False  # GGX lobes: Cycles' Multiscatter GGX energy compensation

    def same_closure(self, other: Term) -> bool:
        return (
            self.kind == other.kind
            and self.fresnel == other.fresnel
            and self.multiscatter == other.multiscatter
            and np.allclose(self.weight, other.weight, rtol=1e-6, atol=1e-9)
            and np.allclose(self.color, other.color, rtol=1e-6, atol=1e-9)
            and np.allclose(self.tint, other.tint, rtol=1e-6, atol=1e-9)
            and math.isclose(self.roughness, other.roughness, abs_tol=1e-9)
            and math.isclose(self.ior, other.ior, abs_tol=1e-9)
            and math.isclose(self.anisotropy, other.anisotropy, abs_tol=1e-9)
            and self.binds == other.binds
            and self.scales == other.scales
        )


VOLUME_KINDS = {"scatter", "absorb", "volume_emission"}


def side_terms(terms: list[Term], side: int) -> list[Term]:
    return [replace(term, sides=SIDE_NAMES[side]) for term in terms]


def merge_sides(front: list[Term], back: list[Term]) -> list[Term]:
    """Terms evaluated for each face: one two-sided list when both faces agree."""
    if len(front) == len(back) and all(f.same_closure(b) for f, b in zip(front, back)):
        return [replace(term, sides="both") for term in front]
    return side_terms(front, FRONT) + side_terms(back, BACK)


def restrict_to_side(term: Term, side: str) -> Term | None:
    """The part of `term` on faces `side`, or None if it has none there."""
    if term.sides == "both":
        return replace(term, sides=side)
    return replace(term) if term.sides == side else None


def scale_terms(terms: list[Term], factor: np.ndarray) -> list[Term]:
    """Multiply closure weights by a sided scalar (2, 1), splitting terms whose faces differ."""
    front, back = float(factor[FRONT, 0]), float(factor[BACK, 0])
    scaled = []
    for term in terms:
        if front == back:
            scaled.append(replace(term, weight=term.weight * front))
            continue
        for side, value in (("front", front), ("back", back)):
            part = restrict_to_side(term, side)
            if part is not None:
                scaled.append(replace(part, weight=part.weight * value))
    return [term for term in scaled if np.any(term.weight != 0.0)]


# ---------------------------------------------------------------------------- the graph as handlers see it


class ClosureGraph(ValueGraph, Protocol):
    """What a closure handler asks of the graph that evaluates it."""

    def closure(self, socket, scope: tuple = ()) -> list[Term]: ...


class Inputs:
    """Plain values of a node's inputs on one face (floats, or (3,) arrays for colours)."""

    def __init__(self, graph: ValueGraph, node, scope: tuple, side: int) -> None:
        self._graph, self.node, self._scope, self._side = graph, node, scope, side
        self._claimed: set[str] = set()

    def __call__(self, name: str):
        """The input's value; for an input claimed with varying(), its unlinked value (a
        placeholder: the program sets the field it drives)."""
        socket = self.node.inputs[name]
        if name in self._claimed:
            width = 3 if socket.type in ("RGBA", "VECTOR") else 1
            row = self._graph.unlinked_value(socket, width)[self._side]
        else:
            row = self._graph.input_value(socket, self._scope)[self._side]
        return float(row[0]) if row.shape[0] == 1 else row.copy()

    def varying(self, name: str):
        """The input's program register when a texture drives it (the caller binds it to a
        lobe field), else None. Graphs without programs (volumes) return None."""
        find = getattr(self._graph, "input_varying", None)
        reg = None if find is None else find(self.node.inputs[name], self._scope)
        if reg is not None:
            self._claimed.add(name)
        return reg

    @property
    def program(self):
        return self._graph.program

    def warn(self, problem: str) -> None:
        self._graph.warn_node(self.node, problem)


def saturate(value: float) -> float:
    return min(max(value, 0.0), 1.0)


# ---------------------------------------------------------------------------- shader nodes


def combine_mix(graph: ClosureGraph, node, scope: tuple) -> list[Term]:
    varying = getattr(graph, "input_varying", None)
    reg = None if varying is None else varying(node.inputs[0], scope)
    if reg is not None:
        return mix_by_program(graph, node, scope, reg)
    # Cycles clamps the mix factor to [0, 1].
    factor = np.clip(graph.input_value(node.inputs[0], scope), 0.0, 1.0)
    first = graph.closure(node.inputs[1], scope)
    second = graph.closure(node.inputs[2], scope)
    return scale_terms(first, 1.0 - factor) + scale_terms(second, factor)


def combine_add(graph: ClosureGraph, node, scope: tuple) -> list[Term]:
    return graph.closure(node.inputs[0], scope) + graph.closure(node.inputs[1], scope)


COMBINE_HANDLERS: dict[str, Callable[[ClosureGraph, object, tuple], list[Term]]] = {
    "ShaderNodeMixShader": combine_mix,
    "ShaderNodeAddShader": combine_add,
}


def rgb(value) -> tuple[float, float, float]:
    array = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,))
    return (float(array[0]), float(array[1]), float(array[2]))


def reflection_kind(roughness: float) -> str:
    # Cycles treats roughness 0 as a perfect mirror.
    return "conductor" if roughness <= 0.0 else "rough_conductor"


def warn_ignored_distribution(read: Inputs, node) -> bool:
    """Whether the node's microfacets are Multiscatter GGX (others are rendered as GGX)."""
    distribution = getattr(node, "distribution", "GGX")
    if distribution not in {"GGX", "MULTI_GGX"}:
        read.warn(f"{distribution} microfacets are rendered as GGX")
    return distribution == "MULTI_GGX"


def shader_diffuse(read: Inputs) -> list[Term]:
    if read("Roughness") > 0.0:
        read.warn("Roughness (Oren-Nayar) is ignored; Haze's diffuse lobe is Lambertian")
    binds = color_binds(read) + normal_bind(read)
    return [Term("diffuse", np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)), binds=binds)]


def shader_glossy(read: Inputs) -> list[Term]:
    node = read.node
    multiscatter = warn_ignored_distribution(read, node)
    if read("Anisotropy") != 0.0:
        read.warn("Anisotropy is ignored")
    binds = color_binds(read) + roughness_bind(read) + normal_bind(read)
    roughness = saturate(read("Roughness"))
    kind = "rough_conductor" if any(f == "roughness" for f, _ in binds) else reflection_kind(roughness)
    return [Term(kind, np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)), roughness=roughness,
                 binds=binds, multiscatter=multiscatter)]


def conductor_reflectance(cos: float, ior: np.ndarray, extinction: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex index n + ik seen from air."""
    n2, k2 = ior**2, extinction**2
    cos2 = cos * cos
    sin2 = 1.0 - cos2
    t = n2 - k2 - sin2
    a2b2 = np.sqrt(t * t + 4.0 * n2 * k2)
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t), 0.0))
    r_s = (a2b2 + cos2 - 2.0 * a * cos) / np.maximum(a2b2 + cos2 + 2.0 * a * cos, 1e-300)
    r_p = r_s * (cos2 * a2b2 + sin2 * sin2 - 2.0 * a * cos * sin2) / np.maximum(
        cos2 * a2b2 + sin2 * sin2 + 2.0 * a * cos * sin2, 1e-300)
    return 0.5 * (r_s + r_p)


F82_COS = 1.0 / 7.0  # about 82 degrees, where the F82-tint curve takes its tint


def conductor_as_f82(ior: np.ndarray, extinction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F0, edge tint) of the F82-tint curve through the conductor's exact reflectance at
    normal incidence and at cos = 1/7: an approximation of Cycles' Physical Conductor."""
    f0 = np.clip(conductor_reflectance(1.0, ior, extinction), 0.0, 1.0)
    schlick82 = f0 + (1.0 - f0) * (1.0 - F82_COS) ** 5
    tint = conductor_reflectance(F82_COS, ior, extinction) / schlick82
    return f0, np.clip(tint, 0.0, 1.0)


def shader_metallic(read: Inputs) -> list[Term]:
    """Cycles' Metallic BSDF: the F82-tint Fresnel of Base Color and Edge Tint, or (Physical
    Conductor) the exact Fresnel of a complex index, here fitted by an F82-tint curve."""
    node = read.node
    multiscatter = warn_ignored_distribution(read, node)
    if read("Anisotropy") != 0.0:
        read.warn("Anisotropy is ignored")
    if node.fresnel_type == "PHYSICAL_CONDUCTOR":
        f0, tint = conductor_as_f82(np.maximum(read("IOR"), 0.0), np.maximum(read("Extinction"), 0.0))
    else:
        f0 = np.clip(read("Base Color"), 0.0, 1.0)
        tint = np.clip(read("Edge Tint"), 0.0, 1.0)
    roughness = saturate(read("Roughness"))
    return [Term(reflection_kind(roughness), np.ones(3), color=rgb(f0), roughness=roughness, fresnel="f82",
                 tint=rgb(tint), multiscatter=multiscatter)]


def shader_glass(read: Inputs) -> list[Term]:
    roughness = saturate(read("Roughness"))
    if roughness > 0.0:
        read.warn(f"rough glass (Roughness {roughness:g}) is rendered as smooth glass")
    color = rgb(np.maximum(read("Color"), 0.0))
    binds = color_binds(read)
    binds += tuple(("tint", reg) for _, reg in binds)  # Glass BSDF tints reflection and refraction alike
    binds += ior_bind(read) + normal_bind(read)
    ior = max(read("IOR"), 1e-5)
    return [Term("dielectric", np.ones(3), color=color, ior=ior, tint=color, binds=binds)]


def shader_transparent(read: Inputs) -> list[Term]:
    binds = color_binds(read)
    return [Term("transparent", np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)), binds=binds)]


def shader_emission(read: Inputs) -> list[Term]:
    binds = emission_binds(read, "Color", "Strength")
    if binds:  # the program gives the radiance; the weight only marks the term as emitting
        return [Term("emission", np.ones(3), binds=binds)]
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


def adjusted_specular_ior(ior: float, level: float) -> float:
    """Cycles' Specular IOR Level: scales F0 by 2 x level and converts back to an IOR."""
    if level == 0.5:
        return ior
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    root = math.sqrt(min(max(f0, 0.0), 0.9999))
    eta = (1.0 + root) / (1.0 - root)
    return 1.0 / eta if ior < 1.0 else eta


def shader_background(read: Inputs) -> list[Term]:
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


def warn_phase(read: Inputs) -> None:
    phase = getattr(read.node, "phase", "HENYEY_GREENSTEIN")
    if phase != "HENYEY_GREENSTEIN":
        read.warn(f"{phase} phase function is rendered as Henyey-Greenstein with the node's Anisotropy")


def volume_density(read: Inputs) -> tuple[float, tuple]:
    """(density, binds): the Density input's value, or 1 and a ("density", register) bind
    when a program drives it (a procedural medium: materials.volume_medium)."""
    reg = read.varying("Density")
    if reg is not None:
        return 1.0, (("density", reg),)
    return max(read("Density"), 0.0), ()


def shader_volume_scatter(read: Inputs) -> list[Term]:
    warn_phase(read)
    density, binds = volume_density(read)
    sigma_s = np.broadcast_to(np.asarray(read("Color")) * density, (3,)).astype(np.float64)
    return [Term("scatter", sigma_s, anisotropy=read("Anisotropy"), binds=binds)]


def shader_volume_absorption(read: Inputs) -> list[Term]:
    density, binds = volume_density(read)
    sigma_a = np.maximum((1.0 - np.asarray(read("Color"))) * density, 0.0)
    return [Term("absorb", np.broadcast_to(sigma_a, (3,)).astype(np.float64), binds=binds)]


def shader_volume_coefficients(read: Inputs) -> list[Term]:
    warn_phase(read)
    return [
        Term("scatter", np.maximum(read("Scatter Coefficients"), 0.0), anisotropy=read("Anisotropy")),
        Term("absorb", np.maximum(read("Absorption Coefficients"), 0.0)),
        Term("volume_emission", np.asarray(read("Emission Coefficients"), dtype=np.float64)),
    ]


def shader_principled_volume(read: Inputs) -> list[Term]:
    """Cycles' Principled Volume (svm_node_principled_volume); a program-driven Density
    binds both coefficients to it (emission does not scale with density)."""
    density, binds = volume_density(read)
    color = np.asarray(read("Color"), dtype=np.float64)
    absorption_color = np.sqrt(np.maximum(read("Absorption Color"), 0.0))
    absorption = np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption_color, 0.0)
    emission = read("Emission Strength") * np.asarray(read("Emission Color"), dtype=np.float64)
    if read("Blackbody Intensity") > 0.0:
        read.warn("blackbody emission is not supported on mesh volumes and is ignored")
    terms = [
        Term("scatter", color * density, anisotropy=read("Anisotropy"), binds=binds),
        Term("absorb", absorption * density, binds=binds),
    ]
    if read("Emission Strength") > 0.0:
        terms.append(Term("volume_emission", np.broadcast_to(emission, (3,)).astype(np.float64)))
    return terms


def shader_volume_emission(read: Inputs) -> list[Term]:
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("volume_emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


CLOSURE_HANDLERS: dict[str, Callable[[Inputs], list[Term]]] = {
    "ShaderNodeBsdfDiffuse": shader_diffuse,
    "ShaderNodeBsdfGlossy": shader_glossy,
    "ShaderNodeBsdfAnisotropic": shader_glossy,
    "ShaderNodeBsdfMetallic": shader_metallic,
    "ShaderNodeBsdfGlass": shader_glass,
    "ShaderNodeBsdfTransparent": shader_transparent,
    "ShaderNodeEmission": shader_emission,
    "ShaderNodeBackground": shader_background,
    "ShaderNodeVolumeScatter": shader_volume_scatter,
    "ShaderNodeVolumeAbsorption": shader_volume_absorption,
    "ShaderNodeVolumeCoefficients": shader_volume_coefficients,
    "ShaderNodeVolumePrincipled": shader_principled_volume,
}


def as_volume_terms(terms: list[Term]) -> list[Term]:
    """Terms reaching a Volume socket. Emission there is a volume source (per unit length)."""
    return [replace(t, kind="volume_emission") if t.kind == "emission" else t for t in terms]


def fallback_closure(graph: ValueGraph, node, scope: tuple) -> list[Term]:
    """A closure Haze has no model for, rendered as a Diffuse BSDF of its Color input (warned)."""
    graph.warn_node(
        node,
        f"{node.bl_label} shaders are not supported by Haze; rendered as a Diffuse BSDF of its Color",
    )
    if "Color" not in node.inputs:
        return [Term("diffuse", np.ones(3), color=(0.8, 0.8, 0.8))]
    front = Inputs(graph, node, scope, FRONT)("Color")
    back = Inputs(graph, node, scope, BACK)("Color")
    return merge_sides(
        [Term("diffuse", np.ones(3), color=tuple(np.atleast_1d(front) * np.ones(3)))],
        [Term("diffuse", np.ones(3), color=tuple(np.atleast_1d(back) * np.ones(3)))],
    )
