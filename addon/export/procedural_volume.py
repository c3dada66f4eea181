"""Procedural mesh volumes: a material whose Volume output's Density is driven by textures
becomes, per object that uses it, a procedural grid medium (renderer.media.procedural)
over the object's bounding box.

The material compiles once into a template program over the surface opcodes; what is per
object is where "Object" and "Generated" coordinates come from. A surface program reads them
as corner attributes; inside a volume they are affine functions of the world position (Cycles:
object_inverse_position_transform, then the texture space for Generated,
geom/volume.h volume_normalized_position), so each such `attribute` instruction is replaced
by position -> three dot products with the rows of that object's affine map -> plus its
offsets, written to the same registers.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from renderer.scene import Medium
from renderer.shading.names import MATH_OPS, VECTOR_OPS
from renderer.shading.program import INSTR, OP, ShaderProgram

from .node_closures import Term

# Coordinates a volume program can have; the attribute names are program_builder's.
VOLUME_ATTRIBUTES = ("object", "generated")
# Grow the object's box by this share of its size so that the mesh's surface, where rays
# enter the medium, is inside the box after rounding.
BOX_PAD = 1e-4


def density_register(terms: list[Term]) -> int | None:
    """The one register every coefficient term's density is bound to, or None when the
    terms are not a procedural medium Haze can render (no binding, several densities, a
    textured colour or mix factor, or coefficients with and without the density)."""
    regs = set()
    for t in terms:
        if t.scales or any(field != "density" for field, _ in t.binds):
            return None
        if t.kind in ("scatter", "absorb"):
            regs.add(tuple(reg.index for _, reg in t.binds))
    if len(regs) != 1:
        return None
    (only,) = regs
    return only[0] if len(only) == 1 else None


def reads_only_coordinates(program: ShaderProgram) -> bool:
    return all(name in VOLUME_ATTRIBUTES for name in program.attributes)


def _row(op: str, dst: int, a: int = 0, b: int = 0, c: int = 0, d: int = 0, i0: int = 0,
         i1: int = 0) -> np.ndarray:
    row = np.zeros(INSTR.size, np.int32)
    row[:10] = (OP[op], dst, a, b, c, d, 0, i0, i1, 0)
    return row


def object_program(template: ShaderProgram, affines: dict[str, np.ndarray]) -> ShaderProgram:
    """`template` with its Object / Generated coordinate reads replaced by `affines[name]`
    (3 x 4, world position -> coordinates) applied to the position."""
    registers = list(np.asarray(template.registers, np.float32))

    def alloc(values) -> int:
        registers.extend(float(v) for v in values)
        return len(registers) - len(values)

    zero = alloc([0.0])
    code = []
    for row in np.asarray(template.code, np.int32).reshape(-1, INSTR.size):
        if row[0] != OP["attribute"]:
            code.append(row)
            continue
        m = affines[template.attributes[row[INSTR.offset("i0")]]]
        dst = int(row[1])
        pos = alloc([0.0] * 3)
        dots = alloc([0.0] * 3)
        code.append(_row("position", pos))
        for k in range(3):
            axis = alloc(m[k, :3])
            offset = alloc([m[k, 3]])
            code.append(_row("vector_math", dots + k, pos, axis, pos, zero,
                             i0=VECTOR_OPS.index("DOT_PRODUCT"), i1=1))
            code.append(_row("math", dst + k, dots + k, offset, zero, i0=MATH_OPS.index("ADD")))
    return ShaderProgram(np.array(code, np.int32).reshape(-1, INSTR.size), np.array(registers, np.float32),
                         np.zeros((0, 5), np.int32), np.asarray(template.data, np.float32))


def coordinate_affines(matrix_world: np.ndarray, texspace_location, texspace_size) -> dict[str, np.ndarray]:
    """World position -> Object and Generated coordinates of an object (3 x 4 each)."""
    to_object = np.linalg.inv(np.asarray(matrix_world, np.float64))[:3, :]
    location = np.asarray(texspace_location, np.float64)
    size = np.asarray(texspace_size, np.float64)
    size = np.where(size != 0.0, size, 1.0)
    # Generated = (object - (location - size)) / (2 size), as mesh.corner_attribute
    generated = to_object / (2.0 * size)[:, None]
    generated[:, 3] += (size - location) / (2.0 * size)
    return {"object": to_object, "generated": generated}


def object_medium(template: Medium, name: str, matrix_world: np.ndarray, local_vertices: np.ndarray,
                  texspace_location, texspace_size) -> Medium:
    """The procedural medium of one object: `template` (a material's, program with
    coordinate reads) over the object's local bounding box."""
    lo = local_vertices.min(axis=0).astype(np.float64)
    hi = local_vertices.max(axis=0).astype(np.float64)
    pad = BOX_PAD * np.maximum(hi - lo, 1e-6) + 1e-6
    program = object_program(template.program, coordinate_affines(matrix_world, texspace_location,
                                                                   texspace_size))
    return replace(template, name=name, p0=tuple(lo - pad), p1=tuple(hi + pad),
                   to_world=np.asarray(matrix_world, np.float64), program=program)
