"""The batch driver: the only Python in the bounce loop is one Embree call per bounce for
the paths and one (or an interface walk) for their shadow rays; kernels do the rest."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..bsdfs.material import bsdf_eval, bsdf_sample
from ..compile import MAX_STACK, CompiledScene
from ..film import Film, FilmSums
from ..geometry import Intersector
from ..kernels.warmup import KernelCall, warm_up
from ..lights.environment import connect_light_env, escaped_radiance_env
from ..lights.sample import triangle_light_pdf
from ..media.layout import dda_scratch
from ..media.stack_phase import phase_eval, sample_phase
from ..scene import IntegratorSettings
from ..shading.apply import FIELD_OFFSETS, scratch_table
from ..shading.interpreter import program_entry
from . import stages as K
from .aovs import aov_surface
from .config import CFG_AOVS, CFG_LIGHT_AOVS, make_config
from .media_stage import flush_nee_batch
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
from .program_stage import probe_rays
from .records import Hits, Materials, Programs, SceneArrays, Tile
from .stages import STAGES, Call
from .state import Batch, Slots, allocate_paths, allocate_shadows


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
        self.batch_size = int(settings.batch_size)
        self.ps = allocate_paths(self.batch_size)
        self.sh = allocate_shadows(self.batch_size)
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
        self.L = np.zeros((self.batch_size, columns), np.float64)
        self.batch = Batch(self.ps, self.sh, self.L)
        self.aov_columns = AOV_COUNT + (LIGHT_AOV_COUNT if light else 0)  # the film's pass sums
        self.no_aov = np.zeros((0, AOV_COUNT), np.float64)  # the splat's sums.aov without passes
        self.slots = Slots(np.zeros(self.batch_size, np.int32), np.zeros(self.batch_size, np.int32))
        self.remaining = np.zeros(2 * self.batch_size, np.float32)
        self.scene = SceneArrays(cs.geometry, cs.lights, cs.camera, np.array(cs.mist, np.float64))
        # Embree's answers, copied into arrays of our own: the kernels' records stay the same
        # objects from call to call, so each call reuses its compiled entry point
        # (renderer.kernels.Kernel) instead of numba's dispatch on the records' types.
        rows = 2 * self.batch_size
        prim, bu, bv = np.full(rows, -1, np.int32), np.zeros(rows, np.float32), np.zeros(rows, np.float32)
        self.path_hits = Hits(prim, bu, bv, self.ps.tmax)  # Embree writes the distance into tmax
        self.shadow_hits = Hits(prim, bu, bv, np.zeros(rows, np.float32))
        self.init_stack = camera_medium_stack(cs, self.isect)
        self._shader_programs(cs)
        self.runs = {name for name, stage in STAGES.items() if stage.runs(cs)}
        self.stats = {"rays": 0, "shadow_rays": 0, "embree_s": 0.0}
        self.compile_seconds = warm_up(self.kernel_calls(), on_compile)

    def _shader_programs(self, cs: CompiledScene) -> None:
        """Scratch for the shader program stages (integrator.program_stage), only in scenes
        with programs; otherwise the surface stage gets an empty override and the scene's
        own material table. Shadow rays get a table of their own."""
        empty = np.zeros((0, 6), np.float32)
        self.materials = self.shadow_materials = Materials(cs.materials, np.zeros(0, np.int32), empty)
        self.programs = None
        if cs.shading is not None:
            max_lobes = cs.shading.max_lobes
            st, regs = cs.shading.arrays, np.zeros(cs.shading.max_registers, np.float32)
            self.programs = Programs(st, regs, program_entry(st, regs), max_lobes, FIELD_OFFSETS)
            self.materials = Materials(scratch_table(cs.materials, self.batch_size, max_lobes),
                                       np.full(self.batch_size, -1, np.int32),
                                       np.zeros((self.batch_size, 6), np.float32))
            shadows = self.sh.o.shape[0]
            self.shadow_materials = Materials(scratch_table(cs.materials, shadows, max_lobes),
                                              np.full(shadows, -1, np.int32), empty)

    def _run(self, name: str, **values):
        """Call stage `name` with the tracer's records and this call's values (stages.STAGES)."""
        return getattr(K, name)(*STAGES[name].args(self, Call(**values)))

    def kernel_calls(self) -> list[KernelCall]:
        """Every kernel call a batch of this scene makes, with arguments of the types it
        passes (stages.STAGES with stand-in values of the types a batch passes): what
        warm_up compiles before the first batch."""
        cs = self.cs
        one = np.zeros((1, 3), np.float64)
        stand_in = Call(n=1, hits=self.path_hits, s=0, occluded=np.zeros(1, np.bool_), first=0,
                        tile=Tile(cs.width, cs.height, 0, 0, 0),
                        sums=FilmSums(one, one.copy(), np.zeros(1, np.int64), np.zeros((1, 4), np.float64),
                                      np.zeros(1, np.int64), np.zeros(1, np.float64), self.no_aov))
        return self.subtree_calls() + [(getattr(K, name), stage.args(self, stand_in))
                                       for name, stage in STAGES.items() if name in self.runs]

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
        cs, lt, v = self.cs, self.scene.lights, (0.0, 0.0, 1.0)
        mt = self.materials.table
        m, light, tri = np.int32(0), 0, np.int32(0)
        calls: list[KernelCall] = [
            (bsdf_eval, (mt, m, True, v, v)),
            (bsdf_sample, (mt, m, True, v, 0.5, 0.5, 0.5, 0.5)),
            # Compiled into shade_surface with or without passes (L's type is the same).
            (aov_surface, (self.L, m, mt, m, True, v, v, 0.5, m, v, cs.camera, self.scene.mist)),
            (connect_light_env, (lt, cs.environment, light, v, v, 0.5, 0.5)),
            (triangle_light_pdf, (lt, tri, v, v, 1.0)),
            (escaped_radiance_env, (lt, light, lt.sun_rows, cs.environment, v)),
        ]
        if cs.has_media:
            stack = self.init_stack
            calls = [(flush_nee_batch, (0, self.nb, self.ps, self.cfg, self.sh, 0, self.L)),
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
        tile = Tile(int(film.width), int(film.height), int(film.first_row), int(seed), int(sample_base))
        sums = film.sums(film.ensure_aov(self.aov_columns) if self.aovs else self.no_aov)
        for first in range(0, total, self.batch_size):
            n = min(self.batch_size, total - first)
            self._trace_batch(tile, sums, first, n)

    def _trace_batch(self, tile: Tile, sums: FilmSums, first: int, n: int) -> None:
        ps = self.ps
        self.L[:n] = 0.0
        self._run("start_paths", n=n, first=first, tile=tile)
        if self.aovs:
            self._start_aovs(first, n, tile.sample_base, tile.width * tile.rows)
        live = n
        while live > 0:
            hits = self._intersect(self.path_hits, ps.o[:live], ps.d[:live], ps.tmax[:live])
            self.stats["rays"] += live
            count = self._run("shade_media", n=live, hits=hits) if "shade_media" in self.runs else 0
            if "shade_programs" in self.runs:
                self._run("shade_programs", n=live, hits=hits)
            count = self._run("shade_surface", n=live, hits=hits, s=count)
            if count:
                self._shadows(count)
            live = self._run("compact_paths", n=live)
        self._run("splat", n=n, sums=sums)

    def _intersect(self, hits: Hits, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> Hits:
        """The closest hits of rays (o, d) up to t (n,) (overwritten with the distance), in
        rows 0..n-1 of `hits`."""
        n = o.shape[0]
        hits.prim[:n], hits.bu[:n], hits.bv[:n] = self.isect.intersect(o, d, t)
        return hits

    def _start_aovs(self, first: int, n: int, sample_base: int, pixels: int) -> None:
        """The passes' per-path scratch: feature throughput 1, and which paths are their
        pixel's sample 0 (linear index k is sample sample_base + k // pixels, pixels in the
        tile, as in start_paths)."""
        L = self.L
        L[:n, AOV_FEAT_T:AOV_FEAT_T + 3] = 1.0
        sample = sample_base + np.arange(first, first + n) // pixels
        L[:n, AOV_SAMPLE0] = sample == 0

    def _shadows(self, count: int) -> None:
        sh = self.sh
        self.stats["shadow_rays"] += count
        if "emitter_programs" in self.runs:
            # Textured emitters: their radiance at each ray's light point (program_stage).
            hits = self._intersect(self.shadow_hits, *probe_rays(sh, count))
            self._run("emitter_programs", n=count, hits=hits)
        if not self.cs.needs_shadow_walk:
            if "shadow_media" in self.runs:
                self._run("shadow_media", n=count)
            occluded = self.isect.occluded(sh.o[:count], sh.d[:count], sh.tmax[:count])
            self._run("resolve_shadows", n=count, occluded=occluded)
            return
        remaining = self.remaining
        remaining[:count] = sh.tmax[:count]
        while count > 0:
            t = self.shadow_hits.t
            t[:count] = remaining[:count]
            hits = self._intersect(self.shadow_hits, sh.o[:count], sh.d[:count], t[:count])
            if "shadow_programs" in self.runs:
                self._run("shadow_programs", n=count, hits=hits)
            self._run("walk_shadows", n=count, hits=hits)
            count = self._run("compact_shadows", n=count)
