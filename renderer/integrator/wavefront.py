"""The batch driver: the only Python in the bounce loop is one Embree call per bounce for
the paths and one (or an interface walk) for their shadow rays; kernels do the rest."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..bsdfs.material import bsdf_eval, bsdf_sample
from ..compile import MAX_STACK, CompiledScene
from ..film import Film
from ..geometry import Intersector
from ..kernels.warmup import KernelCall, warm_up
from ..lights.environment import connect_light_env, escaped_radiance_env
from ..lights.sample import triangle_light_pdf
from ..media.layout import dda_scratch
from ..media.stack_phase import phase_eval, sample_phase
from ..scene import IntegratorSettings
from ..shading.interpreter import program_entry
from ..shading.shadows import emitter_programs, probe_rays, shadow_programs
from ..shading.stage import FIELD_OFFSETS, scratch_table, shade_programs
from . import stages as K
from .aovs import aov_surface
from .config import CFG_AOVS, CFG_LIGHT_AOVS, make_config
from .media_stage import _flush_nee_batch
from .nee_batch import NeeBatch
from .paths import (
    AOV_COUNT,
    AOV_FEAT_T,
    AOV_SAMPLE0,
    L_COLUMNS,
    L_COLUMNS_AOV,
    L_COLUMNS_LIGHT_AOV,
    LIGHT_AOV_COUNT,
)
from .state import allocate_paths, allocate_shadows


def camera_medium_stack(cs: CompiledScene, isect: Intersector) -> np.ndarray:
    """Media the camera sits in: the world medium, plus each medium mesh whose surface the
    camera is behind. Found from the geometry along one ray: a mesh whose first crossing is
    an exit (the ray leaves through a back face) encloses the camera."""
    stack = np.full(MAX_STACK, -1, np.int32)
    depth = 0
    if cs.world_medium >= 0:
        stack[0] = cs.world_medium
        depth = 1
    geo = cs.geometry
    if not (geo.medium >= 0).any():
        return stack
    origin = cs.camera.to_world[:3, 3].astype(np.float64)
    direction = np.array([0.5773, 0.5774, 0.5775])  # not aligned with any axis-aligned wall
    direction /= np.linalg.norm(direction)
    seen: set[int] = set()
    # Walk every crossing along the ray (one ray: a handful of Python steps, not per pixel).
    o = origin.copy()
    for _ in range(10000):
        t = np.array([1e30], np.float32)
        prim, _, _ = isect.intersect(o[None].astype(np.float32), direction[None].astype(np.float32), t)
        p = int(prim[0])
        if p < 0:
            break
        mesh_medium = int(geo.medium[p])
        if mesh_medium >= 0 and mesh_medium not in seen:
            seen.add(mesh_medium)
            exiting = float(np.dot(direction, geo.ng[p])) > 0.0
            if exiting and depth < MAX_STACK:
                stack[depth] = mesh_medium
                depth += 1
        o = o + direction * (float(t[0]) + 1e-4 * (1.0 + np.abs(o).max()))
    return stack


class Tracer:
    """Traces sample ranges of one compiled scene into films, batch by batch."""

    def __init__(self, cs: CompiledScene, settings: IntegratorSettings,
                 on_compile: Callable[[list[str]], None] | None = None):
        """on_compile(kernel names) is called before this scene's kernels are compiled, when
        the kernel cache does not have them yet (see renderer.kernels.warmup)."""
        self.cs = cs
        self.settings = settings
        self.isect = Intersector(cs.vertices, cs.indices)
        self.batch = int(settings.batch_size)
        self.ps = allocate_paths(self.batch)
        self.sh = allocate_shadows(self.batch)
        self.nb = NeeBatch().arrays() if cs.has_media else None
        self.md = cs.media.with_scratch(dda_scratch())  # the scene's media tables + our DDA scratch
        # The same again where the kernels may meet grid media, None when the scene has none:
        # then they compile without the grid trackers (numba prunes branches on None).
        self.grid_md = self.md if cs.media.has_grids else None
        self.cfg = make_config(cs, settings)
        self.aovs = bool(self.cfg[CFG_AOVS])
        # RGB and transparency, and the render passes' columns when they were asked for.
        light = bool(self.cfg[CFG_LIGHT_AOVS])
        columns = L_COLUMNS_LIGHT_AOV if light else L_COLUMNS_AOV if self.aovs else L_COLUMNS
        self.L = np.zeros((self.batch, columns), np.float64)
        self.aov_columns = AOV_COUNT + (LIGHT_AOV_COUNT if light else 0)  # the film's pass sums
        self.no_aov = np.zeros((0, AOV_COUNT), np.float64)  # splat's film_aov without passes
        self.mist = np.array(cs.mist, np.float64)  # the Mist pass's start, 1 / depth, falloff
        self.pixel_of_pid = np.zeros(self.batch, np.int32)
        self.half_of_pid = np.zeros(self.batch, np.int32)
        self.remaining = np.zeros(2 * self.batch, np.float32)
        self.lt = cs.lights
        self.init_stack = camera_medium_stack(cs, self.isect)
        self._shader_programs(cs)
        self.stats = {"rays": 0, "shadow_rays": 0, "embree_s": 0.0}
        self.compile_seconds = warm_up(self.kernel_calls(), on_compile)

    def _shader_programs(self, cs: CompiledScene) -> None:
        """Scratch for the shader program stage (renderer.shading.stage), only in scenes
        with programs; otherwise the surface stage gets an empty override and the scene's
        own material table. Shadow rays get a table of their own (renderer.shading.shadows)."""
        self.mt = self.shadow_mt = cs.materials
        self.override = self.shadow_override = np.zeros(0, np.int32)
        self.program_out = np.zeros((0, 6), np.float32)
        self.regs = np.zeros(1, np.float32)
        self.entry = 0  # the interpreter's address (interpreter.program_entry), in scenes with programs
        self.max_lobes = 0
        if cs.shading is not None:
            self.max_lobes = cs.shading.max_lobes
            self.mt = scratch_table(cs.materials, self.batch, self.max_lobes)
            self.override = np.full(self.batch, -1, np.int32)
            self.program_out = np.zeros((self.batch, 6), np.float32)
            self.regs = np.zeros(cs.shading.max_registers, np.float32)
            self.entry = program_entry(cs.shading.arrays, self.regs)
            shadows = self.sh.o.shape[0]
            self.shadow_mt = scratch_table(cs.materials, shadows, self.max_lobes)
            self.shadow_override = np.full(shadows, -1, np.int32)

    def kernel_calls(self) -> list[KernelCall]:
        """Every kernel call a batch of this scene makes, with arguments of the types it
        passes (the hits and occlusion flags Embree returns are stood in for by arrays of
        its types): what warm_up compiles before the first batch."""
        cs, ps, sh, lt, cfg, L = self.cs, self.ps, self.sh, self.lt, self.cfg, self.L
        prim, bu, bv = np.full(1, -1, np.int32), np.zeros(1, np.float32), np.zeros(1, np.float32)
        calls: list[KernelCall] = self.subtree_calls() + [
            (K.start_paths, (ps, self.pixel_of_pid, self.half_of_pid, cs.camera, cs.width, cs.height,
                             0, 0, 0, 1, 0, self.init_stack)),
            (K.shade_surface, (1, ps, prim, bu, bv, cs.geometry, self.mt, self.override, self.program_out,
                               lt, cs.environment, cfg, L, sh, 0,
                               cs.camera, self.mist)),
            (K.compact_paths, (1, ps)),
            (K.splat, (1, L, self.pixel_of_pid, self.half_of_pid, np.zeros((1, 3), np.float64),
                       np.zeros((1, 3), np.float64), np.zeros(1, np.int64), np.zeros((1, 4), np.float64),
                       np.zeros(1, np.int64), np.zeros(1, np.float64), self.no_aov)),
        ]
        if cs.shading is not None:
            st, lobes = cs.shading.arrays, self.max_lobes
            calls.append((shade_programs, (1, ps, prim, bu, bv, cs.geometry, st, self.mt, self.regs,
                                           self.entry, self.override, self.program_out, lobes,
                                           FIELD_OFFSETS)))
            if cs.shading.emission:
                calls.append((emitter_programs, (1, sh, prim, bu, bv, cs.geometry, st, self.shadow_mt,
                                                 self.regs, self.entry, 1, lobes, FIELD_OFFSETS)))
            if cs.needs_shadow_walk:
                calls.append((shadow_programs, (1, sh, prim, bu, bv, cs.geometry, st, self.shadow_mt,
                                                self.regs, self.entry, self.shadow_override, lobes,
                                                FIELD_OFFSETS)))
        if cs.has_media:
            calls.append((K.shade_media, (1, ps, prim, lt, cs.environment, self.md, cfg, L, sh, self.nb,
                                          self.grid_md)))
        if cs.needs_shadow_walk:
            calls.append((K.walk_shadows, (1, sh, prim, np.zeros(1, np.float32), self.remaining,
                                           cs.geometry, self.shadow_mt, self.shadow_override, self.md, cfg,
                                           L, self.grid_md)))
            calls.append((K.compact_shadows, (1, sh, self.remaining)))
        else:
            calls.append((K.resolve_shadows, (1, sh, np.zeros(1, np.bool_), L)))
            if cs.has_media:
                calls.append((K.shadow_media, (1, sh, self.md, cfg, self.grid_md)))
        return calls

    def subtree_calls(self) -> list[KernelCall]:
        """The largest helpers inside shade_surface and shade_media, with the argument types
        those kernels pass them, listed before the kernels (see renderer.kernels.warmup).

        A stage kernel compiles its helpers while numba types it, in one process, so on a
        cold cache its compile was one long task: shade_surface took 40 of the surface box's
        47 CPU seconds (BSDF evaluation and sampling 19 of them). Listed here, the helpers are
        compiled first, each under its own lock, and a second worker compiles some of them
        while the first compiles others; the stage kernel then loads them. The types must be
        exactly the stage's (tests/test_kernel_cache.py checks that no helper compiles
        twice), or the helper would compile once more for the stage's own types."""
        cs, lt, v = self.cs, self.lt, (0.0, 0.0, 1.0)
        m, light, tri = np.int32(0), 0, np.int32(0)
        calls: list[KernelCall] = [
            (bsdf_eval, (self.mt, m, True, v, v)),
            (bsdf_sample, (self.mt, m, True, v, 0.5, 0.5, 0.5, 0.5)),
            # Compiled into shade_surface with or without passes (L's type is the same).
            (aov_surface, (self.L, m, self.mt, m, True, v, v, 0.5, m, v, cs.camera, self.mist)),
            (connect_light_env, (lt, cs.environment, light, v, v, 0.5, 0.5)),
            (triangle_light_pdf, (lt, tri, v, v, 1.0)),
            (escaped_radiance_env, (lt, light, cs.lights.sun_rows, cs.environment, v)),
        ]
        if cs.has_media:
            stack = self.init_stack
            calls = [(_flush_nee_batch, (0, self.nb, self.ps, self.cfg, self.sh, 0, self.L)),
                     (phase_eval, (self.md, stack, v, v, v)),
                     (sample_phase, (self.md, stack, v, v, 0.5, 0.5, 0.5))] + calls
        return calls

    def trace(self, film: Film, sample_base: int, spp: int, seed: int) -> None:
        """Add samples sample_base .. sample_base + spp - 1 of every pixel of film to it: the
        whole rendered window, or the tile (a band of its rows) that film covers."""
        cs = self.cs
        assert film.width == cs.width and 0 <= film.first_row and film.first_row + film.height <= cs.height, \
            "a film outside the rendered window"
        total = film.width * film.height * spp
        for first in range(0, total, self.batch):
            n = min(self.batch, total - first)
            self._trace_batch(film, first, n, sample_base, seed)

    def _trace_batch(self, film: Film, first: int, n: int, sample_base: int, seed: int) -> None:
        cs, ps, sh = self.cs, self.ps, self.sh
        self.L[:n] = 0.0
        K.start_paths(ps, self.pixel_of_pid, self.half_of_pid, cs.camera, film.width, film.height,
                      film.first_row, seed, first, n, sample_base, self.init_stack)
        if self.aovs:
            self._start_aovs(first, n, sample_base, film.width * film.height)
        live = n
        while live > 0:
            prim, bu, bv = self.isect.intersect(ps.o[:live], ps.d[:live], ps.tmax[:live])
            self.stats["rays"] += live
            count = 0
            if cs.has_media:
                count = K.shade_media(live, ps, prim, self.lt, cs.environment, self.md, self.cfg, self.L, sh,
                                      self.nb, self.grid_md)
            if cs.shading is not None:
                shade_programs(live, ps, prim, bu, bv, cs.geometry, cs.shading.arrays, self.mt, self.regs,
                               self.entry, self.override, self.program_out, self.max_lobes, FIELD_OFFSETS)
            count = K.shade_surface(live, ps, prim, bu, bv, cs.geometry, self.mt, self.override,
                                    self.program_out, self.lt,
                                    cs.environment, self.cfg, self.L,
                                    sh, count,
                                    cs.camera, self.mist)
            if count:
                self._shadows(count)
            live = K.compact_paths(live, ps)
        film_aov = film.ensure_aov(self.aov_columns) if self.aovs else self.no_aov
        K.splat(n, self.L, self.pixel_of_pid, self.half_of_pid, film.sum, film.sq, film.n, film.odd,
                film.nonfinite, film.alpha, film_aov)

    def _start_aovs(self, first: int, n: int, sample_base: int, pixels: int) -> None:
        """The passes' per-path scratch: feature throughput 1, and which paths are their
        pixel's sample 0 (linear index k is sample sample_base + k // pixels, pixels in the
        tile, as in start_paths)."""
        L = self.L
        L[:n, AOV_FEAT_T:AOV_FEAT_T + 3] = 1.0
        sample = sample_base + np.arange(first, first + n) // pixels
        L[:n, AOV_SAMPLE0] = sample == 0

    def _shadows(self, count: int) -> None:
        sh, cs = self.sh, self.cs
        self.stats["shadow_rays"] += count
        if cs.shading is not None and cs.shading.emission:
            # Textured emitters: their radiance at each ray's light point (shading.shadows).
            prim, bu, bv = self.isect.intersect(*probe_rays(sh, count))
            emitter_programs(count, sh, prim, bu, bv, cs.geometry, cs.shading.arrays, self.shadow_mt,
                             self.regs, self.entry, self.shadow_override.shape[0], self.max_lobes,
                             FIELD_OFFSETS)
        if not self.cs.needs_shadow_walk:
            if self.cs.has_media:
                K.shadow_media(count, sh, self.md, self.cfg, self.grid_md)
            occluded = self.isect.occluded(sh.o[:count], sh.d[:count], sh.tmax[:count])
            K.resolve_shadows(count, sh, occluded, self.L)
            return
        remaining = self.remaining
        remaining[:count] = sh.tmax[:count]
        while count > 0:
            thit = remaining[:count].copy()
            prim, bu, bv = self.isect.intersect(sh.o[:count], sh.d[:count], thit)
            if cs.shading is not None:
                shadow_programs(count, sh, prim, bu, bv, cs.geometry, cs.shading.arrays, self.shadow_mt,
                                self.regs, self.entry, self.shadow_override, self.max_lobes, FIELD_OFFSETS)
            K.walk_shadows(count, sh, prim, thit, remaining, cs.geometry, self.shadow_mt,
                           self.shadow_override, self.md, self.cfg, self.L, self.grid_md)
            count = K.compact_shadows(count, sh, remaining)
