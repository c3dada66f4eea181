"""Error against run time, Haze and Cycles side by side:
`python -m bench convergence [--scenes ...] [--budgets ...] [--quick]`. Prints figures;
asserts nothing.

For each benchmark scene (128x128, both cores):

* a converged Haze reference, rendered once and cached under bench/cache/ (keyed by the
  scene's content and the seed), extended with further seeds whenever a lower error is asked;
* one progressive Haze render per estimator setting, its error measured after every pass,
  so a single run gives the whole curve of error against wall time (the time counts from
  the call to render_progressive: scene compilation and worker start-up included);
* beside the first setting, the same render denoised (Open Image Denoise guided by the
  Denoising Albedo and Normal passes, renderer.denoise) after every pass: its own render,
  since the passes cost time, and each point's time includes its denoising (--no-denoised
  leaves it out);
* Cycles on the same scene, rebuilt in bpy by `python -m bench cycles_reference` (a
  subprocess: the renderer never imports bpy), at 1, 2, 4, ... samples, each render timed, until one takes
  the largest budget; plus Cycles' own converged reference (mean of four seeds, cached).

The error is relMSE with the reference's own noise subtracted (bench/metrics.py). Cycles is
measured against its own reference (noise) and against Haze's (noise plus any disagreement
between the renderers: bias).

Output: a table per scene (budget seconds, spp, relMSE, RMSE per setting and for Cycles),
the time to relMSE 1e-2 and 1e-3 per setting (interpolated on the log-log curve, or
extrapolated along error ~ 1/(t - start-up) past the last point, marked *) with its ratio
to Cycles, tables.md and one log-log SVG per scene under docs/convergence/.

This module is the driver (references, Haze and Cycles runs, the cache, the command line);
the scenes are in bench/scenes.py, the tables in bench/reports.py, the plots in bench/plots.py.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import math
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderer.film import Film
from renderer.scene import Scene
from renderer.validate.scene import MAX_SPP

from .cycles_reference import command as cycles_command
from .metrics import TARGETS, Curve, Reference, film_reference, stack_reference
from .plots import svg_plot
from .reports import SceneResult, machine_line, report
from .scenes import SCENES, SETTING_NOTES, BenchScene

REPO = Path(__file__).resolve().parents[1]
CACHE = REPO / "bench" / "cache" / "convergence"
DOCS = REPO / "docs" / "convergence"

MEASURE_SEED = 1
REFERENCE_SEED = 1000  # the Haze reference uses 1000, 1001, ... (one seed per extension)
CYCLES_SEED = 1
CYCLES_REFERENCE_SEEDS = (101, 102, 103, 104)
HUGE_SPP = MAX_SPP  # "until the time budget runs out": the most samples a scene may ask


# ------------------------------------------------------------------------------ curves


def haze_curve(scene: Scene, label: str, overrides: dict, reference: Reference, max_seconds: float,
               workers: int, denoised: bool = False) -> Curve:
    """One progressive render: the error of the image after every pass against its elapsed
    time; with `denoised`, of the image denoised after every pass, at elapsed time plus the
    denoising's own."""
    from renderer.render import render_progressive

    scene = copy.deepcopy(scene)
    scene.film.aovs = denoised  # the denoiser's albedo and normal passes
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
            seconds, estimate = frame.elapsed, frame.error_estimate
            if denoised:
                started = time.perf_counter()
                image = denoised_image(frame.film, scene)
                seconds += time.perf_counter() - started
                estimate = math.nan  # Haze's estimate is the raw image's
            curve.add(seconds, frame.spp, reference.relmse(image), reference.rmse(image), estimate)
            if curve.relmse[-1] < floor:
                break
    finally:
        frames.close()
    curve.fit_startup()
    return curve


def denoised_image(film: Film, scene: Scene) -> np.ndarray:
    """(H, W, 3) float64: the film's image denoised with its albedo and normal passes."""
    from renderer.denoise import denoise
    from renderer.passes import film_passes

    passes = film_passes(film, scene.camera, ("Denoising Albedo", "Denoising Normal"))
    image = film.mean().reshape(film.height, film.width, 3)
    return denoise(image, passes["Denoising Albedo"], passes["Denoising Normal"]).astype(np.float64)


def denoising_available() -> bool:
    from renderer.denoise import available

    return available()


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
    if "odd" not in data:  # cached before films kept their odd samples' sum: rendered again
        return film, {"seconds": 0.0, "seeds": []}
    film.sum, film.sq, film.n, film.odd = data["sum"], data["sq"], data["n"], data["odd"]
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
        np.savez(path, sum=film.sum, sq=film.sq, n=film.n, odd=film.odd, meta=json.dumps(meta))
    return film_reference(film, meta["seconds"])


# ------------------------------------------------------------------------------ Cycles


def cycles_source(folder: Path) -> Path:
    """What Cycles renders: the Blender scene itself for a scene built in Blender
    (bench/blend_scenes.py puts it beside the export), else the Haze scene folder, which
    bench/cycles_reference.py rebuilds in bpy."""
    blend = folder / "scene.blend"
    return blend if blend.is_file() else folder / "scene"


def run_cycles(folder: Path, out: Path, samples: list[int], seeds: tuple[int, ...], time_limit: float,
               threads: int) -> dict:
    """`python -m bench cycles_reference` in a subprocess (bpy lives only there); its timings."""
    from renderer.scenefile import load_scene

    bounces = load_scene(folder / "scene").integrator.max_bounces
    command = cycles_command([str(cycles_source(folder)), str(out), "--samples", *map(str, samples),
                              "--seeds", *map(str, seeds), "--threads", str(threads),
                              "--time-limit", str(time_limit), "--max-bounces", str(bounces)])
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
        timings = run_cycles(folder, out, [samples_per_seed], seeds, time_limit, threads)
    images = np.stack([image for seed in CYCLES_REFERENCE_SEEDS for _, image in cycles_images(timings, seed)])
    seconds = sum(r["seconds"] for r in timings["renders"])
    return stack_reference(images, timings["renders"][0]["samples"], seconds)


def cycles_curves(folder: Path, max_seconds: float, haze_ref: Reference, threads: int,
                  reference_target: float, reference_time: float) -> tuple[Curve, Curve, Reference]:
    """Cycles at 1, 2, 4, ... samples, each render timed, until one takes `max_seconds`:
    errors against Cycles' own converged reference and against Haze's."""
    out = Path(tempfile.mkdtemp(prefix="haze-cycles-curve-"))
    try:
        timings = run_cycles(folder, out, [2**k for k in range(17)], (CYCLES_SEED,), max_seconds,
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
    denoised: bool = True  # also the first setting's render denoised after every pass
    repeats: int = 1  # rounds of Haze then Cycles; each curve keeps its best round


def run_scene(bench: BenchScene, options: Options) -> SceneResult:
    scene = bench.build(options.size)
    folder = scene_folder(scene, bench.name)
    if bench.blend is not None:  # Cycles renders the Blender scene itself
        blend = bench.blend(options.size)
        shutil.copyfile(blend, folder / "scene.blend")
        if (blend.parent / "assets").is_dir():  # its files (volumes, images), relative to it
            shutil.copytree(blend.parent / "assets", folder / "assets", dirs_exist_ok=True)
    print(f"{bench.name}: {bench.description} ({folder.name})", flush=True)
    haze_ref = haze_reference(scene, folder, options.reference_target, options.reference_time,
                              options.workers)
    print(f"  Haze reference: {haze_ref.spp} spp, noise relMSE {haze_ref.noise_relmse:.2g}", flush=True)
    max_seconds = max(options.budgets)
    load = machine_line()
    chosen = {k: v for k, v in bench.settings.items() if options.settings is None or k in options.settings}
    best: dict[str, Curve] = {}
    cycles_best: tuple[Curve, Curve] | None = None
    cycles_ref = None
    # Rounds alternate Haze and Cycles so both meet the same (shared, varying) machine load;
    # each curve keeps its best round: the fastest to the last target.
    for round_ in range(options.repeats):
        if options.repeats > 1:
            print(f"  round {round_ + 1} of {options.repeats} ({machine_line()})", flush=True)
        for label, overrides in chosen.items():
            _keep_best(best, haze_curve(scene, label, overrides, haze_ref, max_seconds, options.workers))
            print(f"  Haze {label}: {_curve_line(best[label], last=True)}", flush=True)
            if options.denoised and label == next(iter(chosen)) and denoising_available():
                _keep_best(best, haze_curve(scene, f"{label}, denoised", overrides, haze_ref, max_seconds,
                                            options.workers, denoised=True))
                print(f"  Haze {label}, denoised: {_curve_line(best[f'{label}, denoised'])}", flush=True)
        if options.cycles:
            own, vs_haze, cycles_ref = cycles_curves(folder, max_seconds, haze_ref, options.workers,
                                                     options.reference_target, options.reference_time)
            print(f"  Cycles reference: {cycles_ref.spp} samples, noise relMSE {cycles_ref.noise_relmse:.2g}")
            print(f"  Cycles: {_curve_line(own)}", flush=True)
            print(f"  Cycles vs Haze ref: {_curve_line(vs_haze)}", flush=True)
            if cycles_best is None or _faster(own, cycles_best[0]):
                cycles_best = (own, vs_haze)
    cycles, cycles_vs_haze = cycles_best if cycles_best is not None else (None, None)
    return SceneResult(bench, list(best.values()), cycles, cycles_vs_haze, haze_ref, cycles_ref, load)


def _faster(curve: Curve, other: Curve) -> bool:
    """Whether `curve` reaches the last target sooner than `other`."""
    target = TARGETS[-1]
    return curve.time_to(target)[0] < other.time_to(target)[0]


def _keep_best(best: dict[str, Curve], curve: Curve) -> None:
    if curve.label not in best or _faster(curve, best[curve.label]):
        best[curve.label] = curve


def _curve_line(curve: Curve, last: bool = False) -> str:
    """The curve's last point and its time to each target (`last`: the best round so far)."""
    times = ", ".join(f"to {t:g} {curve.time_to(t)[0]:.2f} s" for t in TARGETS)
    return (f"{'best so far: ' if last else ''}{curve.spp[-1]} spp in {curve.seconds[-1]:.1f} s "
            f"(start-up {curve.startup:.2f} s), relMSE {curve.relmse[-1]:.3g}; {times}")


def parse_arguments(argv: list[str] | None) -> tuple[Options, bool]:
    p = argparse.ArgumentParser(prog="python -m bench convergence",
                                description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", choices=list(SCENES), default=None)
    p.add_argument("--budgets", type=float, nargs="+", default=None, help="seconds (default 0.5 1 2 ... 16)")
    p.add_argument("--quick", action="store_true", help="smoke test: 64x64, two scenes, budgets up to 4 s")
    p.add_argument("--size", type=int, default=None)
    p.add_argument("--workers", type=int, default=2, help="Haze processes and Cycles threads")
    p.add_argument("--no-cycles", action="store_true")
    p.add_argument("--no-denoised", action="store_true", help="leave out the denoised curve")
    p.add_argument("--settings", nargs="+", default=None, choices=list(SETTING_NOTES),
                   help="estimator settings to run (default: all those the scene lists)")
    p.add_argument("--repeats", type=int, default=1,
                   help="rounds alternating Haze and Cycles; each keeps its fastest (default 1)")
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
        denoised=not a.no_denoised,
        repeats=max(1, a.repeats),
    )
    return options, quick


def main(argv: list[str] | None = None) -> int:
    options, _ = parse_arguments(argv)
    command = "python -m bench convergence " + " ".join(argv or [])
    load_before = machine_line()
    print(f"{command.strip()}\n{load_before}", flush=True)
    started = time.perf_counter()
    results = [run_scene(SCENES[name], options) for name in options.scenes]
    text = report(results, options.budgets, command.strip(), load_before)
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
