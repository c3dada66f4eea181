"""Warm material-preview time with Haze (issue 16 asks for at most 2 s), for a surface and
a volume material.

    .venv/bin/python -m bench preview_time [--repeats 3] [--workers 0] [--samples N] [--profile]
                                           [--json out.json]

One bpy subprocess (fresh HOME and Blender user folders; the kernel cache of the tests,
bench.blender.shared_numba_cache, so a checkout whose tests ran is warm) registers the
add-on of this checkout and makes two materials with a fake user: "Surface" (a Diffuse
BSDF) and "Volume" (Principled Volume only, density 2). bpy.ops.wm.previews_ensure()
renders every material's icon (32x32) and preview (128x128) synchronously, through the
code the Material tab's preview jobs run (ED_preview_icon_render), with the scene's render
engine: a first call compiles what the preview scene needs and starts the worker (not
timed). Then, --repeats times per material, only that material's preview is tagged
(preview.reload()) and previews_ensure() is timed: that wall time is what a user waits for
the icon and the preview after an edit. The time each Haze render session took (inside
Blender's call) is recorded too, from RenderSession.run.

--workers: the scene's Haze workers (default 0, the add-on's default: one per core).
--samples: the previews' samples instead of addon.session.PREVIEW_SAMPLES and
PREVIEW_VOLUME_SAMPLES (to split a
preview's time into a fixed part and a part per sample). --profile: cProfile over the warm
calls of the volume material; prints the 25 functions of largest cumulative time.

Prints the machine's load average (the 2-core VM is shared: times scale with load), one line
per warm call, and per material the median wall time of previews_ensure and of its sessions.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

from bench.blender import run_blender, shared_numba_cache

BODY = r'''
import cProfile
import io
import pstats
import time
import bpy
import bpy_helpers as H
import blender_cornell as C
session = H.addon_module("session")

REPEATS = {repeats}
PROFILE = {profile}
if {samples} > 0:
    session.PREVIEW_SAMPLES = session.PREVIEW_VOLUME_SAMPLES = {samples}
calls = []
_run = session.RenderSession.run


def counted(self):
    started = time.monotonic()
    _run(self)
    calls.append({{"seconds": time.monotonic() - started, "size": [self.width, self.height],
                  "spp": getattr(self.latest, "spp", 0)}})


session.RenderSession.run = counted


def volume_material():
    material, tree, out = C.node_material("Volume")
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Density"].default_value = 2.0
    tree.links.new(node.outputs[0], out.inputs["Volume"])
    return material


def main():
    H.enable_addon()
    scene = C.clear_scene()
    scene.render.engine = "HAZE"
    scene.haze.workers = {workers}
    materials = [C.diffuse_material("Surface", (0.8, 0.2, 0.1)), volume_material()]
    for material in materials:
        material.use_fake_user = True  # previews_ensure skips data-blocks nobody uses
        material.preview_ensure()
    started = time.monotonic()
    bpy.ops.wm.previews_ensure()
    out = {{"cold_seconds": time.monotonic() - started, "warm": [], "profile": ""}}
    for material in materials:
        profiler = cProfile.Profile() if PROFILE and material.name == "Volume" else None
        for _ in range(REPEATS):
            del calls[:]
            material.preview.reload()
            if profiler:
                profiler.enable()
            started = time.monotonic()
            bpy.ops.wm.previews_ensure()
            seconds = time.monotonic() - started
            if profiler:
                profiler.disable()
            out["warm"].append({{"material": material.name, "seconds": seconds, "sessions": list(calls)}})
        if profiler:
            text = io.StringIO()
            pstats.Stats(profiler, stream=text).sort_stats("cumulative").print_stats(25)
            out["profile"] = text.getvalue()
    return out
'''


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench preview_time", description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=0)
    parser.add_argument("--samples", type=int, default=0)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        run = run_blender(BODY.format(repeats=args.repeats, profile=args.profile, workers=args.workers,
                                      samples=args.samples), Path(tmp),
                          timeout=1800, numba_cache=shared_numba_cache())
    if run.returncode != 0 or not run.result:
        sys.exit(run.describe())
    result = run.result
    print(f"cold previews_ensure (compile, worker start): {result['cold_seconds']:.2f} s")
    for call in result["warm"]:
        sessions = ", ".join(f"{s['size'][0]}x{s['size'][1]} {s['spp']} spp {s['seconds']:.2f} s"
                             for s in call["sessions"])
        print(f"warm {call['material']:8s} previews_ensure {call['seconds']:.2f} s  sessions: {sessions}")
    for name in ("Surface", "Volume"):
        walls = [c["seconds"] for c in result["warm"] if c["material"] == name]
        inside = [sum(s["seconds"] for s in c["sessions"]) for c in result["warm"] if c["material"] == name]
        print(f"{name}: median warm previews_ensure {statistics.median(walls):.2f} s "
              f"(Haze sessions {statistics.median(inside):.2f} s)")
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if result["profile"]:
        print(result["profile"])
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return 0
