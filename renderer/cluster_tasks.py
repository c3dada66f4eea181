"""What a Dask worker runs: trace one unit of a scene, building the scene's tracer once.

The scene reaches every worker once, as the pickle of renderer.shipment.scene_payload,
scattered with broadcast; each task names it by its hash. A worker process keeps the
tracer of the last scene it saw (module state lives as long as the worker process), so a
unit costs its tracing only. Tasks in one process take turns (a lock): a tracer holds its
path buffers, and Embree holds Python's lock anyway.

Whether a worker compiles kernels (first run on that machine) goes to the client as a Dask
event on TOPIC, [worker address, "compile", names] then [address, "ready"], so the render's
time limit pauses meanwhile, as it does for the local pool.
"""

from __future__ import annotations

import pickle
import threading
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .film import Film
    from .integrator.wavefront import Tracer
    from .units import Unit

TOPIC = "haze-tracer"

_lock = threading.Lock()
_scene_key: str | None = None
_tracer: Tracer | None = None
_builds = 0  # tracers built by this process


# The function the client submits. The scheduler unpickles every task it is sent, so a
# function pickled by reference (module and name) would need Haze installed beside the
# scheduler too; this one is defined outside any importable module, so cloudpickle sends it
# by value, with plain arguments, and it imports Haze only on the worker.
_REMOTE_SOURCE = """
def trace_remote(key, payload, unit, seed):
    from renderer.cluster_tasks import trace_task
    from renderer.units import Unit

    return trace_task(key, payload, Unit(*unit), seed)
"""


def remote_task():
    """trace_task as a function the scheduler can unpickle without Haze: (key, payload,
    (index, first_sample, samples, first_row, rows), seed) -> the unit's (tile's) Film."""
    namespace = {"__name__": "haze_remote_task"}  # not importable: pickled by value
    exec(_REMOTE_SOURCE, namespace)
    return namespace["trace_remote"]


def trace_task(key: str, payload: bytes, unit: Unit, seed: int) -> Film:
    """One unit of the scene `key` (payload: its pickle) into a film of its own."""
    from .units import trace_unit

    with _lock:
        return trace_unit(_tracer_for(key, payload), unit, seed)


def _tracer_for(key: str, payload: bytes) -> Tracer:
    global _scene_key, _tracer, _builds
    if key != _scene_key:
        from .integrator.wavefront import Tracer

        _scene_key, _tracer = None, None  # free the old scene before loading the new one
        cs, settings = pickle.loads(payload)
        _tracer = Tracer(cs, settings, lambda names: _event("compile", list(names)))
        _scene_key, _builds = key, _builds + 1
        _event("ready")
    assert _tracer is not None
    return _tracer


def _event(*message) -> None:
    from distributed import get_worker

    worker = get_worker()
    worker.log_event(TOPIC, [worker.address, *message])


def tracer_builds() -> tuple[str | None, int]:
    """(the scene this process holds a tracer for, tracers built so far): for tests."""
    return _scene_key, _builds
