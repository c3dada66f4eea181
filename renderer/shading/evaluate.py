"""Run one material's program at given points from Python (tests, tools, the export of
world programs, procedural.evaluate_density): a jitted entry around the interpreter. The
render kernels do not call it: they call the interpreter through its address
(interpreter.program_entry, renderer.kernels.native_call)."""

from __future__ import annotations

import numpy as np

from renderer.kernels import kernel

from .interpreter import run_program


@kernel
def evaluate_points(st, m, tri, bary, x, n, regs, first, width, out):
    # int64 indices and a bool variable (not a literal) for back: one compile of the
    # interpreter per table type. Barycentrics and points stay float32 here (float() keeps
    # float32 in numba), as the bake tests pin them against Cycles.
    back = tri.shape[0] < 0
    for k in range(tri.shape[0]):
        pos = (float(x[k, 0]), float(x[k, 1]), float(x[k, 2]))
        nrm = (float(n[k, 0]), float(n[k, 1]), float(n[k, 2]))
        # As in Cycles' baking, the view direction is the normal (front face).
        b0, b1, b2 = float(bary[k, 0]), float(bary[k, 1]), float(bary[k, 2])
        run_program(st, m, regs, np.int64(tri[k]), b0, b1, b2, pos, nrm, nrm, back)
        for c in range(width):
            out[k, c] = regs[first + c]


def evaluate_program(tables, material: int, register: int, width: int, triangles: np.ndarray,
                     barycentrics: np.ndarray, positions: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(K, width) float32: registers register .. register + width - 1 after running material
    `material`'s program at K points (triangle index, barycentrics (K, 3), world position
    and shading normal (K, 3)); `tables` is a renderer.shading.table.ShadingTables."""
    k = len(triangles)
    out = np.zeros((k, width), np.float32)
    regs = np.zeros(tables.max_registers, np.float32)
    evaluate_points(tables.arrays, np.int64(material), np.asarray(triangles, np.int32),
                    np.asarray(barycentrics, np.float32), np.asarray(positions, np.float32),
                    np.asarray(normals, np.float32), regs, np.int64(register), np.int64(width), out)
    return out
