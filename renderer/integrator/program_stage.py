"""The shader program stages (only in scenes with programs; the driver skips them
otherwise, so constant materials compile nothing for them). Each runs the programs of the
rows whose hit has a material with one (shading.apply.apply_program) and leaves the result
where the next stage reads it:

* shade_programs, before the surface stage: every path that hit a material with a program
  gets its private scratch material (Materials.override) and the program's emission factor
  and shading normal (Materials.out).
* emitter_programs: a shadow ray aimed at a triangle whose program drives its emission
  carries the light table's radiance (1 per channel for such an emitter, shading.apply);
  here the program runs at the light point and scales the ray's contribution by the
  radiance it gives there, so next-event estimation sees the textured radiance exactly. The
  light point is found by a short probe ray around the ray's end (probe_rays; the driver
  traces it): the shadow ray's end lies 1e-4 of its length before the light (surface_stage,
  media_stage).
* shadow_programs: while shadow rays walk through surfaces (shadow_rays.walk_shadows), a
  surface with a program lets through its transparent part as the program sets it there
  (a texture on Principled Alpha, on a Mix of Transparent, on Transparent's Color).
"""

import numpy as np

from ..kernels import kernel
from ..shading.apply import apply_program
from ..shading.table import P_NCODE
from .paths import PATH_ACTIVE, RAY_FAR, load3

PROBE_BEFORE, PROBE_LENGTH = 1e-3, 2e-3  # probe from 0.999 of the ray's length over 0.002 of it


@kernel
def shade_programs(n, ps, hits, geo, programs, materials):
    """Run the programs of paths 0..n-1 that are PATH_ACTIVE and hit a material with one;
    materials.override[i] = their scratch material, -1 for the others; materials.out[i]
    (n, 6) the factor on the light table's radiance of the emitter hit (1 unless the program
    drives emission) and the shading normal (0 unless the program drives it)."""
    prim, bu, bv = hits.prim, hits.bu, hits.bv
    st, regs, entry, max_lobes, field_offsets = (programs.table, programs.regs, programs.entry,
                                                 programs.max_lobes, programs.field_offsets)
    mt, override, out = materials.table, materials.override, materials.out
    mats, lobes = mt
    progs = st[0]
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
        e, sn = apply_program(geo, st, mt, regs, entry, p, m, float(bu[i]), float(bv[i]), load3(ps.d, i),
                              n_mats + i, n_lobes + i * max_lobes, field_offsets)
        out[i, 0], out[i, 1], out[i, 2] = e[0], e[1], e[2]
        out[i, 3], out[i, 4], out[i, 5] = sn[0], sn[1], sn[2]
        override[i] = n_mats + i


def probe_rays(sh, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(origins, directions, lengths) of rays that meet the light at the end of shadow rays
    0..count-1; length 0 (no hit) for rays to lights at infinity."""
    tmax = sh.tmax[:count]
    finite = tmax < 0.5 * RAY_FAR
    t = np.where(finite, tmax, 0.0).astype(np.float32)
    origins = sh.o[:count] + sh.d[:count] * (t * (1.0 - PROBE_BEFORE))[:, None]
    lengths = np.where(finite, t * PROBE_LENGTH + 1e-6, 0.0).astype(np.float32)
    return origins.astype(np.float32), np.ascontiguousarray(sh.d[:count]), lengths


@kernel
def emitter_programs(count, sh, hits, geo, programs, materials):
    """Scale the contribution of shadow rays 0..count-1 whose probe `hits` met an emitting
    triangle with a program by the emission factor the program gives there. materials: the
    shadow rays' table with scratch rows (shading.apply.scratch_table), one per override row."""
    prim, bu, bv = hits.prim, hits.bu, hits.bv
    st, regs, entry, max_lobes, field_offsets = (programs.table, programs.regs, programs.entry,
                                                 programs.max_lobes, programs.field_offsets)
    mt = materials.table
    n_scratch = materials.override.shape[0]
    mats, lobes = mt
    progs = st[0]
    row = mats.shape[0] - n_scratch
    first = lobes.shape[0] - n_scratch * max_lobes
    for s in range(count):
        p = prim[s]
        if p < 0 or geo.light[p] < 0:
            continue
        m = geo.material[p]
        if progs[m, P_NCODE] < 0:
            continue
        e, _ = apply_program(geo, st, mt, regs, entry, p, m, float(bu[s]), float(bv[s]), load3(sh.d, s), row,
                             first, field_offsets)
        sh.contrib[s, 0] *= e[0]
        sh.contrib[s, 1] *= e[1]
        sh.contrib[s, 2] *= e[2]


@kernel
def shadow_programs(count, sh, hits, geo, programs, materials):
    """materials.override[s] = the scratch material of shadow ray s's hit when its material
    has a program, -1 otherwise (walk_shadows then reads the scene's material)."""
    prim, bu, bv = hits.prim, hits.bu, hits.bv
    st, regs, entry, max_lobes, field_offsets = (programs.table, programs.regs, programs.entry,
                                                 programs.max_lobes, programs.field_offsets)
    mt, override = materials.table, materials.override
    mats, lobes = mt
    progs = st[0]
    n_mats = mats.shape[0] - override.shape[0]
    n_lobes = lobes.shape[0] - override.shape[0] * max_lobes
    for s in range(count):
        override[s] = -1
        p = prim[s]
        if p < 0:
            continue
        m = geo.material[p]
        if progs[m, P_NCODE] < 0:
            continue
        apply_program(geo, st, mt, regs, entry, p, m, float(bu[s]), float(bv[s]), load3(sh.d, s), n_mats + s,
                      n_lobes + s * max_lobes, field_offsets)
        override[s] = n_mats + s
