"""How Haze's cost per sample scales: `.venv/bin/python -m bench scaling [--quick]`. Prints tables.

One core, in this process (no worker start-up), after a warm-up pass; each row renders
until at least --seconds have passed. Four sweeps:

* resolution: the fog Cornell box (g = 0, max_bounces 3) at 32..512 pixels square;
* triangles: an icosphere (20 x 4^k triangles, up to ~1.3M) on the Cornell box floor;
* grid size: one smooth density field sampled at 32^3..256^3 voxels, so the optical
  thickness is the same at every size (it is a property of the field, not of the grid);
* optical thickness: the same field at 64^3 scaled to a peak optical thickness across the
  box of 0.1..100, and a homogeneous box of the same thickness.

Columns: ns per sample (CPU time of the tracing, per pixel sample), M samples/s, path
vertices per sample (Embree rays per sample), and the set-up: scene compile (BVH, light
table, majorant grid) plus the Tracer (Embree scene).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np

from examples.media_scenes import grid_box_mesh, grid_medium, interface_material, with_grid_medium
from examples.scenes import cornell_box, cornell_fog, diffuse, icosphere
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer
from renderer.scene import Medium, Mesh, Scene

BALL_CENTER = (0.0, -0.4, 0.0)
BALL_HALF = 0.55
SMALL_SIZE = 64  # image size of the sweeps that are not about resolution



@dataclass
class Timing:
    ns_per_sample: float
    vertices_per_sample: float
    setup_s: float


def measure(scene: Scene, seconds: float) -> Timing:
    """Trace whole-image passes of 1, 2, 4, ... spp until `seconds` of tracing have passed."""
    start = time.perf_counter()
    compiled = compile_scene(scene)
    tracer = Tracer(compiled, scene.integrator)
    setup = time.perf_counter() - start
    pixels = compiled.width * compiled.height
    tracer.trace(Film(compiled.width, compiled.height), 0, 1, 0)  # warm-up: caches, first-call costs
    rays_before, traced, spp, elapsed = tracer.stats["rays"], 0, 1, 0.0
    while elapsed < seconds:
        film = Film(compiled.width, compiled.height)
        t = time.process_time()
        tracer.trace(film, 1 + traced, spp, 0)
        elapsed += time.process_time() - t
        traced += spp
        spp *= 2
    samples = pixels * traced
    return Timing(1e9 * elapsed / samples, (tracer.stats["rays"] - rays_before) / samples, setup)


def row(label: str, timing: Timing) -> str:
    return (f"| {label} | {timing.ns_per_sample:,.0f} | {1e3 / timing.ns_per_sample:.3f} | "
            f"{timing.vertices_per_sample:.2f} | {timing.setup_s:.2f} |")


HEADER = ["| {} | ns / sample | M samples/s | vertices / sample | set-up s |", "|---|---:|---:|---:|---:|"]


def table(title: str, first_column: str, rows: list[str]) -> None:
    print(f"\n### {title}\n")
    print(HEADER[0].format(first_column))
    print(HEADER[1])
    for line in rows:
        print(line, flush=True)


def resolution_sweep(sizes: list[int], seconds: float) -> None:
    def rows():
        for size in sizes:
            yield row(f"{size}x{size}", measure(cornell_fog(size, 1, g=0.0, max_bounces=3), seconds))

    table("Resolution (fog Cornell box, g = 0)", "image", list(rows()))


def sphere_scene(subdivisions: int) -> Scene:
    scene = cornell_box(SMALL_SIZE, 1, max_bounces=3, boxes=False)
    vertices, indices = icosphere(subdivisions, 0.45)
    scene.materials.append(diffuse("sphere", (0.6, 0.6, 0.6)))
    scene.meshes.append(Mesh("sphere", vertices + np.float32([0.0, -0.55, 0.0]), indices, ["sphere"]))
    return scene


def triangle_sweep(levels: list[int], seconds: float) -> None:
    def rows():
        for k in levels:
            scene = sphere_scene(k)
            yield row(f"{sum(len(m.indices) for m in scene.meshes):,}", measure(scene, seconds))

    table(f"Triangles (icosphere in the Cornell box, {SMALL_SIZE}x{SMALL_SIZE})", "triangles", list(rows()))


def smooth_field(n: int) -> np.ndarray:
    """A soft ball: exp(-r^2 / (2 * 0.18^2)) around the box centre, r in box units, 0 on the faces.
    The same continuous field at every resolution (voxel centres at (k + 1/2)/n)."""
    axis = (np.arange(n) + 0.5) / n - 0.5
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    field = np.exp(-(x * x + y * y + z * z) / (2 * 0.18**2))
    field[[0, -1]] = field[:, [0, -1]] = field[:, :, [0, -1]] = 0.0
    return field.astype(np.float32)


def central_optical_thickness(field: np.ndarray, sigma_t: float) -> float:
    """Optical thickness along the line through the box centre, across the box."""
    n = field.shape[0]
    line = field[n // 2, n // 2, :]  # voxel samples of the field along x
    return float(sigma_t * line.mean() * 2 * BALL_HALF)


def grid_scene(n: int, tau: float) -> Scene:
    """The smooth field at n^3 in the Cornell box, scaled to optical thickness `tau` across it."""
    field = smooth_field(n)
    sigma_t = tau / central_optical_thickness(field, 1.0)
    albedo = 0.8
    medium = grid_medium("ball", field, BALL_CENTER, (BALL_HALF,) * 3, (sigma_t * (1 - albedo),) * 3,
                         (sigma_t * albedo,) * 3)
    scene = with_grid_medium(cornell_box(SMALL_SIZE, 1, boxes=False), medium)
    scene.integrator.max_bounces = 8
    return scene


def homogeneous_scene(tau: float) -> Scene:
    """A homogeneous box of the same size with optical thickness `tau` across it."""
    sigma_t = tau / (2 * BALL_HALF)
    albedo = 0.8
    scene = cornell_box(SMALL_SIZE, 1, max_bounces=8, boxes=False)
    scene.media.append(Medium("ball", sigma_a=(sigma_t * (1 - albedo),) * 3, sigma_s=(sigma_t * albedo,) * 3))
    scene.materials.append(interface_material())
    scene.meshes.append(grid_box_mesh("ball_box", "ball", BALL_CENTER, (BALL_HALF,) * 3))
    return scene


def grid_sweep(sizes: list[int], seconds: float, tau: float) -> None:
    def rows():
        for n in sizes:
            yield row(f"{n}^3", measure(grid_scene(n, tau), seconds))

    table(f"Grid size (smooth ball, optical thickness {tau:g} across, {SMALL_SIZE}x{SMALL_SIZE}, "
          "max_bounces 8)", "grid", list(rows()))


def thickness_sweep(taus: list[float], seconds: float, n: int) -> None:
    def rows():
        for tau in taus:
            yield row(f"{tau:g}, grid {n}^3", measure(grid_scene(n, tau), seconds))
            yield row(f"{tau:g}, homogeneous", measure(homogeneous_scene(tau), seconds))

    table(f"Optical thickness across the ball ({SMALL_SIZE}x{SMALL_SIZE}, albedo 0.8, max_bounces 8)",
          "tau", list(rows()))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench scaling", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rows, shorter measurements")
    parser.add_argument("--seconds", type=float, default=None, help="tracing time per row")
    args = parser.parse_args(argv)
    seconds = args.seconds or (0.3 if args.quick else 2.0)
    resolution_sweep([32, 128] if args.quick else [32, 64, 128, 256, 512], seconds)
    triangle_sweep([0, 4] if args.quick else [0, 2, 4, 6, 7, 8], seconds)
    grid_sweep([32, 64] if args.quick else [32, 64, 128, 256], seconds, 10.0)
    thickness_sweep([0.1, 10.0] if args.quick else [0.1, 1.0, 10.0, 100.0], seconds, 64)
    return 0
