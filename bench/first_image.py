"""Time to first image, cold and warm, for the command line and for F12 (issue 19's closing note).

    .venv/bin/python -m bench first_image [--scenes surface,fog,smoke] [--only cli|f12]
                                          [--size 128] [--spp N] [--json out.json]

Scenes (all --size x --size pixels, default 128x128, the examples' default size):

  surface  the surface-only Cornell box with its two blocks (examples/scenes.py cornell_box,
           3 bounces; in Blender: examples/blender_gallery.py's box and blocks, no fog)
  fog      the Cornell box in the paper's Fig. 1 fog, g = 0 (scenes.py cornell_fog, 3 bounces;
           in Blender: blender_gallery.py fog_isotropic, a world volume, 4 bounces)
  smoke    the Fig. 5 smoke ball, an 11^3 grid (media_scenes.py smoke_ball, 3 bounces; in
           Blender: blender_gallery.py smoke_ball, a Volume object, 16 bounces)

What is measured, per scene; cold = an empty kernel cache, warm = the same cache again:

* CLI: the scene is saved as a scene folder (renderer.scenefile.save_scene) and rendered by
  `python -m renderer render FOLDER -o OUT.exr` as a subprocess with the default worker count
  (one per core, what a user gets) and the scene's samples per pixel (64, or --spp), with
  HAZE_CACHE_DIR a fresh empty folder (cold), then again with that cache (warm). Time to
  first image: from launching the subprocess to the first progress bar line the CLI prints
  ("[###...] N/M spp", printed after every pass; the first pass is 1 sample per pixel), read
  incrementally from its stderr with timestamps. The total wall time (all passes, EXR and PNG
  written, process exited) is recorded too.
* F12: a Python subprocess with bpy (Blender as a module) in a fresh user folder (HOME,
  BLENDER_USER_RESOURCES, XDG_CACHE_HOME, XDG_CONFIG_HOME: new empty folders) and a fresh
  empty HAZE_CACHE_DIR, HAZE_BACKGROUND_COMPILE=0 (no compile at enable: the render compiles
  what it needs, as in a script). It enables the extension zip built from this checkout and
  installed in that user folder (bench/installed.py), builds the scene with bpy.data, sets
  Haze with 1 sample per pixel and the default workers, and times
  `bpy.ops.render.render(write_still=True)`: the time to the finished 1-spp render (scene
  export and kernel compile included; writing a 128x128 EXR adds milliseconds). Warm: a
  second subprocess with the same folders and cache. The renderer (numba) is not imported
  before the render for the surface and fog boxes, as for a user; the smoke ball's builder
  imports it to make its density grid (as the Add > Volume operators do).

Each subprocess has a timeout (--timeout, 900 s); on timeout its process group is killed.
All scene folders, caches and user folders live in one temporary folder removed at the end.
Prints the machine's load average at start (and end), a line per run, then a table of the
times to first image in seconds; the CLI cells read "first image / total wall time".
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from bench.installed import blender_environment

REPO = Path(__file__).resolve().parents[1]

SCENES = ("surface", "fog", "smoke")
DEFAULT_TIMEOUT = 900.0
# The CLI's progress bar, printed after every pass (renderer/cli.py _bar).
PASS_LINE = re.compile(rb"\[[#.]+\] (\d+)/(\d+) spp")
COMPILED_LINE = re.compile(rb"compiled kernels in ([0-9.]+) s")
# "compiling kernels (first run only): N s" (one process) or "haze: compiling kernels (first
# run only): NAMES" (each worker process that compiles).
COMPILING = b"compiling kernels"

F12_SCRIPT = r'''
"""Blender side of bench/first_image.py: build one scene, time one 1-spp F12."""
import json
import sys
import time

started = time.perf_counter()
repo, kind, size, folder, result_path = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
for path in (repo + "/examples", repo):
    if path not in sys.path:  # appended: the installed extension's renderer comes first
        sys.path.append(path)

import math  # noqa: E402
from pathlib import Path  # noqa: E402

import bpy  # noqa: E402

import blender_cornell as C  # noqa: E402
import blender_gallery as G  # noqa: E402
import addon_utils  # noqa: E402

from bench.installed import PACKAGE, enable_installed  # noqa: E402

result = {"kind": kind}
t = time.perf_counter()
enable_installed()  # the extension zip installed in this user folder, as users get it
result["register_seconds"] = time.perf_counter() - t


def surface_box(size):
    """blender_gallery's Cornell box with fog_isotropic's two blocks, no fog; 3 bounces."""
    scene = G.cornell(size, 3)
    for name, center, half, angle in (("Short Block", (0.35, -0.35, 0.3), (0.3, 0.3, 0.3), -17.0),
                                      ("Tall Block", (-0.35, 0.3, 0.6), (0.3, 0.3, 0.6), 17.0)):
        block = C.box(name, (0.0, 0.0, 0.0), 1.0, C.diffuse_material(name, (0.73, 0.73, 0.73)))
        block.location, block.scale = center, half
        block.rotation_euler = (0.0, 0.0, math.radians(angle))
    return scene


t = time.perf_counter()
if kind == "surface":
    scene = surface_box(size)
elif kind == "fog":
    scene = G.fog(size, 0.0)
else:
    scene = G.smoke_ball(size, Path(folder))
result["build_seconds"] = time.perf_counter() - t
scene.haze.samples = 1
result["workers_setting"] = scene.haze.workers
result["max_bounces"] = scene.haze.max_bounces
result["renderer_imported_before_render"] = "renderer.render" in sys.modules
result["numba_imported_before_render"] = "numba" in sys.modules
exr = Path(folder) / "f12.exr"
settings = scene.render.image_settings
settings.file_format, settings.color_depth = "OPEN_EXR", "32"
scene.render.filepath = str(exr)
t = time.perf_counter()
bpy.ops.render.render(write_still=True)
result["f12_seconds"] = time.perf_counter() - t
result["image_written"] = exr.is_file()
result["seconds_before_render"] = t - started
t = time.perf_counter()
addon_utils.disable(PACKAGE, default_set=True)  # stops the persistent render workers
result["unregister_seconds"] = time.perf_counter() - t
with open(result_path, "w") as file:
    json.dump(result, file)
'''


@dataclass
class Run:
    """One timed subprocess."""

    kind: str  # "cli" or "f12"
    scene: str
    cache: str  # "cold" or "warm"
    first_image: float | None = None  # seconds; None if not reached
    total: float | None = None  # wall time of the whole subprocess, seconds
    returncode: int | None = None
    problem: str = ""  # why first_image is missing or doubtful, "" if none
    details: dict = field(default_factory=dict)


@dataclass
class Streamed:
    """What a subprocess printed, with arrival times (seconds after launch)."""

    returncode: int | None
    seconds: float
    timed_out: bool
    output: bytes
    first_pass: float | None
    compiled_seconds: float | None
    compiling_message: float | None  # when "compiling kernels" first showed, seconds after launch


def run_streaming(command: list[str], env: dict[str, str], cwd: Path, timeout: float) -> Streamed:
    """Run `command` with stdout+stderr read as they arrive; note when the first pass line shows.

    The subprocess gets its own process group, killed whole on timeout or on Ctrl-C here.
    """
    start = time.perf_counter()
    process = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL, start_new_session=True)
    buffer = bytearray()
    first: list[float] = []
    compiling: list[float] = []

    def read() -> None:
        assert process.stdout is not None
        fd = process.stdout.fileno()
        while True:
            chunk = os.read(fd, 65536)
            if not chunk:
                return
            now = time.perf_counter() - start
            buffer.extend(chunk)
            # Each line is written in one flushed print; search only the tail that could hold it.
            since = max(0, len(buffer) - len(chunk) - 200)
            if not first and PASS_LINE.search(buffer, since):
                first.append(now)
            if not compiling and buffer.find(COMPILING, since) >= 0:
                compiling.append(now)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    timed_out = False
    try:
        process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        _kill_group(process)
    except BaseException:
        _kill_group(process)
        raise
    seconds = time.perf_counter() - start
    reader.join(timeout=10.0)
    compiled = COMPILED_LINE.search(buffer)
    return Streamed(process.returncode, seconds, timed_out, bytes(buffer), first[0] if first else None,
                    float(compiled.group(1)) if compiled else None, compiling[0] if compiling else None)


def _kill_group(process: subprocess.Popen) -> None:
    """Kill the subprocess and everything it started (its own process group), then reap it."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait()


def base_environment(cache: Path) -> dict[str, str]:
    """This environment without Haze's, numba's and Blender's settings; HAZE_CACHE_DIR = cache."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("HAZE_", "NUMBA_", "BLENDER_"))}
    env.update(HAZE_CACHE_DIR=str(cache), HAZE_BACKGROUND_COMPILE="0", PYTHONUNBUFFERED="1")
    if os.environ.get("HAZE_COMPILE_LOG"):  # kept: who compiled what, and when
        env["HAZE_COMPILE_LOG"] = os.environ["HAZE_COMPILE_LOG"]
    return env


def tail(output: bytes, lines: int = 15) -> str:
    """The last non-empty lines of a subprocess's output (progress bars split at carriage returns)."""
    text = output.decode(errors="replace").replace("\r", "\n")
    kept = [line for line in text.splitlines() if line.strip()]
    return "\n".join(kept[-lines:])


# ------------------------------------------------------------------------------ CLI


def save_cli_scene(name: str, size: int, folder: Path) -> int:
    """Write the scene folder of `name` at size x size; returns its samples per pixel."""
    from examples.media_scenes import smoke_ball
    from examples.scenes import cornell_box, cornell_fog
    from renderer.scenefile import save_scene

    builders = {"surface": lambda: cornell_box(size), "fog": lambda: cornell_fog(size, g=0.0),
                "smoke": lambda: smoke_ball(size)}
    scene = builders[name]()
    save_scene(scene, folder)
    return scene.integrator.spp


def run_cli(name: str, cache_state: str, scene_folder: Path, cache: Path, work: Path, spp: int | None,
            timeout: float) -> Run:
    output = work / f"cli-{name}-{cache_state}.exr"
    command = [sys.executable, "-m", "renderer", "render", str(scene_folder), "-o", str(output)]
    if spp is not None:
        command += ["--spp", str(spp)]
    streamed = run_streaming(command, base_environment(cache), REPO, timeout)
    run = Run("cli", name, cache_state, streamed.first_pass, streamed.seconds, streamed.returncode)
    text = streamed.output.decode(errors="replace").replace("\r", "\n")
    # the ticker's "...: N s" lines once, each worker's line as printed
    compiling = {re.sub(r"\d+ s$", "N s", line.strip())
                 for line in text.splitlines() if COMPILING.decode() in line}
    run.details = {"compiled_seconds_printed": streamed.compiled_seconds,
                   "compiling_message_at": streamed.compiling_message,
                   "compiling_lines": sorted(compiling)[:4],
                   "image_written": output.is_file()}
    if streamed.timed_out:
        run.problem = f"timed out after {timeout:.0f} s"
    elif streamed.returncode != 0:
        run.problem = f"exit status {streamed.returncode}"
    elif streamed.first_pass is None:
        run.problem = "no progress line seen"
    if run.problem:
        run.details["output_tail"] = tail(streamed.output)
    return run


# ------------------------------------------------------------------------------ F12


def run_f12(name: str, cache_state: str, user: Path, cache: Path, work: Path, size: int,
            timeout: float) -> Run:
    """One bpy subprocess in the user folder `user`: build `name`, time one 1-spp F12."""
    script = work / "f12_script.py"
    script.write_text(F12_SCRIPT)
    folder = work / f"f12-{name}-{cache_state}"
    folder.mkdir(parents=True, exist_ok=True)
    result_path = folder / "result.json"
    env = base_environment(cache)
    home, resources = user / "home", user / "blender_user"
    for path in (home, resources):
        path.mkdir(parents=True, exist_ok=True)
    env.update(HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"), XDG_CONFIG_HOME=str(home / ".config"))
    env = blender_environment(resources, env)  # the extension zip of this checkout, installed there
    command = [sys.executable, str(script), str(REPO), name, str(size), str(folder), str(result_path)]
    streamed = run_streaming(command, env, folder, timeout)
    result = json.loads(result_path.read_text()) if result_path.is_file() else {}
    run = Run("f12", name, cache_state, result.get("f12_seconds"), streamed.seconds, streamed.returncode)
    run.details = {k: v for k, v in result.items() if k not in ("kind", "f12_seconds")}
    if streamed.timed_out:
        run.problem = f"timed out after {timeout:.0f} s"
    elif streamed.returncode != 0 or not result:
        run.problem = f"exit status {streamed.returncode}" + ("" if result else ", no result")
    elif not result.get("image_written"):
        run.problem = "no image written"
    if run.problem:
        run.details["output_tail"] = tail(streamed.output)
    return run


# ------------------------------------------------------------------------------ report


def describe(run: Run) -> str:
    first = f"{run.first_image:.1f} s" if run.first_image is not None else "-"
    total = f"{run.total:.1f} s" if run.total is not None else "-"
    extra = ""
    if run.kind == "cli" and run.details.get("compiling_message_at") is not None:
        extra = f", 'compiling kernels' shown at {run.details['compiling_message_at']:.1f} s"
    if run.kind == "cli" and run.details.get("compiled_seconds_printed") is not None:
        extra += f", printed 'compiled kernels in {run.details['compiled_seconds_printed']:.1f} s'"
    if run.kind == "f12" and "seconds_before_render" in run.details:
        extra = f", {run.details['seconds_before_render']:.1f} s import+register+build before F12"
    problem = f"  PROBLEM: {run.problem}" if run.problem else ""
    return (f"{run.kind:3s} {run.scene:7s} {run.cache:4s}: first image {first}, subprocess {total}"
            f"{extra}{problem}")


def cell(run: Run | None, with_total: bool) -> str:
    if run is None:
        return "-"
    if run.first_image is None:
        return "fail"
    text = f"{run.first_image:.1f}"
    if with_total and run.total is not None:
        text += f" / {run.total:.1f}"
    return text + ("?" if run.problem else "")


def table(runs: list[Run], scenes: list[str]) -> str:
    found = {(r.kind, r.scene, r.cache): r for r in runs}
    header = ["scene", "CLI cold", "CLI warm", "F12 cold", "F12 warm"]
    rows = [[scene,
             cell(found.get(("cli", scene, "cold")), True), cell(found.get(("cli", scene, "warm")), True),
             cell(found.get(("f12", scene, "cold")), False), cell(found.get(("f12", scene, "warm")), False)]
            for scene in scenes]
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(text.ljust(width) if i == 0 else text.rjust(width)
                       for i, (text, width) in enumerate(zip(row, widths, strict=True)))
             for row in [header, *rows]]
    return "\n".join(lines)


def git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                              timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


# ------------------------------------------------------------------------------ main


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m bench first_image", description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated: surface,fog,smoke")
    parser.add_argument("--only", choices=("cli", "f12"), help="measure only the CLI or only F12")
    parser.add_argument("--size", type=int, default=128, help="image width and height (default 128)")
    parser.add_argument("--spp", type=int, help="CLI samples per pixel (default: the scene's, 64); F12: 1")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="per subprocess, seconds")
    parser.add_argument("--json", type=Path, help="also write the results to this JSON file")
    arguments = parser.parse_args(argv)
    arguments.scene_list = [s.strip() for s in arguments.scenes.split(",") if s.strip()]
    unknown = [s for s in arguments.scene_list if s not in SCENES]
    if unknown or not arguments.scene_list:
        parser.error(f"--scenes: choose from {','.join(SCENES)} (got {arguments.scenes!r})")
    if arguments.size < 1 or (arguments.spp is not None and arguments.spp < 1) or arguments.timeout <= 0:
        parser.error("--size and --spp must be >= 1, --timeout > 0")
    return arguments


def measure(arguments: argparse.Namespace, root: Path) -> list[Run]:
    runs: list[Run] = []
    kinds = [arguments.only] if arguments.only else ["cli", "f12"]
    for name in arguments.scene_list:
        if "cli" in kinds:
            folder, cache = root / f"scene-{name}", root / f"cache-cli-{name}"
            cache.mkdir()
            spp = save_cli_scene(name, arguments.size, folder)
            print(f"cli {name}: {arguments.size}x{arguments.size}, {arguments.spp or spp} spp, "
                  f"scene folder saved", flush=True)
            for state in ("cold", "warm"):
                runs.append(run_cli(name, state, folder, cache, root, arguments.spp, arguments.timeout))
                print(describe(runs[-1]), flush=True)
        if "f12" in kinds:
            user, cache = root / f"user-{name}", root / f"cache-f12-{name}"
            cache.mkdir()
            for state in ("cold", "warm"):
                runs.append(run_f12(name, state, user, cache, root, arguments.size, arguments.timeout))
                print(describe(runs[-1]), flush=True)
    return runs


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(argv)
    load_start = os.getloadavg()
    started = datetime.now(UTC)
    print(f"load average at start: {load_start[0]:.2f} {load_start[1]:.2f} {load_start[2]:.2f} "
          f"({os.cpu_count()} cores); {started:%Y-%m-%d %H:%M} UTC", flush=True)
    with tempfile.TemporaryDirectory(prefix="haze-first-image-", ignore_cleanup_errors=True) as temp:
        root = Path(temp)
        # Saving the CLI scenes imports the renderer here: keep whatever it might cache out of
        # the user's cache (the measured subprocesses get their own HAZE_CACHE_DIR).
        scratch = root / "cache-scratch"
        scratch.mkdir()
        os.environ["HAZE_CACHE_DIR"] = str(scratch)
        runs = measure(arguments, root)
    load_end = os.getloadavg()
    print(f"load average at end: {load_end[0]:.2f} {load_end[1]:.2f} {load_end[2]:.2f}")
    print(f"\ntime to first image, seconds ({arguments.size}x{arguments.size}; "
          f"CLI: first pass / total wall time, default workers; F12: 1-spp render incl. export)")
    print(table(runs, arguments.scene_list))
    if arguments.json:
        report = {
            "started_utc": started.isoformat(timespec="seconds"), "load_average_start": load_start,
            "load_average_end": load_end, "cpu_count": os.cpu_count(), "platform": platform.platform(),
            "python": sys.version.split()[0], "commit": git_commit(),
            "settings": {"scenes": arguments.scene_list, "only": arguments.only, "size": arguments.size,
                         "cli_spp": arguments.spp, "f12_spp": 1, "timeout": arguments.timeout},
            "runs": [asdict(run) for run in runs],
        }
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"wrote {arguments.json}")
    return 1 if any(run.problem for run in runs) else 0
