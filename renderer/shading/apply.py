"""A shader program applied at a hit: run it, and write a private copy of the material's
lobes with the program's results in the bound fields (program.py) into a scratch material.
The program stages (renderer.integrator.program_stage) call apply_program for every path or
shadow ray that hit a material with a program; the surface stage then shades the scratch
material instead of the triangle's.

The extended table is the scene's (mats, lobes) followed by one scratch material per path
slot and `max_lobes` scratch lobes per slot (scratch_table).

A program may also drive the surface's emission (binding field "emission"): apply_program
returns the emitted radiance, which the surface stage uses instead of the light table's
value. The table holds Material.emission = 1 for such an emitter (radiance 1 per channel: it
only weighs the emitter in light sampling), so the program's radiance is the factor to scale
the table's radiance by (the program stage does the same at light sampling points). A
program driving the shading normal (field "normal") returns it on the front side of the
geometric normal, as the surface stage keeps it (zero: the mesh's own normal).
"""

import math

import numpy as np

from renderer.bsdfs.layout import LOBE, M_COUNT, M_FIRST, MATERIAL
from renderer.kernels import inline_kernel
from renderer.kernels.native_call import call_native
from renderer.kernels.vecmath import add, dot, madd, neg, normalize, scale

from .program import BIND, BIND_SCALE
from .table import P_BIND, P_NBIND

B_LOBE, B_FIELD, B_WIDTH, B_REG, B_MODE = (BIND.offset(f) for f in ("lobe", "field", "width", "reg", "mode"))
# Offsets of program.BIND_FIELDS in a lobe row, and the valid range of each.
# F_EMISSION and F_NORMAL have no lobe offset (its binding writes the path's emission, not a lobe).
FIELD_OFFSETS = np.array([LOBE.offset(f) for f in ("weight", "color", "roughness", "ior", "tint")] + [0, 0],
                         np.int32)
F_WEIGHT, F_COLOR, F_ROUGHNESS, F_IOR, F_TINT, F_EMISSION, F_NORMAL = 0, 1, 2, 3, 4, 5, 6


def scratch_table(mt: tuple, batch: int, max_lobes: int) -> tuple:
    """The material table with room for one program-evaluated material per path slot."""
    mats, lobes = mt
    ext_mats = np.zeros((mats.shape[0] + batch, MATERIAL.size), np.int32)
    ext_mats[:mats.shape[0]] = mats
    ext_lobes = np.zeros((lobes.shape[0] + batch * max_lobes, LOBE.size), np.float32)
    ext_lobes[:lobes.shape[0]] = lobes
    return ext_mats, ext_lobes


@inline_kernel
def load3(a, i):
    """Row i of an (n, 3) array as a float64 3-tuple (as integrator.paths.load3, which
    shading/ does not import: the integrator imports shading)."""
    return (np.float64(a[i, 0]), np.float64(a[i, 1]), np.float64(a[i, 2]))


@inline_kernel
def _finite(v, lo, hi):
    """v limited to [lo, hi]; NaN gives lo (a program's extreme output stays renderable)."""
    return min(max(v, lo), hi) if v == v else lo


@inline_kernel
def _bind(lobes, row, field, width, regs, reg, mode, field_offsets):
    lo = 1e-5 if field == F_IOR else 0.0
    hi = 1.0 if field == F_ROUGHNESS or field == F_TINT else 3.0e38
    o = field_offsets[field]
    for ch in range(width):
        if mode == BIND_SCALE:
            v = lobes[row, o + ch] * _finite(float(regs[reg]), 0.0, 1.0)
        else:
            v = float(regs[reg + ch])
        lobes[row, o + ch] = _finite(v, lo, hi)


@inline_kernel
def _shading_normal(geo, p, b0, b1, b2, ng):
    n = normalize(add(add(scale(load3(geo.sn[p], 0), b0), scale(load3(geo.sn[p], 1), b1)),
                      scale(load3(geo.sn[p], 2), b2)))
    return neg(n) if dot(n, ng) < 0.0 else n


@inline_kernel
def _f64(v):
    return (np.float64(v[0]), np.float64(v[1]), np.float64(v[2]))


@inline_kernel
def hit_point(geo, p, b1, b2):
    """World position of barycentrics (b1, b2) on triangle p."""
    return madd(madd(load3(geo.v0, p), load3(geo.e1, p), b1), load3(geo.e2, p), b2)


@inline_kernel
def apply_program(geo, st, mt, regs, entry, p, m, b1, b2, d, row, first, field_offsets):
    """Run material m's program where direction d meets triangle p at barycentrics (b1, b2),
    write the material with the program's results into scratch material `row` (its lobes
    from `first`), and return the emission factor (program.py: the emission binding's
    registers, (1, 1, 1) without one) and the shading normal on the front side of the
    geometric normal ((0, 0, 0) without a normal binding). The normal is the program's as it
    is; the surface stage gives each lobe its own from it (renderer.bsdfs.closure_normals)."""
    mats, lobes = mt
    progs, binds = st[0], st[4]
    b0 = 1.0 - b1 - b2
    x = hit_point(geo, p, b1, b2)
    ng = load3(geo.ng, p)
    back = dot(d, ng) > 0.0
    sn = _shading_normal(geo, p, b0, b1, b2, ng)
    # Cycles' sd->N faces the side the ray came from.
    wi = neg(d)
    side_n = neg(sn) if back else sn
    # The interpreter through its address (interpreter.program_entry), with the types it was
    # compiled for: float() would keep a float32 in numba, hence np.float64.
    call_native(entry, (st, np.int64(m), regs, np.int64(p), np.float64(b0), np.float64(b1), np.float64(b2),
                        _f64(x), _f64(side_n), _f64(wi), back))
    start = mats[m, M_FIRST]
    count = mats[m, M_COUNT]
    for j in range(count):
        for c in range(lobes.shape[1]):
            lobes[first + j, c] = lobes[start + j, c]
    mats[row, M_FIRST] = first
    mats[row, M_COUNT] = count
    e = (1.0, 1.0, 1.0)
    bound = (0.0, 0.0, 0.0)
    b_first = progs[m, P_BIND]
    for k in range(b_first, b_first + progs[m, P_NBIND]):
        r = binds[k, B_REG]
        if binds[k, B_FIELD] == F_EMISSION:
            e = (_finite(float(regs[r]), 0.0, 3.0e38), _finite(float(regs[r + 1]), 0.0, 3.0e38),
                 _finite(float(regs[r + 2]), 0.0, 3.0e38))
        elif binds[k, B_FIELD] == F_NORMAL:
            bound = _bound_normal((float(regs[r]), float(regs[r + 1]), float(regs[r + 2])), back)
        else:
            _bind(lobes, first + binds[k, B_LOBE], binds[k, B_FIELD], binds[k, B_WIDTH], regs,
                  binds[k, B_REG], binds[k, B_MODE], field_offsets)
    return e, bound


@inline_kernel
def _bound_normal(v, back):
    """A program's normal (facing the viewer's side, as Cycles' N) made unit and turned to the
    front side of the geometric normal, where the surface stage keeps normals; (0, 0, 0) when
    it is not a usable direction."""
    length = math.sqrt(dot(v, v))
    if not length > 0.0 or not math.isfinite(length):
        return (0.0, 0.0, 0.0)
    n = scale(v, 1.0 / length)
    return neg(n) if back else n
