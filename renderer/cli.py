"""Command line: `python -m renderer render SCENE_DIR -o OUT.exr [options]`."""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
import time
from pathlib import Path

from .cli_output import PLAIN_INTERVAL, PROGRESS_MODES, CompileTicker, ProgressPrinter, progress_mode, say
from .cluster import ClusterError  # dask itself loads only for a --cluster render
from .cores import usable_cores
from .errors import SceneError

# The exit status of a process ended by Ctrl-C (128 + SIGINT), as shells report it.
EXIT_INTERRUPTED = 130
OUTPUT_RULES = """\
outputs: the EXR is written to a temporary file beside OUTPUT and renamed into place, so a
symbolic link at OUTPUT is replaced, never written through. OUTPUT must not be a folder,
lie under a file, or be one of the scene's input files (or a link to one); this is checked
before rendering. The PNG preview (OUTPUT with .png) replaces an existing file only if Haze
wrote it, unless --overwrite is given. Ctrl-C stops the render, writes the samples so far
and exits with status 130.

exit status: 0 the image is written; 1 the render failed (its workers kept dying, a cluster
error, a file that could not be written, out of memory; samples done are still written);
2 the command or the scene was refused before rendering (bad options, an invalid scene, an
unsafe output); 130 Ctrl-C (the samples so far written); 128+N stopped by signal N
(SIGTERM 143, SIGHUP 129).
"""




def _parser() -> argparse.ArgumentParser:
    invoked = "haze" if Path(sys.argv[0]).stem == "haze" else "python -m renderer"  # entry point or -m
    p = argparse.ArgumentParser(prog=invoked, description="Haze volumetric path tracer")
    p.add_argument("--version", action="version", version=f"%(prog)s {haze_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser(
        "render",
        help="render a scene folder to an EXR (and a PNG preview)",
        epilog=OUTPUT_RULES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    r.add_argument("scene", type=Path, help="scene folder holding scene.json")
    r.add_argument("-o", "--output", type=Path, required=True, help="output .exr path")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    r.add_argument("--time-limit", type=_finite_float, help="stop after this many seconds")
    r.add_argument("--seed", type=int, help="random seed (default: the scene's)")
    r.add_argument("--max-bounces", type=int, help="Cycles' max_bounces: 0 = direct light only")
    r.add_argument(
        "--target-error", type=_nonnegative_float, default=0.0,
        help="stop once estimated relMSE <= this (0 = off)",
    )
    r.add_argument("--workers", type=int, default=usable_cores(),
                   help="processes (default: the cores this process may use: its CPU affinity and quota)")
    r.add_argument("--cluster", default="", metavar="ADDRESS|local",
                   help="render on a running Dask cluster (tcp://HOST:8786), or 'local' for a Dask "
                   "LocalCluster of --workers processes; the same image bits as without")
    r.add_argument("--no-png", action="store_true", help="do not write the PNG preview")
    r.add_argument("--denoise", action="store_true",
                   help="denoise the image with Open Image Denoise (Blender's library), guided by the "
                   "albedo and normal passes")
    r.add_argument(
        "--overwrite", action="store_true", help="let the PNG preview replace a file Haze did not write"
    )
    r.add_argument("--progress", choices=PROGRESS_MODES, default="auto",
                   help="progress on stderr: a bar redrawn in place, plain lines (one every "
                   f"{PLAIN_INTERVAL:g} s and the last, for logs), or none; auto = the bar on a "
                   "terminal, plain lines otherwise")
    return p


def haze_version() -> str:
    """The installed package's version (pip, the extension's wheel), else the source's."""
    from importlib import metadata

    try:
        return metadata.version("haze-renderer")
    except metadata.PackageNotFoundError:
        from . import __version__

        return __version__


def _finite_float(text: str) -> float:
    """A finite number: argparse refuses nan and inf with the option's name."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def _nonnegative_float(text: str) -> float:
    value = _finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (off) or more, got {text!r}")
    return value


def _check(args) -> str | None:
    from .validate.scene import MAX_BOUNCES, MAX_SEED, MAX_SPP

    if args.spp is not None and not 1 <= args.spp <= MAX_SPP:
        return f"--spp must be in [1, {MAX_SPP}]"
    if args.time_limit is not None and args.time_limit <= 0:
        return "--time-limit must be positive"
    if args.max_bounces is not None and not 0 <= args.max_bounces <= MAX_BOUNCES:
        return f"--max-bounces must be in [0, {MAX_BOUNCES}]"
    if args.seed is not None and not 0 <= args.seed < MAX_SEED:
        return "--seed must be in [0, 2**64)"
    if args.workers < 1:
        return "--workers must be at least 1"
    if args.output.suffix.lower() != ".exr":
        return f"output {args.output}: must end in .exr"
    return _output_place_problem(args.output)


def _output_place_problem(output: Path) -> str | None:
    """Why `output` cannot be written where it is (checked before rendering), or None."""
    if output.is_dir():
        return f"output {output}: is a folder"
    ancestor = output.parent
    while not ancestor.exists() and not ancestor.is_symlink() and ancestor != ancestor.parent:
        ancestor = ancestor.parent  # missing folders are created when the image is written
    if not ancestor.is_dir():
        return f"output {output}: {ancestor} is not a folder"
    if not os.access(ancestor, os.W_OK | os.X_OK):
        return f"output {output}: folder {ancestor} is not writable"
    return None


def _output_conflict(output: Path, inputs: list[Path], what: str) -> str | None:
    """Why writing `output` would destroy one of the scene's `inputs`, or None."""
    target = output.resolve()
    for file in inputs:
        same = target == file.resolve() or (output.exists() and _same_file(output, file))
        if same:
            return f"{what} {output}: is the scene's input file {file} (or a link to it)"
    return None


def _same_file(a: Path, b: Path) -> bool:
    # Also catches hard links, which resolve() cannot see.
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _png_problem(png: Path, inputs: list[Path], overwrite: bool) -> str | None:
    from .imageio import is_haze_png

    conflict = _output_conflict(png, inputs, "preview")
    if conflict:
        return conflict
    if png.is_dir():
        return f"preview {png}: is a folder (pass --no-png to skip the preview)"
    exists = png.exists() or png.is_symlink()
    if exists and not overwrite and not is_haze_png(png):
        return (f"preview {png}: exists and was not written by Haze; "
                "pass --overwrite to replace it or --no-png to skip the preview")
    return None


def _outputs_problem(args, inputs: list[Path]) -> str | None:
    """Why the outputs would destroy an input or someone's file (checked before rendering)."""
    conflict = _output_conflict(args.output, inputs, "output")
    if conflict or args.no_png:
        return conflict
    return _png_problem(args.output.with_suffix(".png"), inputs, args.overwrite)


def render_command(args) -> int:
    from .memory import check_scene_memory, workers_allowed
    from .scenefile import load_scene_and_inputs
    from .workers import start_workers

    problem = _check(args)
    if problem:
        say(f"error: {problem}")
        return 2
    if args.denoise:
        from .denoise import available

        if not available():
            say("error: --denoise needs Open Image Denoise, which was not found (it comes with "
                 "Blender's bpy module; HAZE_OIDN_LIBRARY may name the library)")
            return 2
    if args.cluster:  # first: an unreachable scheduler is an error in seconds, before any loading
        from .cluster import connect

        connect(args.cluster, args.workers)
    scene, inputs = load_scene_and_inputs(args.scene)
    problem = _outputs_problem(args, inputs)
    if problem:
        say(f"error: {problem}")
        return 2
    scene.film.aovs = bool(args.denoise)  # the denoiser's albedo and normal passes
    if not args.cluster:  # a cluster's workers are on other machines
        allowed = workers_allowed(scene, args.workers)
        if allowed < args.workers:
            say(f"warning: rendering with {allowed} worker processes, not {args.workers}: "
                 f"as many as this machine's cores and memory allow")
            args.workers = allowed
    check_scene_memory(scene, args.workers if not args.cluster else 1)
    if not args.cluster:
        # Before numba loads here: the first worker's start overlaps this process's imports (the
        # others start once it is heard from: renderer.render._PoolRender._pool_size).
        start_workers(1)
    return _render_and_write(args, scene)


def _render_and_write(args, scene) -> int:
    from .imageio import write_exr, write_png
    from .render import render_progressive

    s = scene.integrator
    if args.spp is not None:
        s.spp = args.spp
    if args.time_limit is not None:
        s.time_limit = args.time_limit
    if args.seed is not None:
        s.seed = args.seed
    if args.max_bounces is not None:
        s.max_bounces = args.max_bounces
    t0 = time.perf_counter()
    last = None
    interrupted = False
    mode = progress_mode(args.progress)
    printer = ProgressPrinter(mode, s.spp)
    ticker = CompileTicker(plain=mode != "bar", quiet=mode == "none")
    try:
        for last in render_progressive(scene, workers=args.workers, target_error=args.target_error,
                                       on_compile=ticker.start, in_process=False, cluster=args.cluster):
            ticker.stop()
            printer.show(last.spp, last.elapsed, last.error_estimate)
    except KeyboardInterrupt:
        interrupted = True
        say("\ninterrupted: writing the samples so far")
    finally:
        ticker.stop()
    printer.finish()
    if last is None or (last.failed and last.film.spp == 0):
        say(f"error: {last.note if last is not None else 'no samples were rendered'}")
        return EXIT_INTERRUPTED if interrupted else 1
    image = _denoised(last, scene.camera) if args.denoise else last.image
    _write(write_exr, args.output, image)
    msg = f"wrote {args.output}"
    if not args.no_png:
        png = args.output.with_suffix(".png")
        _write(write_png, png, image)
        msg += f" and {png}"
    seconds = time.perf_counter() - t0
    samples = int(last.film.n.sum())  # traced: a stop in mid-pass leaves some tiles a unit ahead
    say(msg)
    if last.note and not last.failed:
        say(f"warning: {last.note}")
    if last.film.nonfinite[0]:
        bad = int(last.film.nonfinite[0])
        say(f"warning: {bad} path values were NaN or infinite and were counted as 0")
    say(f"{last.spp} spp, {seconds:.2f} s, {samples / seconds / 1e6:.3f} M samples/s")
    if last.failed:  # the samples done are written, but the render did not finish
        say(f"error: {last.note}")
        return 1
    return EXIT_INTERRUPTED if interrupted else 0


def _write(writer, path: Path, image) -> None:
    """writer(path, image), an OSError naming the file it could not write."""
    try:
        writer(path, image)
    except OSError as error:
        raise OSError(f"could not write {path}: {error.strerror or error}") from None


def _denoised(last, camera):
    """The final image denoised by OIDN with the film's Denoising Albedo and Normal passes."""
    from .denoise import denoise
    from .passes import film_passes

    passes = film_passes(last.film, camera, ("Denoising Albedo", "Denoising Normal"))
    say("denoising")
    return denoise(last.image, passes["Denoising Albedo"], passes["Denoising Normal"])


class _Stopped(BaseException):
    """SIGTERM or SIGHUP: unwinds the render like Ctrl-C does (its workers terminated, its
    scene file removed) instead of ending the process where it stands. A BaseException, so
    no `except Exception` on the way swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_stopped(signum: int, frame) -> None:
    raise _Stopped(signum)


def _stop_on_termination() -> dict:
    """Handlers for SIGTERM and SIGHUP that raise _Stopped; the previous ones, by signal."""
    if threading.current_thread() is not threading.main_thread():  # only it may set handlers
        return {}
    numbers = [getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)]
    return {number: signal.signal(number, _raise_stopped) for number in numbers}


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    previous = _stop_on_termination()
    try:
        return _main(args)
    finally:
        for number, handler in previous.items():  # an in-process caller (tests) gets its own back
            signal.signal(number, handler)
        _silence_broken_streams()


def _silence_broken_streams() -> None:
    """Python flushes stdout and stderr at exit, and a broken one (a closed pipe, a full
    disk) would turn the exit status into 120 after the image was written: such a stream is
    replaced by the null device."""
    for name in ("stdout", "stderr"):
        try:
            getattr(sys, name).flush()
        except (OSError, ValueError):
            try:
                setattr(sys, name, open(os.devnull, "w"))  # noqa: SIM115 - lives until exit
            except OSError:
                pass


def _main(args) -> int:
    try:
        if args.command == "render":
            return render_command(args)
    except _Stopped as stopped:
        say(f"\nerror: stopped by {signal.Signals(stopped.signum).name}")
        return 128 + stopped.signum
    except SceneError as e:
        say(f"error: {e}")
        return 2
    except ClusterError as e:
        say(f"error: {e}")
        return 1
    except FileNotFoundError as e:
        say(f"error: {e}")
        return 2
    except OSError as e:  # e.g. the disk filled up while writing the image
        say(f"error: {e}")
        return 1
    except MemoryError:  # the estimate before rendering was too low, or others took the memory
        say("error: out of memory while rendering; try a smaller film or fewer --workers")
        return 1
    except KeyboardInterrupt:  # while loading, or a second Ctrl-C while writing
        say("\ninterrupted")
        return EXIT_INTERRUPTED
    return 1
