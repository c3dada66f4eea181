"""The background kernel compile started when the add-on is enabled (no bpy import here).

Numba compiles the renderer's kernels the first time they are needed, which takes minutes.
When the add-on is enabled, `start()` runs addon/precompile.py in a separate process so
that Blender stays responsive while the kernels of common scenes are compiled (or, when
the cache is warm, merely checked in a few seconds). At most one such process is started
per Blender process at a time; other Blender processes (and renders) wait on the
renderer's compile lock rather than compiling the same kernels again.

The child gets the interpreter and the import path of this process: in Blender
sys.executable is Blender's own Python, with the bpy module it is the venv's, and an
installed extension's renderer and numba live in folders Blender added to sys.path.
Its output goes to `<cache root>/warmup.log`.

Without a user interface (`blender -b`, the bpy module) it is off by default: a script
renders right after enabling the add-on, so a background compile could not get ahead of
that render, only take a core from it while compiling scenes the script may not use; the
render compiles what it needs itself. HAZE_BACKGROUND_COMPILE=1 turns it on there too,
HAZE_BACKGROUND_COMPILE=0 turns it off everywhere.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from . import bootstrap, precompile

SCRIPT = Path(precompile.__file__).resolve()
LOG_NAME = "warmup.log"
SWITCH_ENV = "HAZE_BACKGROUND_COMPILE"
# On Windows a console window would pop up for the child otherwise.
NO_CONSOLE_WINDOW = getattr(subprocess, "CREATE_NO_WINDOW", 0)


@dataclass
class Job:
    process: subprocess.Popen | None
    log: Path
    started: float  # time.monotonic() at start
    finished: float | None = None
    stopped: bool = False  # ended by stop(), not by itself
    error: str = ""  # why it could not start


_job: Job | None = None  # the one background compile of this Blender process


def log_path() -> Path:
    return bootstrap.haze_cache_root() / LOG_NAME


def enabled(headless: bool = False) -> bool:
    """Whether to compile in the background (headless: Blender runs without a UI)."""
    switch = os.environ.get(SWITCH_ENV, "").strip().lower()
    if switch in {"0", "false", "no", "off"}:
        return False
    return switch in {"1", "true", "yes", "on"} or not headless


def child_environment() -> dict[str, str]:
    """This environment with our sys.path as PYTHONPATH, so the child imports what we import."""
    env = dict(os.environ)
    paths = [p for p in sys.path if p and os.path.isdir(p)]
    env["PYTHONPATH"] = os.pathsep.join(paths)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def command() -> list[str]:
    # -P: do not put addon/ on sys.path (its modules would shadow others); -u: unbuffered log;
    # -S when we run without site-packages, so the child imports exactly what we can.
    flags = ["-P", "-u"] + (["-S"] if sys.flags.no_site else [])
    return [sys.executable, *flags, str(SCRIPT)]


def running() -> bool:
    return _job is not None and _job.process is not None and _job.process.poll() is None


def start(headless: bool = False, asked: bool = False) -> Job | None:
    """Start the background compile unless it is switched off (asked: the user clicked for
    it, so it runs anyway) or already running."""
    global _job
    if not (asked or enabled(headless)):
        return None
    if running():
        return _job
    log = log_path()
    try:
        log.parent.mkdir(parents=True, exist_ok=True)
        with open(log, "w") as out:
            process = subprocess.Popen(command(), stdout=out, stderr=subprocess.STDOUT,
                                       stdin=subprocess.DEVNULL, env=child_environment(),
                                       cwd=str(log.parent), creationflags=NO_CONSOLE_WINDOW)
    except OSError as error:
        _job = Job(None, log, time.monotonic(), time.monotonic(), error=str(error))
        return _job
    _job = Job(process, log, time.monotonic())
    return _job


def stop(timeout: float = 5.0) -> None:
    """End the background compile if it runs (the compile lock dies with it)."""
    if not running():
        return
    assert _job is not None and _job.process is not None
    _job.stopped = True
    _job.process.terminate()
    try:
        _job.process.wait(timeout)
    except subprocess.TimeoutExpired:
        _job.process.kill()
        _job.process.wait()


def log_says_compiling(log: Path) -> bool:
    try:
        return precompile.COMPILING_LINE in log.read_text(errors="replace")
    except OSError:
        return False


@dataclass
class State:
    kind: str  # "idle", "checking", "compiling", "ready", "failed", "stopped"
    seconds: float  # since the start (running) or how long it ran (finished)
    log: Path
    detail: str = ""  # why it could not start


def state() -> State:
    """What the preferences panel shows about the background compile."""
    if _job is None:
        return State("idle", 0.0, log_path())
    if _job.process is None:
        return State("failed", 0.0, _job.log, _job.error)
    code = _job.process.poll()
    if code is None:
        kind = "compiling" if log_says_compiling(_job.log) else "checking"
        return State(kind, time.monotonic() - _job.started, _job.log)
    if _job.finished is None:
        _job.finished = time.monotonic()
    seconds = _job.finished - _job.started
    if _job.stopped:
        return State("stopped", seconds, _job.log)
    return State("ready" if code == 0 else "failed", seconds, _job.log)


def forget() -> None:
    """Drop a finished job's state (after the cache it filled was cleared)."""
    global _job
    if not running():
        _job = None
