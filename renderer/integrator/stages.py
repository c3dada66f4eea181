"""The wavefront's kernels, one per stage, in the order a bounce runs them.

Per bounce the driver (wavefront.py) makes one closest-hit call for the live paths and one
occlusion call (or an interface walk) for their shadow rays; these kernels do the rest, per
path, as scalar code (the homogeneous medium segments as SIMD batches, nee_batch.py):

  start_paths      camera_rays.py   camera rays and initial medium stacks
  shade_media      media_stage.py   media along the segment: emission, next-event vertex,
                                    free flight, phase sampling (only when there are media)
  shade_surface    surface_stage.py emission, next-event estimation, BSDF sampling,
                                    Russian roulette; no medium code
  shadow_media     shadow_rays.py   transmittance of shadow rays through their media
  resolve_shadows  shadow_rays.py   add unoccluded shadow contributions
  walk_shadows     shadow_rays.py   one step of shadow rays through interfaces and media
  compact_*        compaction.py    move live rows to the front
  splat            film.py          add finished paths to the film

The driver calls them through this module only, so a tool can stand in for all of them at
once (python -m bench kernel_profile times each call; renderer.bench.speed swaps in a surface stage
compiled without media).

Conventions: `max_bounces` counts scattering events exactly like Cycles: the vertex a path
is shading has index `depth` (the number of earlier scattering events); next-event
estimation and emission found by BSDF sampling at that vertex belong to paths of `depth`
bounces, so a vertex is shaded only while depth <= max_bounces. Passing through an
interface (a surface with no lobes, or a transparent lobe) is not a bounce. Settings reach
the kernels as the cfg array (config.py); path states are paths.PATH_*.
"""

from ..film import splat
from .camera_rays import start_paths
from .compaction import compact_paths, compact_shadows
from .media_stage import shade_media
from .shadow_rays import resolve_shadows, shadow_media, walk_shadows
from .surface_stage import shade_surface

__all__ = [
    "compact_paths", "compact_shadows", "resolve_shadows", "shade_media", "shade_surface", "shadow_media",
    "splat", "start_paths", "walk_shadows",
]
