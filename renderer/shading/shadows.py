"""Shader programs along shadow rays: what a programmed material does to a connection to a
light (only in scenes with programs; the driver skips these kernels otherwise).

* emitter_programs: a shadow ray aimed at a triangle whose program drives its emission
  carries the light table's radiance (1 per channel for such an emitter, stage.py); here
  the program runs at the light point and scales the ray's contribution by the radiance it
  gives there, so next-event estimation sees the textured radiance exactly. The light point
  is found by a short probe ray around the ray's end (the driver traces it): the shadow
  ray's end lies 1e-4 of its length before the light (surface_stage, media_stage).
* shadow_programs: while shadow rays walk through surfaces (shadow_rays.walk_shadows), a
  surface with a program lets through its transparent part as the program sets it there
  (a texture on Principled Alpha, on a Mix of Transparent, on Transparent's Color).
"""

import numpy as np

from renderer.integrator.paths import RAY_FAR, load3
from renderer.kernels import kernel

from .stage import apply_program
from .table import P_NCODE

PROBE_BEFORE, PROBE_LENGTH = 1e-3, 2e-3  # probe from 0.999 of the ray's length over 0.002 of it


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
def emitter_programs(count, sh, prim, bu, bv, geo, st, mt, regs, entry, n_scratch, max_lobes, field_offsets):
    """Scale the contribution of shadow rays 0..count-1 whose probe (prim, bu, bv) met an
    emitting triangle with a program by the emission factor the program gives there.
    mt: a table with scratch rows (stage.scratch_table), n_scratch of them."""
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
def shadow_programs(count, sh, prim, bu, bv, geo, st, mt, regs, entry, override, max_lobes, field_offsets):
    """override[s] = the scratch material of shadow ray s's hit (prim, bu, bv) when its
    material has a program, -1 otherwise (walk_shadows then reads the scene's material)."""
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
