"""The shader program stage: before the surface stage, every path that hit a material
with a program runs it, and gets a private copy of the material's lobes with the program's
results written into the bound fields (program.py). The surface stage then shades row
`override[i]` of the extended material table instead of the triangle's material.

Only scenes with a program run this kernel (the driver skips it otherwise), so constant
materials keep their path and compile nothing for it.

The extended table is the scene's (mats, lobes) followed by one scratch material per path
slot and `max_lobes` scratch lobes per slot (scratch_table).
"""

import numpy as np

from renderer.bsdfs.layout import LOBE, M_COUNT, M_FIRST, MATERIAL
from renderer.integrator.paths import PATH_ACTIVE, load3
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import add, dot, madd, neg, normalize, scale

from .interpreter import run_program
from .program import BIND, BIND_SCALE
from .table import P_BIND, P_NBIND, P_NCODE

B_LOBE, B_FIELD, B_WIDTH, B_REG, B_MODE = (BIND.offset(f) for f in ("lobe", "field", "width", "reg", "mode"))
# Offsets of program.BIND_FIELDS in a lobe row, and the valid range of each.
FIELD_OFFSETS = np.array([LOBE.offset(f) for f in ("weight", "color", "roughness", "ior", "tint")], np.int32)
F_WEIGHT, F_COLOR, F_ROUGHNESS, F_IOR, F_TINT = 0, 1, 2, 3, 4


def scratch_table(mt: tuple, batch: int, max_lobes: int) -> tuple:
    """The material table with room for one program-evaluated material per path slot."""
    mats, lobes = mt
    ext_mats = np.zeros((mats.shape[0] + batch, MATERIAL.size), np.int32)
    ext_mats[:mats.shape[0]] = mats
    ext_lobes = np.zeros((lobes.shape[0] + batch * max_lobes, LOBE.size), np.float32)
    ext_lobes[:lobes.shape[0]] = lobes
    return ext_mats, ext_lobes


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


@kernel
def shade_programs(n, ps, prim, bu, bv, geo, st, mt, regs, override, max_lobes, field_offsets):
    """Run the programs of paths 0..n-1 that are PATH_ACTIVE and hit a material with one;
    override[i] = their scratch material, -1 for the others."""
    mats, lobes = mt
    progs, binds = st[0], st[4]
    n_mats = mats.shape[0] - override.shape[0]
    n_lobes = lobes.shape[0] - override.shape[0] * max_lobes
    for i in range(n):
        override[i] = -1
        p = prim[i]
        if ps.alive[i] != PATH_ACTIVE or p < 0:
            continue
        m = geo.material[p]
        if progs[m, P_NCODE] < 0:
            continue
        b1 = float(bu[i])
        b2 = float(bv[i])
        b0 = 1.0 - b1 - b2
        x = madd(madd(load3(geo.v0, p), load3(geo.e1, p), b1), load3(geo.e2, p), b2)
        ng = load3(geo.ng, p)
        d = load3(ps.d, i)
        back = dot(d, ng) > 0.0
        sn = _shading_normal(geo, p, b0, b1, b2, ng)
        # Cycles' sd->N faces the side the ray came from.
        run_program(st, m, regs, p, b0, b1, b2, x, neg(sn) if back else sn, neg(d), back)
        row = n_mats + i
        first = n_lobes + i * max_lobes
        start = mats[m, M_FIRST]
        count = mats[m, M_COUNT]
        for j in range(count):
            for c in range(lobes.shape[1]):
                lobes[first + j, c] = lobes[start + j, c]
        mats[row, M_FIRST] = first
        mats[row, M_COUNT] = count
        b_first = progs[m, P_BIND]
        for k in range(b_first, b_first + progs[m, P_NBIND]):
            _bind(lobes, first + binds[k, B_LOBE], binds[k, B_FIELD], binds[k, B_WIDTH], regs,
                  binds[k, B_REG], binds[k, B_MODE], field_offsets)
        override[i] = row
