"""The wavefront's kernels, one per stage, in the order a bounce runs them, and the one list
of their calls (STAGES).

Per bounce the driver (wavefront.py) makes one closest-hit call for the live paths and one
occlusion call (or an interface walk) for their shadow rays; these kernels do the rest, per
path, as scalar code (the homogeneous medium segments as SIMD batches, nee_batch.py):

  start_paths       camera_rays.py    camera rays and initial medium stacks
  shade_media       media_stage.py    media along the segment: emission, next-event vertex,
                                      free flight, phase sampling (only when there are media)
  shade_programs    program_stage.py  shader programs at the hits (only with programs)
  shade_surface     surface_stage.py  emission, next-event estimation, BSDF sampling,
                                      Russian roulette; no medium code
  emitter_programs  program_stage.py  textured emitters' radiance at shadow rays' ends
  shadow_media      shadow_rays.py    transmittance of shadow rays through their media
  resolve_shadows   shadow_rays.py    add unoccluded shadow contributions
  shadow_programs   program_stage.py  programs at the surfaces walking shadow rays meet
  walk_shadows      shadow_rays.py    one step of shadow rays through interfaces and media
  compact_*         compaction.py     move live rows to the front
  splat             splat.py          add finished paths to the film

The driver calls them through this module only, so a tool can stand in for all of them at
once (python -m bench kernel_profile times each call; bench.speed swaps in a surface stage
compiled without media). STAGES says, per stage, which scenes run it and what it is passed:
the tracer's records (records.py, state.py) and the values of one call (Call). The warm-up
(Tracer.kernel_calls) and the bounce loop (Tracer._run) both build their calls from it, so
each call is written once.

Conventions: `max_bounces` counts scattering events exactly like Cycles: the vertex a path
is shading has index `depth` (the number of earlier scattering events); next-event
estimation and emission found by BSDF sampling at that vertex belong to paths of `depth`
bounces, so a vertex is shaded only while depth <= max_bounces. Passing through an
interface (a surface with no lobes, or a transparent lobe) is not a bounce. Settings reach
the kernels as the cfg array (config.py); path states are paths.PATH_*.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from .camera_rays import start_paths
from .compaction import compact_paths, compact_shadows
from .media_stage import shade_media
from .program_stage import emitter_programs, shade_programs, shadow_programs
from .shadow_rays import resolve_shadows, shadow_media, walk_shadows
from .splat import splat
from .surface_stage import shade_surface

__all__ = [
    "compact_paths", "compact_shadows", "emitter_programs", "resolve_shadows", "shade_media",
    "shade_programs", "shade_surface", "shadow_media", "shadow_programs", "splat", "start_paths",
    "walk_shadows",
]


class Call(NamedTuple):
    """What changes from one call of a stage to the next (the rest is the tracer's)."""

    n: int = 1  # rows the call covers: paths, or shadow rays
    hits: Any = None  # records.Hits of those rows
    s: int = 0  # shade_surface: the first free shadow-ray row
    occluded: Any = None  # resolve_shadows: (n,) bool, Embree's occlusion answers
    first: int = 0  # start_paths: the batch's first linear sample index
    tile: Any = None  # start_paths: records.Tile
    sums: Any = None  # splat: film.FilmSums


class Stage(NamedTuple):
    """runs(cs): whether a compiled scene's batches call the stage; args(t, c): its
    arguments, from the tracer t (wavefront.Tracer) and the call's values c (Call)."""

    runs: Callable[[Any], bool]
    args: Callable[[Any, Call], tuple]


def _always(cs) -> bool:
    return True


def _programs(cs) -> bool:
    return cs.shading is not None


def _walks(cs) -> bool:
    return cs.needs_shadow_walk


STAGES: dict[str, Stage] = {
    "start_paths": Stage(_always, lambda t, c: (
        c.n, c.first, c.tile, t.ps, t.slots, t.cs.camera, t.init_stack)),
    "shade_media": Stage(lambda cs: cs.has_media, lambda t, c: (
        c.n, t.batch, c.hits, t.scene, t.cs.environment, t.md, t.cfg, t.nb, t.grid_md)),
    "shade_programs": Stage(_programs, lambda t, c: (
        c.n, t.ps, c.hits, t.cs.geometry, t.programs, t.materials)),
    "shade_surface": Stage(_always, lambda t, c: (
        c.n, t.batch, c.hits, t.scene, t.materials, t.cs.environment, t.cfg, c.s)),
    "emitter_programs": Stage(lambda cs: cs.shading is not None and cs.shading.emission, lambda t, c: (
        c.n, t.sh, c.hits, t.cs.geometry, t.programs, t.shadow_materials)),
    "shadow_media": Stage(lambda cs: cs.has_media and not cs.needs_shadow_walk, lambda t, c: (
        c.n, t.sh, t.md, t.cfg, t.grid_md)),
    "resolve_shadows": Stage(lambda cs: not cs.needs_shadow_walk, lambda t, c: (c.n, t.sh, c.occluded, t.L)),
    "shadow_programs": Stage(lambda cs: cs.needs_shadow_walk and cs.shading is not None, lambda t, c: (
        c.n, t.sh, c.hits, t.cs.geometry, t.programs, t.shadow_materials)),
    "walk_shadows": Stage(_walks, lambda t, c: (
        c.n, t.batch, c.hits, t.remaining, t.scene, t.shadow_materials, t.md, t.cfg, t.grid_md)),
    "compact_shadows": Stage(_walks, lambda t, c: (c.n, t.sh, t.remaining)),
    "compact_paths": Stage(_always, lambda t, c: (c.n, t.ps)),
    "splat": Stage(_always, lambda t, c: (c.n, t.L, t.slots, c.sums)),
}
