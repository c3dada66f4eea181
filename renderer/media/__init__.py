"""Participating media as numba kernels.

build_media_data() turns Scene.media into MediaData (immutable tables, layout.py); the
tracer adds its walker scratch (MediaData.with_scratch(dda_scratch())) to make the kernels'
MediaTable argument, and then calls, per path and with the path's medium stack (an int32
row, see stack.py):

    sample_distance   free flight over a segment: scatter vertex or pass-through, + emission
    transmittance     shadow-ray transmittance over a segment
    sample_phase / phase_eval / phase_pdf   the stack's phase-function mixture at a point
    nee_vertex        decoupled next-event vertex on a homogeneous segment (equiangular MIS)
    stack_push / stack_remove / stack_is_empty / stack_has_grid
"""

from renderer.media.compile import build_media_data, compile_media
from renderer.media.equiangular import equiangular_pdf, equiangular_sample
from renderer.media.layout import MEDIUM_GRID, MEDIUM_HOMOGENEOUS, MediaData, MediaTable, dda_scratch
from renderer.media.medium import sample_distance, transmittance
from renderer.media.nee import nee_vertex
from renderer.media.stack import EMPTY, MAX_STACK, stack_has_grid, stack_is_empty, stack_push, stack_remove
from renderer.media.stack_phase import phase_eval, phase_pdf, sample_phase

__all__ = [
    "EMPTY",
    "MAX_STACK",
    "MEDIUM_GRID",
    "MEDIUM_HOMOGENEOUS",
    "MediaData",
    "MediaTable",
    "build_media_data",
    "compile_media",
    "dda_scratch",
    "equiangular_pdf",
    "equiangular_sample",
    "nee_vertex",
    "phase_eval",
    "phase_pdf",
    "sample_distance",
    "sample_phase",
    "stack_has_grid",
    "stack_is_empty",
    "stack_push",
    "stack_remove",
    "transmittance",
]
