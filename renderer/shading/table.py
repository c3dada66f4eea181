"""The scene's shader programs as the kernels read them: every material's program
concatenated into flat tables, with its attribute, image and data references made global.

ShadingTables.arrays is the tuple the interpreter takes (interpreter.run_program):
    progs   int32 (M, PROG.size)   per material: where its code, registers and bindings are;
                                   ncode = -1 for a material without a program
    code    int32 (I, INSTR.size)
    init    float32 (R,)           initial registers of all programs
    data    float32 (D,)           tables (colour ramps, curves)
    binds   int32 (B, BIND.size)
    corner  float32 (T, 3, A)      corner attributes of every triangle (A columns, >= 1)
    texels  float32 (P, 4)         every image's RGBA texels
    images  int32 (N, 4)           per image: first texel, width, height, sRGB-encoded (0/1)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.errors import SceneError
from renderer.layout import Layout

from .bump import CORNER_POSITION
from .program import BIND, BIND_FIELDS, I_P0, I_P1, INSTR, OP

PROG = Layout("prog", [("code", 1), ("ncode", 1), ("init", 1), ("nregs", 1), ("bind", 1), ("nbind", 1)])
P_CODE, P_NCODE, P_INIT = PROG.offset("code"), PROG.offset("ncode"), PROG.offset("init")
P_NREGS, P_BIND, P_NBIND = PROG.offset("nregs"), PROG.offset("bind"), PROG.offset("nbind")


@dataclass
class ShadingTables:
    arrays: tuple
    max_registers: int  # the largest register file of any program
    max_lobes: int  # lobes of the largest material with a program
    emission: bool = False  # some program drives its surface's emission (integrator.program_stage)


def attribute_width(name: str) -> int:
    return 2 if name.startswith("uv:") else 3


def build_shading_tables(materials, meshes, images, triangles: int) -> ShadingTables | None:
    """None when no material has a program: the scene then compiles and pays nothing."""
    if not any(m.program is not None for m in materials):
        return None
    image_index = {image.name: k for k, image in enumerate(images)}
    columns: dict[str, int] = {}
    for m in materials:
        for name in (m.program.attributes if m.program else []):
            if name not in columns:
                columns[name] = sum(attribute_width(n) for n in columns)
    progs = np.full((len(materials), PROG.size), 0, np.int32)
    progs[:, P_NCODE] = -1
    code, init, data, binds = [], [], [], []
    counts = [0, 0, 0, 0]  # instructions, registers, data, bindings so far
    for k, m in enumerate(materials):
        prog = m.program
        if prog is None:
            continue
        c = np.array(prog.code, np.int32).reshape(-1, INSTR.size).copy()
        for row in c:
            if row[0] == OP["attribute"]:
                name = prog.attributes[row[I_P0]]
                row[I_P0], row[I_P1] = columns[name], min(int(row[I_P1]), attribute_width(name))
            elif row[0] == OP["image"]:
                name = prog.images[row[I_P0]]
                if name not in image_index:
                    raise SceneError(f"materials[{k}].program", f"reads image {name!r}, not in the scene")
                row[I_P0] = image_index[name]
            elif row[0] in (OP["bump_eval"], OP["bump"]):
                row[I_P1] = columns[prog.attributes[row[I_P1]]]
            elif row[0] in (OP["ramp"], OP["curve"]):
                row[I_P0] += counts[2]
        progs[k] = (counts[0], len(c), counts[1], len(prog.registers), counts[3], len(prog.bindings))
        code.append(c)
        init.append(np.asarray(prog.registers, np.float32))
        data.append(np.asarray(prog.data, np.float32))
        binds.append(np.array(prog.bindings, np.int32).reshape(-1, BIND.size))
        for j, n in enumerate((len(c), len(prog.registers), len(prog.data), len(prog.bindings))):
            counts[j] += n
    corner = np.zeros((max(triangles, 1), 3, max(1, sum(attribute_width(n) for n in columns))), np.float32)
    start = 0
    for mesh in meshes:
        count = np.asarray(mesh.indices).reshape(-1, 3).shape[0]
        if CORNER_POSITION in columns:  # the triangles' world-space corners (Bump's tangent frame)
            triangles_xyz = np.asarray(mesh.vertices, np.float32)[np.asarray(mesh.indices).reshape(-1, 3)]
            col = columns[CORNER_POSITION]
            corner[start:start + count, :, col:col + 3] = triangles_xyz
        for attribute in mesh.attributes:
            if attribute.name in columns:
                values = np.asarray(attribute.values, np.float32).reshape(count, 3, -1)
                col = columns[attribute.name]
                width = min(values.shape[2], attribute_width(attribute.name))
                corner[start:start + count, :, col:col + width] = values[:, :, :width]
        start += count
    texels = [np.asarray(im.pixels, np.float32).reshape(-1, 4) for im in images]
    texels = texels or [np.zeros((1, 4), np.float32)]
    firsts = np.cumsum([0] + [t.shape[0] for t in texels])[:-1]
    image_rows = np.array([(f, im.pixels.shape[1], im.pixels.shape[0], int(im.srgb))
                           for f, im in zip(firsts, images)] or np.zeros((1, 4)), np.int32).reshape(-1, 4)
    data.append(np.zeros(1, np.float32))  # never empty
    arrays = (progs, np.concatenate(code), np.concatenate(init), np.concatenate(data), np.concatenate(binds),
              corner, np.ascontiguousarray(np.concatenate(texels)), image_rows)
    max_lobes = max(len(m.lobes) for m in materials if m.program is not None)
    emission = bool(np.any(arrays[4][:, BIND.offset("field")] == BIND_FIELDS.index("emission")))
    max_registers = max(1, int(progs[:, PROG.offset("nregs")].max()))
    return ShadingTables(arrays, max_registers, max(1, max_lobes), emission)
