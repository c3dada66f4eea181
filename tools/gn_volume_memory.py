"""Peak memory of exporting a large geometry-node volume.

    .venv/bin/python tools/gn_volume_memory.py [--res 400] [--repo CHECKOUT]

A Volume object whose geometry-nodes modifier outputs a Volume Cube (RES^3 voxels over
-1..1) with a noise density in a spherical shell (radius 0.85, 0.06 thick: its bounding box
is nearly the whole cube, its voxels a few % of it), under a Principled Volume: the kind of
volume only the geometry-node sampler can read. One fresh Python process with bpy per run:
it evaluates the volume, then exports the scene (addon.export.scene.export_scene, this
checkout's add-on, or --repo another checkout's), and prints the process's RSS before the
export and its peak RSS during the export (Linux: the peak is reset through
/proc/self/clear_refs first, so Blender's evaluation of the cube before the export does not
count; the sampler's own evaluation of it, in its temporary scene, does), the peak of the
Python and numpy allocations during the export (tracemalloc: Haze's arrays without
Blender's), the export's time and how the density was stored. Run it on two checkouts to compare.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SCRIPT = r'''
import json, sys, time, tracemalloc
sys.path.insert(0, {repo!r})
import bpy
import numpy as np

RES = {res}


def status_mb(field):
    for line in open("/proc/self/status"):
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024.0


def reset_peak():
    """Linux: the peak RSS (VmHWM) starts again from the current RSS."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


bpy.ops.wm.read_factory_settings(use_empty=True)
from addon import register  # noqa: E402  the add-on of the checkout, as a developer enables it
register()
scene = bpy.context.scene
scene.render.engine = "HAZE"
camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(camera)
camera.location = (0.0, -5.0, 0.0)
camera.rotation_euler = (1.5708, 0.0, 0.0)
scene.camera = camera
material = bpy.data.materials.new("Smoke")
material.use_nodes = True
nodes = material.node_tree.nodes
nodes.clear()
volume_shader = nodes.new("ShaderNodeVolumePrincipled")
output = nodes.new("ShaderNodeOutputMaterial")
material.node_tree.links.new(volume_shader.outputs[0], output.inputs["Volume"])
obj = bpy.data.objects.new("Volume", bpy.data.volumes.new("Volume"))
scene.collection.objects.link(obj)
obj.data.materials.append(material)
tree = bpy.data.node_groups.new("Sphere", "GeometryNodeTree")
tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
n, link = tree.nodes.new, tree.links.new
cube = n("GeometryNodeVolumeCube")
for axis in "XYZ":
    cube.inputs["Resolution " + axis].default_value = RES
length = n("ShaderNodeVectorMath")
length.operation = "LENGTH"
link(n("GeometryNodeInputPosition").outputs[0], length.inputs[0])
offset = n("ShaderNodeMath")
offset.operation = "SUBTRACT"
offset.inputs[1].default_value = 0.85
link(length.outputs["Value"], offset.inputs[0])
distance = n("ShaderNodeMath")
distance.operation = "ABSOLUTE"
link(offset.outputs[0], distance.inputs[0])
inside = n("ShaderNodeMath")
inside.operation = "LESS_THAN"
inside.inputs[1].default_value = 0.03
link(distance.outputs[0], inside.inputs[0])
noise = n("ShaderNodeTexNoise")
noise.inputs["Scale"].default_value = 3.0
density = n("ShaderNodeMath")
density.operation = "MULTIPLY"
link(inside.outputs[0], density.inputs[0])
link(noise.outputs["Fac"], density.inputs[1])
link(density.outputs[0], cube.inputs["Density"])
assign = n("GeometryNodeSetMaterial")
assign.inputs["Material"].default_value = material
link(cube.outputs["Volume"], assign.inputs["Geometry"])
link(assign.outputs["Geometry"], n("NodeGroupOutput").inputs[0])
obj.modifiers.new("Sphere", "NODES").node_group = tree
depsgraph = bpy.context.evaluated_depsgraph_get()
obj.evaluated_get(depsgraph)
from addon.export.scene import export_scene  # noqa: E402
reset_peak()
before = status_mb("VmRSS")
tracemalloc.start()
start = time.perf_counter()
exported = export_scene(depsgraph, render_depsgraph=False)
seconds = time.perf_counter() - start
peak = status_mb("VmHWM")
arrays_peak = tracemalloc.get_traced_memory()[1] / 2**20
tracemalloc.stop()
(medium,) = exported.scene.media
grid = medium.density
stored = (f"sparse, {{len(grid.bricks)}} of {{grid.index.size}} bricks" if hasattr(grid, "bricks")
          else f"dense {{tuple(grid.shape)}}")
print(json.dumps({{"rss_before_export_mb": round(before), "peak_during_export_mb": round(peak),
                  "export_peak_increase_mb": round(peak - before),
                  "python_numpy_peak_mb": round(arrays_peak),
                  "export_s": round(seconds, 2), "density": stored, "warnings": exported.warnings}}))
'''


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", type=int, default=400)
    parser.add_argument("--repo", type=Path, default=REPO, help="the checkout whose add-on exports")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as home:
        env = dict(os.environ, HOME=home, BLENDER_USER_RESOURCES=home)
        script = SCRIPT.format(repo=str(args.repo.resolve()), res=args.res)
        run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True)
    lines = [line for line in run.stdout.splitlines() if line.startswith("{")]
    if run.returncode != 0 or not lines:
        sys.exit(f"the run failed ({run.returncode}):\n{run.stderr[-3000:]}")
    print(json.dumps({"repo": str(args.repo), "res": args.res, **json.loads(lines[-1])}))


if __name__ == "__main__":
    main()
