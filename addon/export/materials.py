"""Blender materials and world shaders to Haze Materials and Media (Cycles' semantics).

Rules that follow from how Cycles shades (see docs/blender.md):

* Surface linked: the surface is opaque wherever no lobe exists. Cycles terminates a path on
  a face side that has no BSDF (e.g. the back of a one-sided emitter), so Haze gets a black
  diffuse lobe there; a material without lobes would otherwise be an invisible interface.
* Surface unlinked but Volume linked: an invisible boundary enclosing the medium.
* Neither linked (or no output node): black, as in Cycles.
* No node tree: a diffuse surface of the material's viewport colour.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from renderer.scene import LOBE_KINDS, Lobe, Material, Medium
from renderer.shading.names import VECTOR_OPS
from renderer.shading.program import BIND_FIELDS, BIND_SCALE, BIND_SET

from .images import ImageLibrary
from .messages import Messages, material_subject
from .node_closures import VOLUME_KINDS, Term, as_volume_terms, rgb
from .node_program_normals import displacement_bump
from .nodes import ShaderGraph
from .procedural_volume import density_register, reads_only_coordinates

DEFAULT_MATERIAL_NAME = "Haze Default Surface"
MAX_ANISOTROPY = 1.0 - 1e-3  # Cycles clamps Henyey-Greenstein g to this magnitude
BLACK = (0.0, 0.0, 0.0)


def default_material() -> Material:
    """Cycles' surface for objects without a material, or with an empty slot. In Blender 5.0
    that is a new material's Principled BSDF as it comes (Base Color 0.8, Roughness 0.5,
    IOR 1.5, Specular IOR Level 0.5, Multiscatter GGX): Cycles renders the two identically.
    Written out here because an export must not create a material in the user's file;
    tests/test_addon_export.py checks it against the conversion of bpy.data.materials.new()."""
    grey = float(np.float32(0.8))  # Blender stores the socket's 0.8 as float32
    principled = Term("plastic", np.ones(3), color=(grey, grey, grey), roughness=0.5, ior=1.5,
                      multiscatter=True)
    return surface_material(DEFAULT_MATERIAL_NAME, [principled], Messages())


def medium_name(owner_name: str) -> str:
    return f"{owner_name} (volume)"


def side_covered(lobes: list[Lobe], side: str) -> bool:
    return any(lobe.sides in (side, "both") for lobe in lobes)


def close_open_sides(lobes: list[Lobe]) -> list[Lobe]:
    """Add black diffuse lobes on face sides no lobe covers, so those sides stay opaque."""
    missing = [side for side in ("front", "back") if not side_covered(lobes, side)]
    if len(missing) == 2:
        return lobes + [Lobe("diffuse", color=BLACK, sides="both")]
    return lobes + [Lobe("diffuse", color=BLACK, sides=side) for side in missing]


def lobe_from_term(term: Term) -> Lobe:
    return Lobe(kind=term.kind, weight=rgb(term.weight), color=rgb(term.color),
                roughness=float(term.roughness), ior=float(term.ior), sides=term.sides,
                fresnel=term.fresnel, tint=rgb(term.tint), multiscatter=bool(term.multiscatter))


def emission_per_side(terms: list[Term]) -> tuple[np.ndarray, np.ndarray]:
    front, back = np.zeros(3), np.zeros(3)
    for term in terms:
        if term.kind != "emission":
            continue
        if term.sides in ("front", "both"):
            front += term.weight
        if term.sides in ("back", "both"):
            back += term.weight
    return front, back


def choose_emission(front: np.ndarray, back: np.ndarray, subject: str, messages: Messages):
    """One emission value and its sides; Haze cannot emit different colours on each side."""
    if np.allclose(front, back):
        return rgb(front), "both"
    if not np.any(back):
        return rgb(front), "front"
    if not np.any(front):
        return rgb(back), "back"
    messages.warn(subject, "emission differs between front and back faces; the front value is used on both")
    return rgb(front), "both"


def program_bindings(lobe_terms: list[Term]) -> list[tuple[int, int, int, int, int]]:
    """Rows of ShaderProgram.bindings for the lobes made from `lobe_terms`, in order. A
    bound Normal is the material's (one row, lobe -1: see renderer.shading.program)."""
    rows = []
    for lobe, term in enumerate(lobe_terms):
        for field, reg in term.binds:
            if field == "normal":
                if not any(row[1] == BIND_FIELDS.index(field) for row in rows):
                    rows.append((-1, BIND_FIELDS.index(field), 3, reg.index, BIND_SET))
                continue
            rows.append((lobe, BIND_FIELDS.index(field), reg.width, reg.index, BIND_SET))
        for reg in term.scales:
            rows.append((lobe, BIND_FIELDS.index("weight"), 3, reg.index, BIND_SCALE))
    return rows


def program_emission(terms: list[Term], sides: str, program) -> tuple[int, int, int, int, int]:
    """The binding row of a varying emission: the program sums the emission terms on
    `sides` (each its radiance register or constant weight, times its scale registers)."""
    side_terms = [t for t in terms if t.kind == "emission" and t.sides in (sides, "both")]
    one, total = program.const(1.0), None
    multiply, add = VECTOR_OPS.index("MULTIPLY"), VECTOR_OPS.index("ADD")
    for term in side_terms:
        reg = dict(term.binds).get("emission") or program.const(term.weight)
        for scale in term.scales:
            reg = program.emit("vector_math", 3, reg, program.widen(scale), reg, one, i0=multiply)
        total = reg if total is None else program.emit("vector_math", 3, total, reg, reg, one, i0=add)
    return (-1, BIND_FIELDS.index("emission"), 3, total.index, BIND_SET)


def surface_material(name: str, terms: list[Term], messages: Messages, program=None) -> Material:
    """`program` (a ProgramBuilder) holds the registers the terms' bindings name. A varying
    emission gets Material.emission 1 (what light sampling weighs the emitter by) and a
    binding that sets the radiance per shading point (renderer.shading.program)."""
    subject = material_subject(name)
    if any(term.kind in VOLUME_KINDS for term in terms):
        messages.warn(subject, "a volume shader connected to the Surface output is ignored (as in Cycles)")
    lobe_terms = [t for t in terms if t.kind in LOBE_KINDS and np.any(t.weight != 0.0)]
    lobes = [lobe_from_term(t) for t in lobe_terms]
    emission, emission_sides = choose_emission(*emission_per_side(terms), subject, messages)
    bindings = program_bindings(lobe_terms)
    if len({reg for t in lobe_terms for field, reg in t.binds if field == "normal"}) > 1:
        messages.warn(subject, "closures with different Normal inputs share the first one")
    if program is not None and any(t.kind == "emission" and (t.binds or t.scales) for t in terms):
        sides = "front" if emission_sides == "both" else emission_sides
        bindings.append(program_emission(terms, sides, program))
        emission = (1.0, 1.0, 1.0)
    shader = program.build(bindings) if program is not None and bindings else None
    return Material(name, lobes=close_open_sides(lobes), emission=emission, emission_sides=emission_sides,
                    program=shader)


def mean_anisotropy(scatter: list[Term], subject: str, messages: Messages) -> float:
    """Henyey-Greenstein g of several scattering closures, weighted by their scattering."""
    weights = np.array([float(np.mean(t.weight)) for t in scatter])
    values = np.array([t.anisotropy for t in scatter])
    if len(set(np.round(values, 6))) > 1:
        messages.warn(subject, "volume closures with different Anisotropy are combined into one mean value")
    g = float(np.sum(weights * values) / np.sum(weights)) if np.sum(weights) > 0 else float(values[0])
    return float(np.clip(g, -MAX_ANISOTROPY, MAX_ANISOTROPY))


def volume_medium(name: str, terms: list[Term], messages: Messages, subject: str) -> Medium | None:
    """A homogeneous Medium named `name` from volume closure terms, or None if they add up to
    nothing. `subject` names the Blender datablock in warnings."""
    if any(term.kind in LOBE_KINDS or term.kind == "emission" for term in terms):
        messages.warn(subject, "a surface shader connected to the Volume output is ignored (as in Cycles)")
    scatter = [t for t in terms if t.kind == "scatter"]
    sigma_s = sum((t.weight for t in scatter), np.zeros(3))
    sigma_a = sum((t.weight for t in terms if t.kind == "absorb"), np.zeros(3))
    emission = sum((t.weight for t in terms if t.kind == "volume_emission"), np.zeros(3))
    if not (np.any(sigma_s) or np.any(sigma_a) or np.any(emission)):
        return None
    g = mean_anisotropy(scatter, subject, messages) if scatter else 0.0
    return Medium(name, sigma_a=rgb(np.maximum(sigma_a, 0.0)),
                  sigma_s=rgb(np.maximum(sigma_s, 0.0)), g=g, emission=rgb(emission))


def procedural_medium(name: str, terms: list[Term], graph: ShaderGraph, messages: Messages,
                      subject: str) -> Medium | None:
    """A procedural template Medium (program reading Object / Generated coordinates, no
    box yet: procedural_volume.object_medium places it per object), or None when the
    terms' programs are not a density Haze can render as one."""
    reg = density_register(terms)
    if reg is None or not reads_only_coordinates(graph.program.build([])):
        return None
    plain = [replace(t, binds=()) for t in terms]
    medium = volume_medium(name, plain, messages, subject)
    if medium is None:
        return None
    return replace(medium, type="grid", program=graph.program.build([]), program_density=reg)


def convert_volume(tree, output, messages: Messages, subject: str, name: str,
                   programs: bool) -> Medium | None:
    """The medium of a material's Volume output: procedural when textures drive the Density
    (and nothing else varies), else homogeneous with every input folded to a constant."""
    socket = output.inputs["Volume"]
    if programs:
        quiet = Messages()
        graph = ShaderGraph(subject, quiet, None)
        graph.programs = True
        terms = as_volume_terms(graph.closure(socket))
        if any(t.binds for t in terms):
            medium = procedural_medium(name, terms, graph, quiet, subject)
            if medium is not None:
                for warning in quiet.warnings:
                    messages.warn(*warning.split(": ", 1))
                return medium
    graph = ShaderGraph(subject, messages, None)
    graph.programs = False
    return volume_medium(name, as_volume_terms(graph.closure(socket)), messages, subject)


class MaterialExport:
    """One Blender material converted: its surface and, if it has one, its medium."""

    def __init__(self, material: Material, medium: Medium | None) -> None:
        self.material = material
        self.medium = medium


def viewport_color_material(blender_material) -> Material:
    color = tuple(float(c) for c in blender_material.diffuse_color[:3])
    return Material(blender_material.name_full, lobes=[Lobe("diffuse", color=color)])


def uses_nodes(datablock) -> bool:
    """The "Use Nodes" switch of Blender < 5.0 (5.0 always uses nodes and deprecates it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return bool(getattr(datablock, "use_nodes", True))


def active_output(node_tree):
    """The output node Cycles uses (active, target All or Cycles)."""
    return node_tree.get_output_node("CYCLES") if node_tree is not None else None


def convert_material(blender_material, messages: Messages,
                     images: ImageLibrary | None = None) -> MaterialExport:
    name = blender_material.name_full
    subject = material_subject(name)
    tree = blender_material.node_tree
    if tree is None or not uses_nodes(blender_material):
        return MaterialExport(viewport_color_material(blender_material), None)
    output = active_output(tree)
    if output is None:
        messages.warn(subject, "has no active Material Output node; rendered black (as in Cycles)")
        return MaterialExport(Material(name, lobes=close_open_sides([])), None)
    graph = ShaderGraph(subject, messages, images)
    graph.pass_index = blender_material.pass_index
    medium = convert_volume(tree, output, messages, subject, medium_name(name), images is not None)
    if graph.link_source(output.inputs["Surface"]) is None and medium is not None:
        return MaterialExport(Material(name), medium)  # invisible boundary of the medium
    surface = graph.closure(output.inputs["Surface"])
    surface = displaced_as_bump(blender_material, graph, output, surface, messages, subject)
    return MaterialExport(surface_material(name, surface, messages, graph.program), medium)


def displaced_as_bump(blender_material, graph: ShaderGraph, output, terms: list[Term], messages: Messages,
                      subject: str) -> list[Term]:
    """The surface terms with the Displacement output's bump (Cycles' default method, Bump
    Only) as the normal of every lobe without a Normal input of its own."""
    socket = output.inputs["Displacement"]
    if graph.link_source(socket) is None:
        return terms
    method = getattr(blender_material, "displacement_method", "BUMP")
    if method != "BUMP":
        messages.warn(subject, f"displacement method {method.replace('_', ' ').lower()} is rendered as "
                      "Bump Only (the mesh is not displaced)")
    if not graph.programs:
        return terms
    normal = displacement_bump(graph, socket)
    if normal is None:
        return terms
    if any(field == "normal" for t in terms for field, _ in t.binds):
        messages.warn(subject, "the displacement's bump is not combined with a closure's own Normal "
                      "input; that Normal is used")
        return terms
    return [replace(t, binds=t.binds + (("normal", normal),)) if t.kind in LOBE_KINDS else t for t in terms]


class MaterialLibrary:
    """Converts each Blender material once and collects the scene's Materials and Media."""

    def __init__(self, messages: Messages) -> None:
        self.messages = messages
        self._by_name: dict[str, MaterialExport] = {}
        self._default: Material | None = None
        self.extra_materials: list[Material] = []  # e.g. area-light emitters
        self.images = ImageLibrary(messages)  # what the shader programs read

    def get(self, blender_material) -> MaterialExport:
        if blender_material is None:
            return MaterialExport(self.default(), None)
        name = blender_material.name_full
        if name not in self._by_name:
            self._by_name[name] = convert_material(blender_material, self.messages, self.images)
        return self._by_name[name]

    def default(self) -> Material:
        if self._default is None:
            self._default = default_material()
        return self._default

    def add(self, material: Material) -> None:
        self.extra_materials.append(material)

    def materials(self, used: set[str]) -> list[Material]:
        candidates = [entry.material for entry in self._by_name.values()] + self.extra_materials
        if self._default is not None:
            candidates.append(self._default)
        return [m for m in candidates if m.name in used]

    def medium_by_material(self) -> dict[str, str | None]:
        """Name of the medium each converted material encloses (None for none)."""
        return {e.material.name: (e.medium.name if e.medium else None) for e in self._by_name.values()}

    def media(self, used: set[str]) -> list[Medium]:
        return [e.medium for e in self._by_name.values() if e.medium is not None and e.medium.name in used]
