"""Error against run time, Haze and Cycles side by side:
`python -m bench convergence [--scenes ...] [--budgets ...] [--quick]`. Prints figures;
asserts nothing.

For each benchmark scene (128x128, both cores):

* a converged Haze reference, rendered once and cached under bench/cache/ (keyed by the
  scene's content and the seed), extended with further seeds whenever a lower error is asked;
* one progressive Haze render per estimator setting, its error measured after every pass,
  so a single run gives the whole curve of error against wall time (the time counts from
  the call to render_progressive: scene compilation and worker start-up included);
* Cycles on the same scene, rebuilt in bpy by tools/cycles_reference.py (a subprocess: the
  renderer never imports bpy), at 1, 2, 4, ... samples, each render timed, until one takes
  the largest budget; plus Cycles' own converged reference (mean of four seeds, cached).

relMSE = mean((x - ref)^2 / (ref^2 + 1e-2)) minus the reference's own noise, i.e. minus the
mean of its per-pixel variance of the mean over the same denominator (both are independent,
so the expected squared differences add). Cycles is measured against its own reference
(noise) and against Haze's (noise plus any disagreement between the renderers: bias).

Output: a table per scene (budget seconds, spp, relMSE, RMSE per setting and for Cycles),
the time to relMSE 1e-2 and 1e-3 per setting (interpolated on the log-log curve, or
extrapolated along error ~ 1/(t - start-up) past the last point, marked *) with its ratio
to Cycles, tables.md and one log-log SVG per scene under docs/convergence/.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderer.film import REL_EPS, Film
from renderer.scene import Scene

REPO = Path(__file__).resolve().parents[1]
CACHE = REPO / "bench" / "cache" / "convergence"
DOCS = REPO / "docs" / "convergence"
CYCLES_TOOL = REPO / "tools" / "cycles_reference.py"

MEASURE_SEED = 1
REFERENCE_SEED = 1000  # the Haze reference uses 1000, 1001, ... (one seed per extension)
CYCLES_SEED = 1
CYCLES_REFERENCE_SEEDS = (101, 102, 103, 104)
TARGETS = (1e-2, 1e-3)
HUGE_SPP = 10**8  # "until the time budget runs out"


# ------------------------------------------------------------------------------ scenes


@dataclass
class BenchScene:
    name: str
    build: Callable[[int], Scene]
    # label -> IntegratorSettings overrides; "default" = ratio tracking, spectral MIS,
    # majorant grid, equiangular: the renderer's defaults
    settings: dict[str, dict[str, object]]
    description: str


def _cornell(size: int) -> Scene:
    from examples.scenes import cornell_box

    return cornell_box(size, 1, max_bounces=3)


def _fog(g: float) -> Callable[[int], Scene]:
    def build(size: int) -> Scene:
        from examples.scenes import cornell_fog

        return cornell_fog(size, 1, g=g, max_bounces=3)

    return build


def _smoke_ball(size: int) -> Scene:
    from examples.media_scenes import smoke_ball

    return smoke_ball(size, 1)


CHROMATIC_SIGMA_T = (30.0, 3.0, 0.3)  # per unit: 100x between red and blue
CHROMATIC_ALBEDO = 0.9


def _chromatic(size: int) -> Scene:
    """A homogeneous box of a strongly chromatic medium on the Cornell box floor: optically
    thick in red (27 across), thin in blue (0.27)."""
    from examples.media_scenes import INTERFACE, MEDIA_MAX_BOUNCES, interface_material
    from examples.scenes import box, cornell_box
    from renderer.scene import Medium, Mesh

    scene = cornell_box(size, 1, max_bounces=MEDIA_MAX_BOUNCES, boxes=False)
    sigma_s = tuple(CHROMATIC_ALBEDO * s for s in CHROMATIC_SIGMA_T)
    sigma_a = tuple((1.0 - CHROMATIC_ALBEDO) * s for s in CHROMATIC_SIGMA_T)
    scene.media.append(Medium("chromatic", sigma_a=sigma_a, sigma_s=sigma_s))
    scene.materials.append(interface_material())
    scene.meshes.append(Mesh("chromatic_box", *box((0.0, -0.55, 0.0), (0.45, 0.45, 0.45), 25), [INTERFACE],
                             medium="chromatic"))
    return scene


NO_EQUIANGULAR = {"equiangular": False}
UNIFORM = {"distance_sampling": "uniform"}
SCENES: dict[str, BenchScene] = {s.name: s for s in (
    BenchScene("cornell", _cornell, {"default": {}}, "Cornell box, surfaces only, max_bounces 3"),
    BenchScene("fog_g0", _fog(0.0), {"default": {}, "no-equiangular": NO_EQUIANGULAR, "uniform": UNIFORM},
               "Cornell box in the Fig. 1 fog, g = 0, max_bounces 3"),
    BenchScene("fog_g0.9", _fog(0.9), {"default": {}, "no-equiangular": NO_EQUIANGULAR},
               "Cornell box in the Fig. 1 fog, g = 0.9, max_bounces 3"),
    BenchScene("smoke_ball", _smoke_ball, {"default": {}, "delta": {"transmittance": "delta"},
                                           "no-majorant-grid": {"majorant_grid": False}},
               "Fig. 3 smoke ball (11^3 grid, sigma_a 90, sigma_s 10) in the Cornell box, max_bounces 16"),
    BenchScene("chromatic", _chromatic, {"default": {}, "uniform": UNIFORM, "no-equiangular": NO_EQUIANGULAR},
               f"box of sigma_t {CHROMATIC_SIGMA_T}, albedo {CHROMATIC_ALBEDO} in the Cornell box, "
               "max_bounces 16"),
)}
SETTING_NOTES = {
    "default": "ratio tracking, spectral MIS, majorant grid, equiangular (the defaults)",
    "no-equiangular": "free-flight distance sampling only",
    "uniform": "distance sampling in one uniformly chosen channel (no spectral MIS)",
    "delta": "delta-tracking shadow transmittance",
    "no-majorant-grid": "one global majorant",
}


# ------------------------------------------------------------------------------ error


@dataclass
class Reference:
    """A converged image and the variance of each pixel's mean (its remaining noise)."""

    mean: np.ndarray  # (H, W, 3) float64
    variance: np.ndarray  # (H, W, 3) float64
    spp: int
    seconds: float

    @property
    def noise_relmse(self) -> float:
        return float(np.mean(self.variance / (self.mean**2 + REL_EPS)))

    def relmse(self, image: np.ndarray) -> float:
        """relMSE of `image` against the converged image: the reference's noise subtracted."""
        return float(np.mean((image - self.mean) ** 2 / (self.mean**2 + REL_EPS))) - self.noise_relmse

    def rmse(self, image: np.ndarray) -> float:
        return math.sqrt(max(float(np.mean((image - self.mean) ** 2) - np.mean(self.variance)), 0.0))


def film_reference(film: Film, seconds: float) -> Reference:
    shape = (film.height, film.width, 3)
    return Reference(film.mean().reshape(shape), film.variance_of_mean().reshape(shape), film.spp, seconds)


def stack_reference(images: np.ndarray, spp: int, seconds: float) -> Reference:
    """Reference from K independent renders: their mean, and its variance from their spread."""
    k = images.shape[0]
    return Reference(images.mean(axis=0), images.var(axis=0, ddof=1) / k, spp * k, seconds)


# ------------------------------------------------------------------------------ curves


@dataclass
class Curve:
    """Error against wall time of one renderer / setting on one scene."""

    label: str
    seconds: list[float] = field(default_factory=list)
    spp: list[int] = field(default_factory=list)
    relmse: list[float] = field(default_factory=list)
    rmse: list[float] = field(default_factory=list)
    estimate: list[float] = field(default_factory=list)  # Haze's own running estimate (nan for Cycles)
    startup: float = math.nan  # fixed cost per render: intercept of seconds against spp

    def add(self, seconds: float, spp: int, relmse: float, rmse: float, estimate: float = math.nan) -> None:
        self.seconds.append(seconds)
        self.spp.append(spp)
        self.relmse.append(relmse)
        self.rmse.append(rmse)
        self.estimate.append(estimate)

    def fit_startup(self) -> None:
        """The part of the wall time that does not grow with samples (compile, process start,
        Cycles' scene sync and volume octree): the time to the first image less the sampling
        in it, at the steady seconds per sample of the later half of the curve."""
        if len(self.spp) >= 3:
            half = len(self.spp) // 2
            slope = (self.seconds[-1] - self.seconds[half]) / max(self.spp[-1] - self.spp[half], 1)
            self.startup = max(self.seconds[0] - self.spp[0] * slope, 0.0)

    def at_budget(self, budget: float) -> int | None:
        """Index of the last image available within `budget` seconds."""
        inside = [i for i, t in enumerate(self.seconds) if t <= budget]
        return inside[-1] if inside else None

    def time_to(self, target: float) -> tuple[float, bool]:
        """(seconds to reach relMSE `target`, extrapolated?) on the log-log curve."""
        t, e = np.asarray(self.seconds), np.asarray(self.relmse)
        for i in range(len(e)):
            if 0 < e[i] <= target:
                if i == 0 or e[i - 1] <= 0:
                    return float(t[i]), False
                s = (math.log(target) - math.log(e[i - 1])) / (math.log(e[i]) - math.log(e[i - 1]))
                return float(math.exp(math.log(t[i - 1]) + s * (math.log(t[i]) - math.log(t[i - 1])))), False
        return self._extrapolate(target), True

    def _extrapolate(self, target: float) -> float:
        """Past the last point: error ~ c / (t - startup), c fitted on the last third."""
        start = 0.0 if math.isnan(self.startup) else self.startup
        t, e = np.asarray(self.seconds), np.asarray(self.relmse)
        tail = slice(2 * len(t) // 3, None)
        keep = (e[tail] > 0) & (t[tail] > start)
        if not np.any(keep):
            return math.nan
        c = math.exp(float(np.mean(np.log(e[tail][keep]) + np.log(t[tail][keep] - start))))
        return start + c / target


def haze_curve(scene: Scene, label: str, overrides: dict, reference: Reference, max_seconds: float,
               workers: int) -> Curve:
    """One progressive render: the error of the image after every pass against its elapsed time."""
    from renderer.render import render_progressive

    scene = copy.deepcopy(scene)
    for key, value in overrides.items():
        setattr(scene.integrator, key, value)
    scene.integrator.spp, scene.integrator.seed = HUGE_SPP, MEASURE_SEED
    scene.integrator.time_limit = max_seconds
    curve = Curve(label)
    shape = reference.mean.shape
    # Below twice the reference's own noise the subtraction dominates: stop measuring there.
    floor = 2.0 * reference.noise_relmse
    frames = render_progressive(scene, workers=workers)
    try:
        for frame in frames:
            image = frame.film.mean().reshape(shape)
            curve.add(frame.elapsed, frame.spp, reference.relmse(image), reference.rmse(image),
                      frame.error_estimate)
            if curve.relmse[-1] < floor:
                break
    finally:
        frames.close()
    curve.fit_startup()
    return curve


# ------------------------------------------------------------------------------ cache


def scene_folder(scene: Scene, name: str) -> Path:
    """The scene saved under the cache, in a folder named by a hash of its content, so a
    changed scene never meets a stale reference."""
    from renderer.scenefile import save_scene

    with tempfile.TemporaryDirectory() as tmp:
        save_scene(scene, tmp)
        digest = hashlib.sha256()
        for path in sorted(Path(tmp).rglob("*")):
            if path.is_file():
                digest.update(path.relative_to(tmp).as_posix().encode())
                digest.update(path.read_bytes())
        folder = CACHE / f"{name}-{digest.hexdigest()[:12]}"
        if not (folder / "scene" / "scene.json").is_file():
            shutil.copytree(tmp, folder / "scene", dirs_exist_ok=True)
    return folder


def _load_film(path: Path, width: int, height: int) -> tuple[Film, dict]:
    film = Film(width, height)
    if not path.is_file():
        return film, {"seconds": 0.0, "seeds": []}
    data = np.load(path)
    film.sum, film.sq, film.n = data["sum"], data["sq"], data["n"]
    return film, json.loads(str(data["meta"]))


def haze_reference(scene: Scene, folder: Path, target: float, time_cap: float, workers: int) -> Reference:
    """Haze's converged image: rendered until its estimated relMSE is below `target` or
    `time_cap` seconds were spent on it in total; cached, and extended with a new seed (an
    independent sample set that merges with the old one) when asked for less error."""
    from renderer.render import render_progressive

    path = folder / f"haze_reference_seed{REFERENCE_SEED}.npz"
    film, meta = _load_film(path, scene.film.width, scene.film.height)
    while film.spp == 0 or film.rel_mse_estimate() > target:
        left = time_cap - meta["seconds"]
        if left <= 1.0:
            break
        job = copy.deepcopy(scene)
        job.integrator.seed = REFERENCE_SEED + len(meta["seeds"])
        job.integrator.spp, job.integrator.time_limit = HUGE_SPP, left
        needed = film.spp * (film.rel_mse_estimate() / target - 1.0) if film.spp else 0.0
        if needed > 0:
            job.integrator.spp = max(4, int(1.1 * needed))
        print(f"  Haze reference: seed {job.integrator.seed}, up to {left:.0f} s", flush=True)
        last = None
        for frame in render_progressive(job, workers=workers, target_error=0.0 if film.spp else target):
            last = frame  # keep only the latest: every frame holds an image
        assert last is not None
        film.add(last.film)
        meta["seconds"] += last.elapsed
        meta["seeds"].append(job.integrator.seed)
        np.savez(path, sum=film.sum, sq=film.sq, n=film.n, meta=json.dumps(meta))
    return film_reference(film, meta["seconds"])


# ------------------------------------------------------------------------------ Cycles


def run_cycles(scene_dir: Path, out: Path, samples: list[int], seeds: tuple[int, ...], time_limit: float,
               threads: int) -> dict:
    """tools/cycles_reference.py in a subprocess (bpy lives only there); its timings."""
    command = [sys.executable, str(CYCLES_TOOL), str(scene_dir), str(out), "--samples", *map(str, samples),
               "--seeds", *map(str, seeds), "--threads", str(threads), "--time-limit", str(time_limit)]
    process = subprocess.run(command, capture_output=True, text=True, cwd=REPO)
    if process.returncode != 0:
        raise RuntimeError(f"Cycles failed ({process.returncode}):\n{process.stdout[-3000:]}\n"
                           f"{process.stderr[-3000:]}")
    return json.loads((out / "timings.json").read_text())


def cycles_images(timings: dict, seed: int) -> list[tuple[dict, np.ndarray]]:
    from renderer.imageio import read_exr

    renders = [r for r in timings["renders"] if r["seed"] == seed]
    return [(r, read_exr(r["path"]).astype(np.float64)) for r in sorted(renders, key=lambda r: r["samples"])]


def cycles_reference(folder: Path, samples_per_seed: int, time_limit: float, threads: int) -> Reference:
    """Mean of Cycles renders with four seeds, cached under the scene's folder."""
    out = folder / "cycles_reference"
    timings_file = out / "timings.json"
    if timings_file.is_file():
        timings = json.loads(timings_file.read_text())
    else:
        seeds = CYCLES_REFERENCE_SEEDS
        print(f"  Cycles reference: {len(seeds)} seeds x {samples_per_seed} samples", flush=True)
        timings = run_cycles(folder / "scene", out, [samples_per_seed], seeds, time_limit, threads)
    images = np.stack([image for seed in CYCLES_REFERENCE_SEEDS for _, image in cycles_images(timings, seed)])
    seconds = sum(r["seconds"] for r in timings["renders"])
    return stack_reference(images, timings["renders"][0]["samples"], seconds)


def cycles_curves(folder: Path, max_seconds: float, haze_ref: Reference, threads: int,
                  reference_target: float, reference_time: float) -> tuple[Curve, Curve, Reference]:
    """Cycles at 1, 2, 4, ... samples, each render timed, until one takes `max_seconds`:
    errors against Cycles' own converged reference and against Haze's."""
    out = Path(tempfile.mkdtemp(prefix="haze-cycles-curve-"))
    try:
        timings = run_cycles(folder / "scene", out, [2**k for k in range(17)], (CYCLES_SEED,), max_seconds,
                             threads)
        renders = cycles_images(timings, CYCLES_SEED)
        against_haze = Curve("Cycles vs Haze ref")
        for r, image in renders:
            against_haze.add(r["seconds"], r["samples"], haze_ref.relmse(image), haze_ref.rmse(image))
        against_haze.fit_startup()
        own_ref = cycles_reference(folder, _cycles_reference_samples(against_haze, reference_target,
                                                                     reference_time), reference_time, threads)
        own = Curve("Cycles")
        for r, image in renders:
            own.add(r["seconds"], r["samples"], own_ref.relmse(image), own_ref.rmse(image))
        own.startup = against_haze.startup
        return own, against_haze, own_ref
    finally:
        shutil.rmtree(out, ignore_errors=True)


def _cycles_reference_samples(curve: Curve, target: float, time_budget: float) -> int:
    """Samples per seed for a four-seed mean with relMSE ~ `target` (error ~ 1/samples,
    from the curve's last point, an upper bound as it includes any bias), within the budget."""
    k = len(CYCLES_REFERENCE_SEEDS)
    wanted = curve.spp[-1] * max(curve.relmse[-1], target) / (k * target)
    startup = 0.0 if math.isnan(curve.startup) else curve.startup
    per_sample = (curve.seconds[-1] - startup) / curve.spp[-1]
    affordable = (time_budget / k - startup) / max(per_sample, 1e-9)
    return int(max(16, min(wanted, affordable)))


# ------------------------------------------------------------------------------ report


@dataclass
class SceneResult:
    scene: BenchScene
    haze: list[Curve]
    cycles: Curve | None
    cycles_vs_haze: Curve | None
    haze_ref: Reference
    cycles_ref: Reference | None
    load: str  # machine load when the scene's measurements started


def fmt(value: float, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}g}"


def budget_table(result: SceneResult, budgets: list[float]) -> list[str]:
    """Markdown rows: per budget and curve, the last image available by then."""
    rows = ["| budget s | curve | seconds | spp | relMSE | RMSE | Haze's estimate |",
            "|---:|---|---:|---:|---:|---:|---:|"]
    curves = result.haze + [c for c in (result.cycles, result.cycles_vs_haze) if c is not None]
    for budget in budgets:
        for curve in curves:
            i = curve.at_budget(budget)
            if i is None:
                rows.append(f"| {budget:g} | {curve.label} | - | - | - | - | - |")
                continue
            rows.append(f"| {budget:g} | {curve.label} | {curve.seconds[i]:.2f} | {curve.spp[i]} | "
                        f"{fmt(curve.relmse[i])} | {fmt(curve.rmse[i])} | {fmt(curve.estimate[i])} |")
    return rows


def time_cell(curve: Curve, target: float) -> tuple[str, float]:
    seconds, extrapolated = curve.time_to(target)
    return (fmt(seconds) + ("*" if extrapolated else "")), seconds


def summary_table(results: list[SceneResult]) -> list[str]:
    """Markdown rows: time to relMSE 1e-2 and 1e-3 per curve, with and without start-up, and
    ratios to Cycles."""
    head = "| scene | curve | start-up s |"
    line = "|---|---|---:|"
    for target in TARGETS:
        head += f" to {target:g} s | / Cycles | to {target:g} s, no start-up | / Cycles |"
        line += "---:|---:|---:|---:|"
    rows = [head, line]
    for result in results:
        for curve in result.haze + [c for c in (result.cycles,) if c is not None]:
            row = f"| {result.scene.name} | {curve.label} | {fmt(curve.startup, 2)} |"
            for target in TARGETS:
                row += _target_cells(curve, result.cycles, target)
            rows.append(row)
    return rows


def _target_cells(curve: Curve, cycles: Curve | None, target: float) -> str:
    text, seconds = time_cell(curve, target)
    net = seconds - (0.0 if math.isnan(curve.startup) else curve.startup)
    ratio = ratio_net = math.nan
    if cycles is not None:
        cycles_seconds, _ = cycles.time_to(target)
        cycles_net = cycles_seconds - (0.0 if math.isnan(cycles.startup) else cycles.startup)
        ratio, ratio_net = seconds / cycles_seconds, net / cycles_net
    star = "*" if text.endswith("*") else ""
    return f" {text} | {fmt(ratio, 2)} | {fmt(net)}{star} | {fmt(ratio_net, 2)} |"


def reference_rows(results: list[SceneResult]) -> list[str]:
    rows = ["| scene | Haze ref spp | Haze ref noise relMSE | Haze ref s | Cycles ref spp | "
            "Cycles ref noise relMSE | Cycles ref s | Cycles vs Haze: mean ratio R, G, B |",
            "|---|---:|---:|---:|---:|---:|---:|---|"]
    for r in results:
        h, c = r.haze_ref, r.cycles_ref
        ratio = "-"
        if c is not None:
            ratio = ", ".join(f"{x:.4f}" for x in c.mean.mean(axis=(0, 1)) / h.mean.mean(axis=(0, 1)))
        rows.append(f"| {r.scene.name} | {h.spp} | {fmt(h.noise_relmse, 2)} | {h.seconds:.0f} | "
                    f"{c.spp if c else '-'} | {fmt(c.noise_relmse, 2) if c else '-'} | "
                    f"{f'{c.seconds:.0f}' if c else '-'} | {ratio} |")
    return rows


def estimate_rows(results: list[SceneResult]) -> list[str]:
    """The online estimates against the true relMSE along each scene's default Haze curve."""
    rows = ["| scene | setting | spp | true relMSE | Haze's estimate | true / estimate |",
            "|---|---|---:|---:|---:|---:|"]
    for result in results:
        if not result.haze:
            continue
        curve = result.haze[0]
        spp = np.asarray(curve.spp)
        wanted = [n for n in (4, 16, 64, 256, 1024) if spp.max() >= n / 2]
        picks = sorted({int(np.argmin(np.abs(spp - n))) for n in wanted})
        for i in picks:
            true = curve.relmse[i]
            rows.append(f"| {result.scene.name} | {curve.label} | {curve.spp[i]} | {fmt(true)} | "
                        f"{fmt(curve.estimate[i])} | {fmt(true / curve.estimate[i], 2)} |")
    return rows


# ------------------------------------------------------------------------------ SVG plot

PALETTE = ("#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf")
CYCLES_COLOR = "#d62728"


def svg_plot(result: SceneResult, path: Path, size: int, workers: int) -> None:
    """relMSE against seconds on log-log axes, one line per curve; 1e-2 and 1e-3 marked."""
    series = [(c, PALETTE[i % len(PALETTE)], "") for i, c in enumerate(result.haze)]
    if result.cycles is not None:
        series.append((result.cycles, CYCLES_COLOR, "6,3"))
    if result.cycles_vs_haze is not None:
        series.append((result.cycles_vs_haze, CYCLES_COLOR, "2,3"))
    points = [(t, e) for c, _, _ in series for t, e in zip(c.seconds, c.relmse) if t > 0 and e > 0]
    xs, ys = [p[0] for p in points], [p[1] for p in points] + list(TARGETS)
    axes = LogAxes(min(xs), max(xs), min(ys), max(ys))
    parts = [axes.frame(f"{result.scene.name}: relMSE against wall time ({size}x{size}, {workers} cores)")]
    for target in TARGETS:
        parts.append(axes.hline(target))
    for curve, color, dash in series:
        parts.append(axes.polyline(curve.seconds, curve.relmse, color, dash))
    parts.append(legend([(c.label, color, dash) for c, color, dash in series], axes))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{LogAxes.WIDTH}" '
                    f'height="{LogAxes.HEIGHT}" font-family="sans-serif" font-size="12">\n'
                    '<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(parts) + "\n</svg>\n")


class LogAxes:
    """Maps data to SVG pixels on decade-aligned log-log axes."""

    WIDTH, HEIGHT = 720, 460
    LEFT, RIGHT, TOP, BOTTOM = 70, 200, 40, 50

    def __init__(self, x0: float, x1: float, y0: float, y1: float):
        self.x0, self.x1 = math.floor(math.log10(x0)), math.ceil(math.log10(x1))
        self.y0, self.y1 = math.floor(math.log10(y0)), math.ceil(math.log10(y1))
        self.x1 = max(self.x1, self.x0 + 1)
        self.y1 = max(self.y1, self.y0 + 1)

    def px(self, x: float) -> float:
        span = self.WIDTH - self.LEFT - self.RIGHT
        return self.LEFT + (math.log10(x) - self.x0) / (self.x1 - self.x0) * span

    def py(self, y: float) -> float:
        span = self.HEIGHT - self.TOP - self.BOTTOM
        return self.HEIGHT - self.BOTTOM - (math.log10(y) - self.y0) / (self.y1 - self.y0) * span

    def frame(self, title: str) -> str:
        left, right = self.LEFT, self.WIDTH - self.RIGHT
        top, bottom = self.TOP, self.HEIGHT - self.BOTTOM
        out = [f'<text x="{left}" y="22" font-size="14">{title}</text>',
               f'<rect x="{left}" y="{top}" width="{right - left}" height="{bottom - top}" fill="none" '
               'stroke="black"/>']
        for k in range(self.x0, self.x1 + 1):
            for m in range(1, 10) if k < self.x1 else (1,):
                x = self.px(m * 10.0**k)
                tick = 6 if m == 1 else 3
                out.append(f'<line x1="{x:.1f}" y1="{bottom}" x2="{x:.1f}" y2="{bottom - tick}" '
                           'stroke="black"/>')
                if m == 1:
                    out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="#ddd"/>')
                    out.append(f'<text x="{x:.1f}" y="{bottom + 16}" text-anchor="middle">{10.0**k:g}</text>')
        for k in range(self.y0, self.y1 + 1):
            y = self.py(10.0**k)
            out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{right}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">1e{k}</text>')
        out.append(f'<text x="{(left + right) / 2}" y="{self.HEIGHT - 12}" text-anchor="middle">'
                   'wall seconds (start-up included)</text>')
        out.append(f'<text x="16" y="{(top + bottom) / 2}" text-anchor="middle" '
                   f'transform="rotate(-90 16 {(top + bottom) / 2})">relMSE</text>')
        return "\n".join(out)

    def hline(self, y: float) -> str:
        return (f'<line x1="{self.LEFT}" y1="{self.py(y):.1f}" x2="{self.WIDTH - self.RIGHT}" '
                f'y2="{self.py(y):.1f}" stroke="#999" stroke-dasharray="1,3"/>')

    def polyline(self, xs: list[float], ys: list[float], color: str, dash: str) -> str:
        pts = " ".join(f"{self.px(x):.1f},{self.py(y):.1f}" for x, y in zip(xs, ys) if x > 0 and y > 0)
        dashing = f' stroke-dasharray="{dash}"' if dash else ""
        return f'<polyline points="{pts}" fill="none" stroke="{color}" stroke-width="1.6"{dashing}/>'


def legend(entries: list[tuple[str, str, str]], axes: LogAxes) -> str:
    x = axes.WIDTH - axes.RIGHT + 12
    out = []
    for i, (label, color, dash) in enumerate(entries):
        y = axes.TOP + 14 + 18 * i
        dashing = f' stroke-dasharray="{dash}"' if dash else ""
        out.append(f'<line x1="{x}" y1="{y - 4}" x2="{x + 24}" y2="{y - 4}" stroke="{color}" stroke-width="2"'
                   f'{dashing}/>')
        out.append(f'<text x="{x + 30}" y="{y}">{label}</text>')
    return "\n".join(out)


# ------------------------------------------------------------------------------ driver


@dataclass
class Options:
    scenes: list[str]
    budgets: list[float]
    size: int
    workers: int
    cycles: bool
    reference_target: float
    reference_time: float
    out: Path | None
    settings: list[str] | None  # estimator settings to run (None: every one the scene has)


def run_scene(bench: BenchScene, options: Options) -> SceneResult:
    scene = bench.build(options.size)
    folder = scene_folder(scene, bench.name)
    print(f"{bench.name}: {bench.description} ({folder.name})", flush=True)
    haze_ref = haze_reference(scene, folder, options.reference_target, options.reference_time,
                              options.workers)
    print(f"  Haze reference: {haze_ref.spp} spp, noise relMSE {haze_ref.noise_relmse:.2g}", flush=True)
    max_seconds = max(options.budgets)
    curves = []
    load = machine_line()
    chosen = {k: v for k, v in bench.settings.items() if options.settings is None or k in options.settings}
    for label, overrides in chosen.items():
        curves.append(haze_curve(scene, label, overrides, haze_ref, max_seconds, options.workers))
        print(f"  Haze {label}: {_curve_line(curves[-1])}", flush=True)
    cycles = cycles_vs_haze = cycles_ref = None
    if options.cycles:
        cycles, cycles_vs_haze, cycles_ref = cycles_curves(folder, max_seconds, haze_ref, options.workers,
                                                           options.reference_target, options.reference_time)
        print(f"  Cycles reference: {cycles_ref.spp} samples, noise relMSE {cycles_ref.noise_relmse:.2g}")
        print(f"  Cycles: {_curve_line(cycles)}", flush=True)
        print(f"  Cycles vs Haze ref: {_curve_line(cycles_vs_haze)}", flush=True)
    return SceneResult(bench, curves, cycles, cycles_vs_haze, haze_ref, cycles_ref, load)


def _curve_line(curve: Curve) -> str:
    return (f"{curve.spp[-1]} spp in {curve.seconds[-1]:.1f} s (start-up {curve.startup:.2f} s), "
            f"relMSE {curve.relmse[-1]:.3g}")


def machine_line() -> str:
    load = os.getloadavg()
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


def report(results: list[SceneResult], options: Options, command: str, load_before: str) -> str:
    lines = [f"Command: `{command}`", "", f"Machine at start: {load_before}", "",
             f"Machine at end: {machine_line()}", "",
             "Times are wall seconds from the start of each render (start-up included); the "
             "'no start-up' columns subtract each curve's fitted fixed cost. * = extrapolated "
             "along relMSE ~ 1/(t - start-up) past the last measured point.", "",
             "## Time to relMSE", ""]
    lines += summary_table(results) + ["", "## References", ""] + reference_rows(results)
    lines += ["", "## Online error estimate against the true relMSE", ""] + estimate_rows(results)
    lines += ["", "Settings: " + "; ".join(f"{k}: {v}" for k, v in SETTING_NOTES.items()), ""]
    for result in results:
        lines += ["", f"## {result.scene.name}: {result.scene.description}", "",
                  f"Measured from: {result.load}", ""]
        lines += budget_table(result, options.budgets)
    return "\n".join(lines) + "\n"


def parse_arguments(argv: list[str] | None) -> tuple[Options, bool]:
    p = argparse.ArgumentParser(prog="python -m bench convergence",
                                description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", choices=list(SCENES), default=None)
    p.add_argument("--budgets", type=float, nargs="+", default=None, help="seconds (default 0.5 1 2 ... 16)")
    p.add_argument("--quick", action="store_true", help="smoke test: 64x64, two scenes, budgets up to 4 s")
    p.add_argument("--size", type=int, default=None)
    p.add_argument("--workers", type=int, default=2, help="Haze processes and Cycles threads")
    p.add_argument("--no-cycles", action="store_true")
    p.add_argument("--settings", nargs="+", default=None, choices=list(SETTING_NOTES),
                   help="estimator settings to run (default: all those the scene lists)")
    p.add_argument("--reference-target", type=float, default=None, help="relMSE of the references")
    p.add_argument("--reference-time", type=float, default=None, help="seconds per reference at most")
    p.add_argument("--out", type=Path, default=None,
                   help=f"tables.md and plots (default {DOCS}; none in --quick)")
    a = p.parse_args(argv)
    quick = a.quick
    options = Options(
        scenes=a.scenes or (["cornell", "fog_g0"] if quick else list(SCENES)),
        budgets=a.budgets or ([1.0, 2.0, 4.0] if quick else [0.5, 1.0, 2.0, 4.0, 8.0, 16.0]),
        size=a.size or (64 if quick else 128),
        workers=a.workers,
        cycles=not a.no_cycles,
        settings=a.settings,
        reference_target=a.reference_target or (1e-3 if quick else 1e-4),
        reference_time=a.reference_time or (15.0 if quick else 1200.0),
        out=a.out if a.out is not None else (None if quick else DOCS),
    )
    return options, quick


def main(argv: list[str] | None = None) -> int:
    options, _ = parse_arguments(argv)
    command = "python -m bench convergence " + " ".join(argv or [])
    load_before = machine_line()
    print(f"{command.strip()}\n{load_before}", flush=True)
    started = time.perf_counter()
    results = [run_scene(SCENES[name], options) for name in options.scenes]
    text = report(results, options, command.strip(), load_before)
    print("\n" + text)
    if options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        (options.out / "tables.md").write_text(text)
        for result in results:
            svg_plot(result, options.out / f"{result.scene.name}.svg", options.size, options.workers)
        print(f"wrote {options.out}/tables.md and plots")
    print(f"total {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
