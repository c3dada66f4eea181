"""The 512^3 cloud: `python -m bench cloud512 [--data DIR] [--spp 4] [--size 96]`. Prints figures.

Issue 18's closing benchmark. A .vdb cloud in a 512^3 index box (a noisy cumulus, about
18 M active voxels, written once with Blender's openvdb module and cached under DIR,
default ~/.cache/haze-bench, never in git), a .blend with a Volume object loading it
(Principled Volume, a sun and a grey sky, 96x96), rendered with Cycles and with Haze (the
extension zip built from this checkout and installed, as users get it; bench/installed.py)
at 4 samples per pixel, each in a fresh Python process with bpy.
Haze renders once first to fill its kernel cache (not measured), then both are measured.

Reported per renderer: time to first image (process start to the written EXR: bpy
import, .blend load, scene export or sync, render) and peak memory of the whole process
tree, sampled every 50 ms: the sum of RSS (shared pages counted once per process) and the
sum of PSS (shared pages divided among the processes mapping them: the machine's real
cost). Floors (issue 18): Haze peak <= 2x Cycles', time <= 3x Cycles'.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.installed import blender_environment

REPO = Path(__file__).resolve().parents[1]
N = 512
RADIUS = 0.34  # of the box: about 18 M voxels above the threshold with the noise below

WRITE = r'''
import sys, numpy as np
import bpy
sys.path.append(bpy.utils.resource_path("LOCAL") + "/python/lib/python3.11/site-packages")
import openvdb as vdb  # Blender's own OpenVDB module
n, radius = {n}, {radius}
rng = np.random.default_rng(18)
coarse = rng.random((17, 17, 17))  # value noise: trilinear on a 16-cell lattice


def weights(coordinates, octave):
    """(len, 17) trilinear weights of value-noise lattice points at unit coordinates."""
    f = np.clip(coordinates * 16 * octave % 16, 0, 15.999)
    i = np.floor(f).astype(int)
    w = np.zeros((len(f), 17))
    w[np.arange(len(f)), i] = 1.0 - (f - i)
    w[np.arange(len(f)), i + 1] = f - i
    return w


def noise(first, second, third):
    """Value noise (two octaves) on the lattice spanned by three 1-D coordinate arrays, as an
    array over (first, second, third): separable, so a slab is three small matrix products."""
    total = 0.0
    for octave, weight in ((1, 0.65), (3, 0.35)):
        wa, wb, wc = (weights(c, octave) for c in (first, second, third))
        total = total + weight * np.einsum("abc,ia,jb,kc->ijk", coarse, wa, wb, wc, optimize=True)
    return total


grid = vdb.FloatGrid()
grid.name = "density"
grid.transform = vdb.createLinearTransform(voxelSize=2.0 / n)
c = (np.arange(n) + 0.5) / n
slab = 16
for z0 in range(0, n, slab):
    zs = c[z0:z0 + slab]
    z, y, x = np.meshgrid(zs, c, c, indexing="ij")
    # A cumulus: a sphere flattened below, its radius modulated by noise.
    dz = (z - 0.5) * np.where(z < 0.5, 1.6, 1.0)
    r = np.sqrt(dz * dz + (y - 0.5) ** 2 + (x - 0.5) ** 2)
    bumpy = radius * (0.75 + 0.5 * noise(zs, c, c))
    detail = noise(c, zs, c).transpose(1, 2, 0)  # another pattern: the lattice's axes turned
    density = np.clip((bumpy - r) / (0.15 * radius), 0.0, 1.0) * (0.5 + detail)
    grid.copyFromArray(np.ascontiguousarray(density.astype(np.float32).transpose(2, 1, 0)), ijk=(0, 0, z0),
                       tolerance=0.0)
vdb.write({path!r}, grids=[grid])
print("active voxels", grid.activeVoxelCount())
'''

BUILD = r'''
import math, sys, bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
volume = bpy.data.volumes.new("Cloud")
volume.filepath = {vdb!r}
cloud = bpy.data.objects.new("Cloud", volume)
scene.collection.objects.link(cloud)
cloud.location = (-1.0, -1.0, -1.0)
material = bpy.data.materials.new("Cloud")
material.use_nodes = True
tree = material.node_tree
tree.nodes.clear()
out = tree.nodes.new("ShaderNodeOutputMaterial")
node = tree.nodes.new("ShaderNodeVolumePrincipled")
node.inputs["Density"].default_value = 20.0
tree.links.new(node.outputs[0], out.inputs["Volume"])
volume.materials.append(material)
camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(camera)
camera.location = (0.0, -3.6, 0.3)
camera.rotation_euler = (math.radians(86), 0.0, 0.0)
scene.camera = camera
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (math.radians(40), math.radians(20), 0.0)
scene.collection.objects.link(sun)
world = bpy.data.worlds.new("Sky")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs[0].default_value = (0.4, 0.5, 0.7, 1.0)
scene.world = world
scene.render.resolution_x = scene.render.resolution_y = {size}
scene.render.resolution_percentage = 100
bpy.ops.wm.save_as_mainfile(filepath={blend!r})
'''

RENDER = r'''
import sys, bpy
sys.path.append({repo!r})  # appended: the installed extension's renderer comes first
bpy.ops.wm.open_mainfile(filepath={blend!r})
scene = bpy.context.scene
if {engine!r} == "HAZE":
    from bench.installed import enable_installed
    enable_installed()  # Haze as users get it: the extension zip, installed
    scene.render.engine = "HAZE"
    scene.haze.samples = {spp}
    scene.haze.max_bounces = 8
else:
    scene.render.engine = "CYCLES"
    scene.cycles.samples = {spp}
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 8
    # Every kind of bounce to the same limit, as Haze's max_bounces: Cycles' volume_bounces
    # defaults to 0 (single scattering in the cloud), which left its image 2 % darker.
    for kind in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(scene.cycles, kind, 8)
    scene.cycles.device = "CPU"
settings = scene.render.image_settings
settings.file_format, settings.color_depth = "OPEN_EXR", "32"
scene.render.filepath = {out!r}
bpy.ops.render.render(write_still=True)
'''


def _python(code: str, env: dict[str, str], cwd: Path) -> subprocess.Popen:
    """`python -c code` in `cwd`: not the checkout, whose renderer/ would come first on sys.path."""
    return subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=cwd)


def _tree_memory(pid: int) -> dict[str, tuple[int, int]]:
    """{process label: (RSS, PSS) in bytes} of process pid ("main") and its descendants
    (labelled by their command line, pid included)."""
    import psutil

    try:
        root = psutil.Process(pid)
        processes = [root] + root.children(recursive=True)
    except psutil.NoSuchProcess:
        return {}
    found = {}
    for p in processes:
        try:
            text = Path(f"/proc/{p.pid}/smaps_rollup").read_text()
            label = "main" if p.pid == pid else f"{p.pid} {' '.join(p.cmdline())[-40:]}"
        except (OSError, psutil.Error):
            continue
        fields = {line.split(":")[0]: int(line.split()[1]) * 1024 for line in text.splitlines()[1:]}
        found[label] = (fields.get("Rss", 0), fields.get("Pss", 0))
    return found


def measure(code: str, env: dict[str, str], out: Path) -> dict[str, float]:
    """Run `code` in a fresh Python; seconds until `out` exists and peak tree memory (with
    each process's RSS and PSS at the tree's PSS peak, in "at_peak")."""
    out.unlink(missing_ok=True)
    start = time.perf_counter()
    process = _python(code, env, out.parent)
    peak_rss = peak_pss = 0
    at_peak: dict[str, tuple[int, int]] = {}
    first = None
    while process.poll() is None:
        tree = _tree_memory(process.pid)
        rss, pss = sum(r for r, _ in tree.values()), sum(p for _, p in tree.values())
        if pss > peak_pss:
            at_peak = tree
        peak_rss, peak_pss = max(peak_rss, rss), max(peak_pss, pss)
        if first is None and out.exists():
            first = time.perf_counter() - start
        time.sleep(0.05)
    log = process.stdout.read()
    if process.returncode != 0 or not out.exists():
        raise RuntimeError(f"render failed ({process.returncode}):\n{log[-3000:]}")
    elapsed = time.perf_counter() - start
    return {"first_image": first or elapsed, "total": elapsed, "rss": peak_rss / 2**30,
            "pss": peak_pss / 2**30, "at_peak": at_peak, "log": log}


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench cloud512", description=__doc__.splitlines()[0])
    default = os.environ.get("HAZE_BENCH_DATA", Path.home() / ".cache" / "haze-bench")
    parser.add_argument("--data", type=Path, default=Path(default))
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--n", type=int, default=N, help="voxels per axis of the index box (a smaller cloud)")
    args = parser.parse_args(argv)
    args.data.mkdir(parents=True, exist_ok=True)
    vdb, blend = args.data / f"cloud{args.n}.vdb", args.data / f"cloud{args.n}_{args.size}.blend"
    env = dict(os.environ)
    if not vdb.exists():
        t = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", WRITE.format(n=args.n, radius=RADIUS, path=str(vdb))],
                              env=env, capture_output=True, text=True)
        if done.returncode != 0:
            print(done.stdout[-2000:], done.stderr[-3000:])
            return 1
        print(f"wrote {vdb} ({vdb.stat().st_size / 2**20:.0f} MB) in {time.perf_counter() - t:.0f} s:",
              done.stdout.strip().splitlines()[-1])
    if not blend.exists():
        subprocess.run([sys.executable, "-c", BUILD.format(vdb=str(vdb), size=args.size, blend=str(blend))],
                       env=env, check=True, capture_output=True)
    results = {}
    with tempfile.TemporaryDirectory(prefix="haze-cloud512-") as tmp:
        env = blender_environment(Path(tmp) / "blender_user", env)  # Haze from the installed zip
        for label, engine in (("haze (cache fill)", "HAZE"), ("cycles", "CYCLES"), ("haze", "HAZE")):
            out = Path(tmp) / f"{engine.lower()}.exr"
            code = RENDER.format(repo=str(REPO), blend=str(blend), engine=engine, spp=args.spp, out=str(out))
            results[label] = r = measure(code, env, out)
            print(f"{label:18s} first image {r['first_image']:6.1f} s  peak tree RSS {r['rss']:.2f} GB, "
                  f"PSS {r['pss']:.2f} GB", flush=True)
            for name, (rss, pss) in r["at_peak"].items():
                print(f"    at the PSS peak: {name:48s} RSS {rss / 2**20:6.0f} MB, PSS {pss / 2**20:6.0f} MB")
            if engine == "HAZE":
                for line in r["log"].splitlines():
                    if line.startswith("Haze:"):
                        print("   ", line)
            results[label]["image"] = _mean(out)
    h, c = results["haze"], results["cycles"]
    print(f"image means: cycles {np.round(c['image'], 4)}, haze {np.round(h['image'], 4)}")
    print(f"haze / cycles: time {h['first_image'] / c['first_image']:.2f}x (floor 3x), "
          f"peak RSS {h['rss'] / c['rss']:.2f}x, PSS {h['pss'] / c['pss']:.2f}x (floor 2x)")
    print(f"load: {os.getloadavg()}")
    return 0


def _mean(path: Path) -> np.ndarray:
    from renderer.imageio import read_exr

    return read_exr(str(path))[..., :3].reshape(-1, 3).mean(axis=0)
