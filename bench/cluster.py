"""Cluster rendering figures: `.venv/bin/python -m bench cluster [--size 128] [--spp 256]`.

Prints, for the fog Cornell box (g = 0, max_bounces 3), wall-clock seconds for one full
render (kernels compiled, workers started and holding the scene's tracer: a warm-up render
of the same scene first), best of --repeat:

* one process (in this process, no workers);
* the local worker pool, 2 processes (renderer.workers: today's multi-process path);
* a Dask LocalCluster of 2 single-threaded worker processes (--cluster local);

and the speed-ups. Then:

* overhead per unit: --units units of one sample of a 4x4 image, submitted as the cluster
  render submits them, against the same units traced in this process (per unit: cluster
  wall time x workers minus the tracing itself);
* time to first image: a render of a scene the cluster's workers have not seen (request
  to the first Progress), on the running LocalCluster (its workers' numba already loaded)
  and on the running pool, and the time to start a LocalCluster of 2 workers.
"""

from __future__ import annotations

import argparse
import time

from examples.scenes import cornell_box, cornell_fog
from renderer.cluster import LOCAL, connect, shutdown_clusters
from renderer.render import render_progressive
from renderer.scene import Scene


def fog(size: int, spp: int, seed: int = 0) -> Scene:
    scene = cornell_fog(size, 1, g=0.0, max_bounces=3)
    scene.integrator.spp, scene.integrator.seed = spp, seed
    return scene


def timed(scene: Scene, **options) -> tuple[float, float]:
    """(seconds to the first image, seconds to the last) of one render."""
    t0 = time.perf_counter()
    first = None
    for _ in render_progressive(scene, **options):
        first = first or time.perf_counter() - t0
    return first or 0.0, time.perf_counter() - t0


def best(scene_of, repeat: int, **options) -> float:
    timed(scene_of(), **options)  # warm-up: workers started, tracers built, kernels loaded
    return min(timed(scene_of(), **options)[1] for _ in range(repeat))


def unit_overhead(units: int) -> tuple[float, float]:
    """(ms per unit traced here, ms of worker time per unit beyond that on the cluster, and
    on the local pool)."""
    from distributed import as_completed

    from renderer.cluster_tasks import trace_task
    from renderer.compile import compile_scene
    from renderer.integrator.wavefront import Tracer
    from renderer.shipment import scene_payload
    from renderer.units import Unit, trace_unit

    scene = cornell_box(4, 1, max_bounces=3)
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    plan = [Unit(i, i, 1, 0, cs.height) for i in range(units)]
    t0 = time.perf_counter()
    for unit in plan:
        trace_unit(tracer, unit, 0)
    here = (time.perf_counter() - t0) / units
    client = connect(LOCAL, 2)
    key, payload = scene_payload(cs, scene.integrator)
    data = client.scatter(payload, broadcast=True, hash=False)
    client.gather([client.submit(trace_task, key, data, u, 0, pure=False) for u in plan[:4]])  # build tracers
    t0 = time.perf_counter()
    pending = as_completed()
    fresh = iter(plan)
    for unit in [next(fresh) for _ in range(4)]:  # 2 per worker in flight, as the render does
        pending.add(client.submit(trace_task, key, data, unit, 0, pure=False, priority=-unit.index))
    for done in pending:
        done.result()
        unit = next(fresh, None)
        if unit is not None:
            pending.add(client.submit(trace_task, key, data, unit, 0, pure=False, priority=-unit.index))
    cluster = (time.perf_counter() - t0) * 2 / units  # two workers' time per unit
    return here * 1e3, (cluster - here) * 1e3, (pool_per_unit(cs, scene, plan) - here) * 1e3


def pool_per_unit(cs, scene: Scene, plan) -> float:
    """Seconds of worker time per unit on the local pool of 2, units handed out as it does."""
    from renderer.shipment import shipped
    from renderer.workers import pool

    pool.resize(2)
    with shipped(cs, scene.integrator) as shipment:
        def run(units) -> None:
            fresh = iter(units)
            while True:
                for worker in pool.idle():
                    unit = next(fresh, None)
                    if unit is not None:
                        worker.send(shipment, unit, 0)
                if not pool.busy():
                    return
                for worker, message in pool.events(60.0):
                    if message is None or message[0] in ("done", "error"):
                        worker.unit = None

        run(plan[:4])  # workers started, tracers built
        t0 = time.perf_counter()
        run(plan)
        return (time.perf_counter() - t0) * 2 / len(plan)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench cluster", description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--units", type=int, default=400)
    args = parser.parse_args(argv)

    def scene():
        return fog(args.size, args.spp)

    t0 = time.perf_counter()
    connect(LOCAL, 2)
    start = time.perf_counter() - t0
    one = best(scene, args.repeat, workers=1, in_process=True)
    pool = best(scene, args.repeat, workers=2, in_process=False)
    dask = best(scene, args.repeat, workers=2, cluster=LOCAL)
    print(f"fog box {args.size}x{args.size}, {args.spp} spp, best of {args.repeat} (s):")
    print(f"  one process {one:.2f}   pool of 2 {pool:.2f} ({one / pool:.2f}x)   "
          f"LocalCluster of 2 {dask:.2f} ({one / dask:.2f}x one process, {pool / dask:.2f}x the pool)")
    here, extra, pool_extra = unit_overhead(args.units)
    print(f"overhead per unit ({args.units} units of 4x4 x 1 spp): traced here {here:.2f} ms; worker time "
          f"beyond that: LocalCluster {extra:.2f} ms, pool {pool_extra:.2f} ms")
    for label, options in (("LocalCluster", {"cluster": LOCAL}), ("pool", {"in_process": False})):
        new = fog(args.size, args.spp, seed=1)
        new.integrator.max_bounces = 2  # another scene for the workers: another tracer to build
        first, _ = timed(new, workers=2, **options)
        print(f"time to first image, new scene, running {label}: {first:.2f} s")
    print(f"starting a LocalCluster of 2 workers: {start:.2f} s")
    shutdown_clusters()
    return 0
