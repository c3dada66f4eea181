"""The medium operations the integrator calls, in one place (renderer.media implements them).

A scene without media never reaches the costly ones: the driver runs the medium stage
(media_stage.py) and shadow_media only when the scene has media, and the surface stage
touches a path's medium stack only where it crosses a mesh that bounds a medium.
"""

from ..media.homogeneous import segment, stack_sigma
from ..media.medium import (
    grid_sample_distance,
    homogeneous_transmittance,
    sample_distance,
    sample_segment,
    segment_emission,
    transmittance,
)
from ..media.nee import nee_vertex_on
from ..media.spectral import channel_probabilities
from ..media.stack import EMPTY, stack_has_grid, stack_is_empty, stack_push, stack_remove
from ..media.stack_phase import phase_eval, sample_phase
from ..media.table import phase_g

__all__ = [
    "EMPTY", "channel_probabilities", "grid_sample_distance", "homogeneous_transmittance",
    "nee_vertex_on", "phase_eval", "phase_g", "sample_distance",
    "sample_phase", "sample_segment", "segment", "segment_emission", "stack_has_grid",
    "stack_is_empty", "stack_push", "stack_remove", "stack_sigma", "transmittance",
]
