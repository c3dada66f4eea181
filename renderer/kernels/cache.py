"""One kernel cache per machine and user, shared by every Haze process.

Numba's own cache is keyed by each source file's path and modification time, so the CLI
run from a clone, the add-on installed as an extension and the add-on enabled from a clone
each compiled the same kernels into a folder of their own, and a kernel whose inlined
callees changed in another file could be loaded stale. Here every kernel of the `renderer`
package is cached under

    <root>/kernels-<build key>/<subpackage>/

where the build key hashes the source of the whole package with the versions of numba,
llvmlite and Python: any change to any kernel source (or an update of Haze or numba) gives
a new, empty folder, and identical sources share one folder wherever they are installed.
Numba's index also keys every entry by CPU name and features, so machines of different
kinds sharing a home folder never load each other's code.

The root is renderer.cache_folder.cache_root(): HAZE_CACHE_DIR if set, else
NUMBA_CACHE_DIR if set, else the per-user cache folder (~/.cache/haze on Linux).

function_lock(name) serialises compiling one function between processes: the first process
to need it compiles it (and saves it) while the others wait, then load it from the cache.
The lock is per function, not per build, so two processes starting on a cold cache compile
different kernels at once (renderer.kernels.warmup picks the ones nobody holds), and a
function's index file (all its signatures) is only ever written under its lock.
"""

from __future__ import annotations

import hashlib
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import llvmlite
import numba
from numba.core import event
from numba.core.caching import CacheImpl, _CacheLocator

from ..cache_folder import cache_root  # the one rule, shared with the add-on

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # the renderer package
LOCK_FOLDER = "locks"


def build_key(package_dir: Path = PACKAGE_DIR) -> str:
    """A short hash of every source file of the package and the compiler's versions."""
    h = hashlib.sha256()
    h.update(f"numba {numba.__version__} llvmlite {llvmlite.__version__} {sys.version}".encode())
    for path in sorted(p for p in package_dir.rglob("*.py") if "__pycache__" not in p.parts):
        h.update(path.relative_to(package_dir).as_posix().encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


BUILD_KEY = build_key()


def kernel_cache_dir() -> Path:
    """This build's kernel folder."""
    return cache_root() / f"kernels-{BUILD_KEY}"


class HazeCacheLocator(_CacheLocator):
    """Numba cache locator for functions defined in the renderer package (see the module)."""

    def __init__(self, py_func, py_file: str):
        self._lineno = py_func.__code__.co_firstlineno
        relative = Path(py_file).resolve().parent.relative_to(PACKAGE_DIR)
        self._cache_path = str(kernel_cache_dir().joinpath(*relative.parts))

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> str:
        # The folder already names the sources; a per-file stamp would add nothing.
        return BUILD_KEY

    def get_disambiguator(self) -> str:
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file: str):
        try:
            Path(py_file).resolve().relative_to(PACKAGE_DIR)
        except (ValueError, OSError):
            return None  # not a renderer kernel: numba's own locators decide
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:
            return None  # an unwritable cache: numba falls back to its own locators
        return self


def install() -> None:
    """Make numba place the renderer's kernels with HazeCacheLocator (before any is defined),
    and log compiles where HAZE_COMPILE_LOG asks."""
    if HazeCacheLocator not in CacheImpl._locator_classes:
        CacheImpl._locator_classes.insert(0, HazeCacheLocator)
    global _compile_log
    path = os.environ.get(COMPILE_LOG_ENV)
    if path and _compile_log is None:
        _compile_log = CompileLog(path)
        event.register("numba:compile", _compile_log)


COMPILE_LOG_ENV = "HAZE_COMPILE_LOG"
_compile_log = None


class CompileLog(event.Listener):
    """One line per function this process compiled (not loaded from the cache): process id,
    function, argument types and the time it was done (Unix seconds), tab-separated,
    appended to the file HAZE_COMPILE_LOG names. Worker processes inherit the variable, so
    one file shows which process compiled what and when (e.g. that two renders on a cold
    cache never compiled the same function twice)."""

    def __init__(self, path: str) -> None:
        self.path = path

    def on_start(self, ev) -> None:
        pass

    def on_end(self, ev) -> None:
        func = ev.data["dispatcher"].py_func
        line = f"{os.getpid()}\t{func.__module__}.{func.__qualname__}\t{ev.data['args']}\t{time.time():.3f}\n"
        with open(self.path, "a", encoding="utf-8") as f:  # one short append: not interleaved
            f.write(line)


_held: dict[str, int] = {}  # locks this process holds, with their depth (re-entry is free)
# How long a compile waits for another process's lock on the same function before it
# compiles the function itself (a compile of one function takes seconds to a minute or two):
# the holder may be stopped (Ctrl-Z) or stuck, and a render must not wait forever.
LOCK_WAIT = 600.0
LOCK_POLL = 0.2
_warned: set[str] = set()


def _warn(text: str) -> None:
    """One line on stderr, once per text and process; dropped if stderr is broken."""
    if text in _warned:
        return
    _warned.add(text)
    try:
        print(f"haze: warning: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


@contextmanager
def function_lock(name: str, blocking: bool = True) -> Iterator[bool]:
    """Hold the compile lock of function `name` (an OS file lock, released if the process
    dies; the file holds its owner's process id). Yields True once held; with
    blocking=False, False at once if another process holds it. Re-entrant within a process.

    A blocking wait ends without the lock (yielding True: the caller compiles on its own,
    as a process without a cache would) when the owner is stopped, after LOCK_WAIT seconds,
    or when the lock file cannot be opened (a read-only cache, a `locks` that is a file),
    each said once on stderr."""
    if name in _held:
        _held[name] += 1
        try:
            yield True
        finally:
            _held[name] -= 1
        return
    digest = hashlib.sha1(name.encode()).hexdigest()[:12]  # short, portable file names
    path = kernel_cache_dir() / LOCK_FOLDER / f"{name[-60:]}-{digest}.lock"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        f = open(path, "a+b")  # noqa: SIM115 - closed below, after the caller's block
    except OSError as error:
        problem = error.strerror or error
        _warn(f"kernel compile locks unusable ({path.parent}: {problem}); compiling without them")
        yield blocking
        return
    with f:
        held = _lock(f, False) or (blocking and _wait_for(f, name))
        if not held:
            yield blocking  # not blocking: someone else compiles it; blocking: gave up waiting
            return
        _held[name] = 1
        _write_owner(f)
        try:
            yield True
        finally:
            del _held[name]
            _unlock(f)


def _wait_for(f, name: str) -> bool:
    """Wait for the lock on f: True once held, False when its owner is stopped or LOCK_WAIT passed."""
    deadline = time.monotonic() + LOCK_WAIT
    while True:
        if _lock(f, False):
            return True
        owner = _owner(f)
        if owner is not None and _is_stopped(owner):
            _warn(f"process {owner} holds the compile lock of {name} but is stopped; compiling it here")
            return False
        if time.monotonic() >= deadline:
            who = f"process {owner}" if owner is not None else "another process"
            _warn(f"{who} has held the compile lock of {name} for over {LOCK_WAIT:.0f} s; compiling it here")
            return False
        time.sleep(LOCK_POLL)


def _write_owner(f) -> None:
    try:
        f.truncate(0)
        f.write(str(os.getpid()).encode())
        f.flush()
    except OSError:  # a full disk: the lock holds all the same, only unnamed
        pass


def _owner(f) -> int | None:
    try:
        f.seek(0)
        text = f.read(32).decode("ascii", "replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _is_stopped(pid: int) -> bool:
    """Whether process `pid` is stopped (Ctrl-Z, SIGSTOP) or traced; Linux's /proc only."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2:stat.rfind(")") + 3] in ("T", "t")


if sys.platform == "win32":
    import msvcrt

    def _lock(f, blocking: bool, poll: float = 0.1) -> bool:
        while True:
            try:
                f.seek(0)
                msvcrt.locking(f.fileno(), msvcrt.LK_NBLCK, 1)
                return True
            except OSError:
                if not blocking:
                    return False
                time.sleep(poll)

    def _unlock(f) -> None:
        f.seek(0)
        msvcrt.locking(f.fileno(), msvcrt.LK_UNLCK, 1)
else:
    import fcntl

    def _lock(f, blocking: bool) -> bool:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX if blocking else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return True

    def _unlock(f) -> None:
        fcntl.flock(f.fileno(), fcntl.LOCK_UN)

