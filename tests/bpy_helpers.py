"""Helpers for tests that need Blender (the bpy module).

Everything touching bpy runs in a subprocess, so a crash in Blender fails one test instead
of the whole run, and each run gets fresh HOME / BLENDER_USER_RESOURCES folders so nothing
of the developer's own Blender setup is read or changed.

This module has two halves:
* host side (pytest): `run_blender` writes a script, runs it, returns its JSON result;
  `compare_images` is the statistical comparison of two renderers;
* Blender side (imported by those scripts): scene builders and render helpers. bpy is
  imported inside the functions, so pytest can import this file without Blender.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TESTS = REPO / "tests"
EXAMPLES = REPO / "examples"
PYTHON = sys.executable

# Packages the installed extension must bring itself (never taken from the test venv).
BUNDLED_MODULES = ("numba", "llvmlite", "embreex", "OpenEXR", "Imath", "openexr", "renderer",
                   # cluster rendering (packaging, zipp and importlib_metadata stay: others use them)
                   "dask", "distributed", "click", "cloudpickle", "fsspec", "jinja2", "lazy_importer",
                   "locket", "partd", "sortedcontainers", "tblib", "toolz", "zict", "msgpack", "psutil",
                   "yaml", "_yaml", "pyyaml", "tornado", "markupsafe")

PRELUDE = """\
import json, os, sys
for _path in {paths!r}:
    if _path not in sys.path:
        sys.path.insert(0, _path)
"""

ADDON_MODE_ENV = "HAZE_TEST_ADDON"
EXTENSION_PACKAGE = "bl_ext.user_default.haze"  # bench.installed.PACKAGE (not imported: Blender side)

EPILOGUE = """
if __name__ == "__main__":
    _result = main()
    with open(os.environ["HAZE_TEST_RESULT"], "w") as _file:
        json.dump(_result if _result is not None else {}, _file)
"""


@dataclass
class BlenderRun:
    returncode: int
    stdout: str
    stderr: str
    result: dict

    def describe(self) -> str:
        return f"exit code {self.returncode}\n--- stdout ---\n{self.stdout[-6000:]}\n" \
               f"--- stderr ---\n{self.stderr[-6000:]}"


def blender_environment(tmp: Path, numba_cache: Path | None) -> dict[str, str]:
    """Environment of a Blender subprocess: private user folders, shared numba cache."""
    home = tmp / "home"
    user = tmp / "blender_user"
    home.mkdir(parents=True, exist_ok=True)
    user.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_", "NUMBA_", "PYTHON", "HAZE_"))}
    env.update(HOME=str(home), BLENDER_USER_RESOURCES=str(user), XDG_CACHE_HOME=str(home / ".cache"),
               XDG_CONFIG_HOME=str(home / ".config"), PYTHONUNBUFFERED="1")
    # No background compile at add-on enable unless a test asks for it (HAZE_BACKGROUND_COMPILE=1;
    # headless Blender has it off by default anyway): it would compete for the two cores.
    env["HAZE_BACKGROUND_COMPILE"] = "0"
    if numba_cache is not None:
        env["NUMBA_CACHE_DIR"] = str(numba_cache)
    return env


def shared_numba_cache() -> Path:
    """Numba cache for dev-mode Blender runs, kept between test sessions.

    Compiling the renderer takes a minute or more, so the cache is reused - but only for the
    exact renderer sources it was built from (numba does not notice edits in called modules),
    hence one folder per hash of those sources, under build/ (never committed).
    """
    digest = hashlib.sha256()
    for path in sorted((REPO / "renderer").rglob("*.py")):
        digest.update(path.relative_to(REPO).as_posix().encode())
        digest.update(path.read_bytes())
    folder = REPO / "build" / "numba-test-cache" / digest.hexdigest()[:16]
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def isolated_site(tmp: Path) -> Path:
    """A site folder with the venv's packages except those the extension must bundle.

    Run with `python -S` and this folder on sys.path, Blender can only find numba, embreex,
    OpenEXR and the renderer in the extension's own wheels.
    """
    site = tmp / "site"
    site.mkdir(parents=True, exist_ok=True)
    venv_site = Path(np.__file__).resolve().parents[1]
    for entry in venv_site.iterdir():
        lowered = entry.name.lower()
        if entry.name.endswith(".pth") or entry.name == "__pycache__":
            continue
        if any(lowered.startswith(name.lower()) for name in BUNDLED_MODULES):
            continue
        (site / entry.name).symlink_to(entry)
    return site


def addon_mode() -> str:
    """How Blender runs get Haze: "installed" (the default, and CI's: the extension zip built
    from this checkout, installed into the run's user folder, with its bundled renderer wheel)
    or "clone" (HAZE_TEST_ADDON=clone: the checkout's addon/ and renderer/, for quick local
    iteration only; no figure or CI run uses it)."""
    mode = os.environ.get(ADDON_MODE_ENV, "installed")
    if mode not in ("installed", "clone"):
        raise ValueError(f"{ADDON_MODE_ENV} must be 'installed' or 'clone', not {mode!r}")
    return mode


def run_blender(body: str, tmp: Path, *, timeout: float = 900.0, numba_cache: Path | None = None,
                dev_paths: bool = True, site: Path | None = None, env: dict[str, str] | None = None
                ) -> BlenderRun:
    """Run `body` (Python source defining `main() -> dict`) with bpy in a subprocess.

    dev_paths: the run may enable Haze (bpy_helpers.enable_addon) and import tests/ and
    examples/; Haze is the installed extension (copied into the run's user folder, the
    process isolated from the venv's copies of the bundled packages) unless addon_mode() is
    "clone", where the repository goes on sys.path. dev_paths=False: only tests/ and `site`,
    for tests that install a zip themselves. site: run isolated (python -S) with only this
    site folder for packages. env: extra environment variables.
    """
    tmp.mkdir(parents=True, exist_ok=True)
    mode = addon_mode() if dev_paths else "none"
    paths = [str(TESTS), str(EXAMPLES)] if dev_paths else [str(TESTS)]
    if mode == "clone":
        paths.append(str(REPO))
    if mode == "installed" and site is None:
        site = isolated_site(tmp)
    if site is not None:
        paths.append(str(site))
    script = tmp / "blender_script.py"
    script.write_text(PRELUDE.format(paths=paths) + textwrap.dedent(body) + EPILOGUE)
    result_file = tmp / "result.json"
    extra = env or {}
    env = blender_environment(tmp, numba_cache)
    env.update(extra, HAZE_TEST_RESULT=str(result_file), **{ADDON_MODE_ENV: mode})
    if mode == "installed":  # into the user folder the run really uses (a test may share one)
        from bench.installed import copy_install, installed_user_folder

        copy_install(installed_user_folder(), Path(env["BLENDER_USER_RESOURCES"]))
    command = [PYTHON, "-S", str(script)] if site is not None else [PYTHON, str(script)]
    process = subprocess.run(command, cwd=tmp, env=env, capture_output=True, text=True, timeout=timeout)
    result = json.loads(result_file.read_text()) if result_file.is_file() else {}
    return BlenderRun(process.returncode, process.stdout, process.stderr, result)


# ------------------------------------------------------------------------------ statistics


@dataclass
class Comparison:
    """Haze against a reference renderer, from K independent renders of each."""

    relative_mean_difference: np.ndarray  # (3,) (mean_haze - mean_ref) / mean_ref per channel
    relative_mean_sigma: np.ndarray  # (3,) standard deviation of that difference (noise)
    block_z: np.ndarray  # (blocks_y, blocks_x, 3) z-scores of block-mean differences
    chi_square: float  # sum of squared z of the blocks' channel sums (see compare_images)
    degrees: int  # number of block z-scores (blocks x channels)
    chi_degrees: int  # number of blocks in chi_square

    def summary(self) -> str:
        worst = float(np.nanmax(np.abs(self.block_z))) if self.block_z.size else 0.0
        return (f"relative mean difference {np.round(100 * self.relative_mean_difference, 3)} % "
                f"(noise sigma {np.round(100 * self.relative_mean_sigma, 3)} %), "
                f"max |block z| {worst:.2f} of {self.degrees}, "
                f"chi2 {self.chi_square:.1f} for {self.chi_degrees} blocks (channel sums)")


def block_sums(images: np.ndarray, block: int) -> np.ndarray:
    """(K, H, W, C) -> (K, H/block, W/block, C) sums over square blocks."""
    k, h, w, c = images.shape
    return images.reshape(k, h // block, block, w // block, block, c).sum(axis=(2, 4))


def mean_and_variance(images: np.ndarray, block: int) -> tuple[np.ndarray, ...]:
    """Block means of the average of K renders and their variances.

    Pixels are independent (box filter of width 1: each sample lands in one pixel), so the
    variance of a block mean is the sum of its pixels' variances over block^2 squared; each
    pixel's variance is estimated from the spread of the K independent renders.
    """
    k = images.shape[0]
    pixel_variance = images.var(axis=0, ddof=1) / k  # variance of the K-average, per pixel
    means = block_sums(images.mean(axis=0)[None], block)[0] / block**2
    variances = block_sums(pixel_variance[None], block)[0] / block**4
    image_mean = images.mean(axis=(0, 1, 2))
    image_variance = pixel_variance.sum(axis=(0, 1)) / (images.shape[1] * images.shape[2]) ** 2
    return means, variances, image_mean, image_variance


# Both renderers compute in float32; Cycles' sun normalisation alone is only good to ~2e-4
# (1 - cos of a small angle in float32). Block sigmas are floored at this share of the block
# mean, so that deterministic regions (a uniformly lit floor, the sky) compare by precision.
FLOAT32_PRECISION = 3e-4


def compare_images(haze: np.ndarray, reference: np.ndarray, block: int = 8) -> Comparison:
    """Statistical comparison of (K, H, W, 3) stacks of independent renders of one scene."""
    h_mean, h_var, h_image, h_image_var = mean_and_variance(np.asarray(haze, np.float64), block)
    r_mean, r_var, r_image, r_image_var = mean_and_variance(np.asarray(reference, np.float64), block)
    precision = (FLOAT32_PRECISION * 0.5 * (np.abs(h_mean) + np.abs(r_mean))) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = (h_image - r_image) / r_image
        sigma = np.sqrt(h_image_var + r_image_var) / r_image
        z = (h_mean - r_mean) / np.sqrt(h_var + r_var + precision)
    z, counted = _lit_blocks(z, h_mean, h_var, r_mean, r_var)
    chi_square, chi_degrees = _channel_sum_chi_square(haze, reference, block)
    return Comparison(relative, sigma, z, chi_square, counted, chi_degrees)


def _lit_blocks(z, h_mean, h_var, r_mean, r_var) -> tuple[np.ndarray, int]:
    """Blocks without any light in either renderer (both exactly zero, no variance) carry no
    test: their z is 0 and they are not counted."""
    both_dark = (h_var + r_var == 0.0) & (h_mean == r_mean)
    return np.where(both_dark, 0.0, z), int(np.count_nonzero(~both_dark))


def _channel_sum_chi_square(haze: np.ndarray, reference: np.ndarray, block: int) -> tuple[float, int]:
    """Chi-square of the blocks' channel sums, and the number of blocks in it.

    The three channels of a block are not independent (in a grey scene their z-scores are
    nearly equal), so the sum of all 3 x blocks squared z-scores is about 3 chi2(blocks), not
    chi2(3 x blocks): its 1e-3 quantile is about half again the threshold for 3 x blocks
    independent ones (measured on the smoke ball: z of R, G and B within 0.5 of each other).
    The channel sum's variance comes from the K renders like each channel's, covariances
    included, so its z-scores are independent between blocks.
    """
    h_mean, h_var, _, _ = mean_and_variance(np.asarray(haze, np.float64).sum(-1, keepdims=True), block)
    r_mean, r_var, _, _ = mean_and_variance(np.asarray(reference, np.float64).sum(-1, keepdims=True), block)
    precision = (FLOAT32_PRECISION * 0.5 * (np.abs(h_mean) + np.abs(r_mean))) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (h_mean - r_mean) / np.sqrt(h_var + r_var + precision)
    z, counted = _lit_blocks(z, h_mean, h_var, r_mean, r_var)
    return float(np.nansum(z**2)), counted


def z_threshold(tests: int, family_alpha: float = 1e-3) -> float:
    """Two-sided normal threshold with a Bonferroni correction for `tests` z-scores."""
    from statistics import NormalDist

    return NormalDist().inv_cdf(1.0 - family_alpha / (2.0 * tests))


def chi_square_threshold(degrees: int, alpha: float = 1e-3) -> float:
    """Upper quantile of chi-square(degrees) by the Wilson-Hilferty approximation."""
    from statistics import NormalDist

    z = NormalDist().inv_cdf(1.0 - alpha)
    d = float(degrees)
    return d * (1.0 - 2.0 / (9.0 * d) + z * math.sqrt(2.0 / (9.0 * d))) ** 3


def assert_agree(comparison: Comparison, mean_tolerance: float = 0.01) -> None:
    """Image means within `mean_tolerance` and block means within noise.

    The mean test is meaningful only if noise cannot fake a 1 % difference: its sigma must be
    at most a third of the tolerance (a 3-sigma margin), otherwise the test setup is wrong.
    """
    assert np.all(comparison.relative_mean_sigma <= mean_tolerance / 3.0), (
        "too noisy for a 1% mean comparison: " + comparison.summary())
    assert np.all(np.abs(comparison.relative_mean_difference) <= mean_tolerance), comparison.summary()
    limit = z_threshold(max(comparison.degrees, 1))
    worst = float(np.max(np.abs(comparison.block_z)))
    assert worst <= limit, f"block z > {limit:.2f}: " + comparison.summary()
    chi_limit = chi_square_threshold(max(comparison.chi_degrees, 1))
    assert comparison.chi_square <= chi_limit, f"chi2 > {chi_limit:.1f}: " + comparison.summary()


# ------------------------------------------------------------------------------ Blender side


def addon_package():
    """Haze's package in this Blender run (see addon_mode), imported but not registered:
    `bl_ext.user_default.haze` of the installed extension, or the clone's `addon`."""
    import importlib

    mode = os.environ.get(ADDON_MODE_ENV)
    if mode not in ("installed", "clone"):
        raise RuntimeError("this Blender run was not started with Haze (run_blender(dev_paths=False))")
    return importlib.import_module(EXTENSION_PACKAGE if mode == "installed" else "addon")


def addon_module(name: str):
    """A module of Haze's package by its name inside the package, e.g. "export.scene"."""
    import importlib

    return importlib.import_module(f"{addon_package().__name__}.{name}")


def addon_names(module: str, *names: str) -> tuple:
    """Attributes of one of Haze's modules, as `from <package>.<module> import names` would."""
    found = addon_module(module)
    return tuple(getattr(found, name) for name in names)


def enable_addon():
    """Enable Haze as a user does (the clone's add-on is registered directly); returns its package."""
    import bpy

    package = addon_package()
    if hasattr(bpy.types.Scene, "haze"):
        return package
    if package.__name__ == "addon":
        package.register()
        return package
    import addon_utils

    def fail(error):
        raise error

    addon_utils.enable(package.__name__, default_set=True, handle_error=fail)
    _require_bundled_renderer()
    return package


def _require_bundled_renderer() -> None:
    """The installed mode's promise: `renderer` is the zip's wheel, never the checkout's (an
    example that put the repository first on sys.path would break it silently)."""
    import importlib.util

    origin = Path(importlib.util.find_spec("renderer").origin).resolve()
    bundled = Path(os.environ["BLENDER_USER_RESOURCES"]).resolve() / "extensions"
    if not origin.is_relative_to(bundled):
        raise RuntimeError(f"the renderer would be imported from {origin}, not from the installed extension")


def configure_cycles(scene, samples: int, max_bounces: int, seed: int, threads: int = 2) -> None:
    """Cycles set up as an unbiased reference with Haze's conventions.

    Same bounce limit for every kind of bounce (volume_bounces too: its default 0 would
    drop multiple scattering), box pixel filter of width 1, no denoising, no clamping, no
    glossy blur, no light threshold, no adaptive sampling.
    """
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.seed = seed
    cycles.use_animated_seed = False
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = max_bounces
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cycles, name, max_bounces)
    cycles.transparent_max_bounces = 64
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.light_sampling_threshold = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads


def configure_haze(scene, samples: int, max_bounces: int, seed: int, workers: int = 1) -> None:
    scene.render.engine = "HAZE"
    scene.haze.samples = samples
    scene.haze.max_bounces = max_bounces
    scene.haze.seed = seed
    scene.haze.workers = workers
    scene.haze.time_limit = 0.0
    scene.haze.target_error = 0.0


def render_exr(scene, path: str) -> str:
    """Render the scene with its current engine into a 32-bit float EXR (linear, lossless)."""
    import bpy

    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    settings.color_mode = "RGBA"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return path


def render_both(scene, out_dir: str, runs: int, cycles_samples: int, haze_samples: int,
                max_bounces: int) -> dict:
    """K independent renders (seeds 1..K) with Cycles and with Haze: their EXR paths."""
    paths: dict[str, list[str]] = {"cycles": [], "haze": []}
    for run in range(runs):
        configure_cycles(scene, cycles_samples, max_bounces, seed=run + 1)
        paths["cycles"].append(render_exr(scene, f"{out_dir}/cycles_{run}.exr"))
    for run in range(runs):
        configure_haze(scene, haze_samples, max_bounces, seed=run + 1)
        paths["haze"].append(render_exr(scene, f"{out_dir}/haze_{run}.exr"))
    return paths


def new_object(name: str, vertices, faces, material=None):
    """A mesh object from vertex and face lists, linked to the scene."""
    import bpy

    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], [], [tuple(f) for f in faces])
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def uv_sphere(name: str, center, radius: float, material, rings: int = 24, segments: int = 48):
    """A closed, smooth-shaded UV sphere with outward normals."""
    vertices = [(center[0], center[1], center[2] + radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2.0 * math.pi * j / segments
            vertices.append((center[0] + radius * math.sin(theta) * math.cos(phi),
                             center[1] + radius * math.sin(theta) * math.sin(phi),
                             center[2] + radius * math.cos(theta)))
    vertices.append((center[0], center[1], center[2] - radius))
    bottom = len(vertices) - 1
    faces = [(0, 1 + j, 1 + (j + 1) % segments) for j in range(segments)]
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        faces += [(a + j, b + j, b + (j + 1) % segments, a + (j + 1) % segments) for j in range(segments)]
    last = 1 + (rings - 2) * segments
    faces += [(last + (j + 1) % segments, last + j, bottom) for j in range(segments)]
    obj = new_object(name, vertices, faces, material)
    obj.data.shade_smooth()
    return obj


def floor_plane(name: str, half: float, material, z: float = 0.0):
    return new_object(name, [(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)],
                      [(0, 1, 2, 3)], material)


def ensure_nodes(datablock) -> None:
    """Turn on node shading; Blender 5.0 always uses nodes and deprecates the switch."""
    import bpy

    if bpy.app.version < (5, 0, 0):
        datablock.use_nodes = True


def principled_material(name: str, **inputs):
    """A Principled BSDF material; keyword names are input names with spaces as underscores."""
    import bpy

    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    bsdf = material.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        if key == "distribution":
            bsdf.distribution = value
            continue
        socket = bsdf.inputs[key.replace("_", " ")]
        socket.default_value = (*value, 1.0) if isinstance(value, tuple) and len(value) == 3 else value
    return material


def add_light(kind: str, name: str, location, rotation_deg=(0.0, 0.0, 0.0), **settings):
    import bpy

    data = bpy.data.lights.new(name, kind)
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def world_color(scene, color, strength: float = 1.0) -> None:
    import bpy

    world = bpy.data.worlds.new("World")
    ensure_nodes(world)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    scene.world = world
