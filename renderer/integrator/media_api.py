"""The medium operations the integrator calls, in one place (renderer.media implements them).

A scene without media never reaches these: the shading kernel tests cfg[CFG_HAS_MEDIA]
before touching the path's medium stack.
"""

from ..media.medium import sample_distance, transmittance
from ..media.nee import nee_vertex
from ..media.stack import stack_has_grid, stack_is_empty, stack_push, stack_remove
from ..media.stack_phase import phase_eval, sample_phase

__all__ = [
    "nee_vertex", "phase_eval", "sample_distance", "sample_phase", "stack_has_grid", "stack_is_empty",
    "stack_push", "stack_remove", "transmittance",
]
