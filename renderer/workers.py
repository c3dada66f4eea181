"""The persistent worker processes of renderer.render, and how the scene reaches them.

Spawned processes (Blender cannot fork; spawn everywhere alike) that live across renders
in this process: a second render or the next animation frame reuses them. The scene is
pickled once per render to a temporary file named by a hash of its contents; a task
carries that (key, path), and a worker loads the scene and builds its tracer only for a
key it has not got (it keeps one tracer). The scene's arrays (grids, meshes) go into that
file raw, beside the pickle (protocol 5, out of band), and workers map them copy-on-write
instead of reading them: all workers' arrays are views of the same pages, so a grid takes
memory once per machine, not once per worker (issue 18, item 3). Arrays that already view a
file of renderer.mapped (a large grid's bricks) are not copied: the shipment names the file
(by its contents' digest, with a table of paths), and workers map that file. The parent
(renderer.render) watches each worker's pipe and process sentinel, so it can terminate one
stuck inside a kernel and notice one that died.

This module imports only the standard library, so a caller can start workers before it
imports numba (`start_workers`): the workers' imports then overlap its own. A worker
imports the renderer as soon as it starts, before its first task.
"""

from __future__ import annotations

import atexit
import dataclasses
import hashlib
import io
import mmap
import multiprocessing
import os
import pickle
import signal
import struct
import sys
import tempfile
import threading
import time
import traceback
import types
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_for
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    from .compile import CompiledScene
    from .integrator.wavefront import Tracer
    from .scene import IntegratorSettings
    from .units import Unit


class Shipment(NamedTuple):
    key: str  # hash of the pickle: a worker that holds this key already has the tracer
    path: str


def tracer_settings(settings: IntegratorSettings) -> IntegratorSettings:
    """The settings with the fields a tracer does not read normalised, so another seed, spp
    or time limit of the same scene does not make the workers rebuild their tracers."""
    return dataclasses.replace(settings, seed=0, spp=1, time_limit=0.0)


def scene_payload(cs: CompiledScene, settings: IntegratorSettings) -> tuple[str, bytes]:
    """(hash, pickle) of what a cluster worker needs to build the tracer (renderer.cluster):
    the same key, the same tracer. The local pool ships the arrays out of band (shipped)."""
    data = pickle.dumps((cs, tracer_settings(settings)), protocol=pickle.HIGHEST_PROTOCOL)
    return hashlib.blake2b(data, digest_size=16).hexdigest(), data


# Shipment file: header (pickle length, buffer count, file table length), then (offset, size)
# per buffer, the pickle, the table of mapped files (a pickled {digest: path}), and the
# buffers, each at a multiple of ALIGN bytes (numba types an array by its alignment too: a
# misaligned view would compile every kernel again).
_HEADER = struct.Struct("<QQQ")
_ENTRY = struct.Struct("<QQ")
ALIGN = 64
# Shipment files a worker still mapped when the render ended (Windows cannot delete them).
_leftovers: list[str] = []


class _ShipmentPickler(pickle.Pickler):
    """Protocol 5 with the arrays out of band, except those viewing a renderer.mapped file:
    they pickle as (digest, offset, shape, dtype), and `files` collects digest -> path."""

    def __init__(self, file, buffers: list[pickle.PickleBuffer]) -> None:
        super().__init__(file, protocol=5, buffer_callback=buffers.append)
        self.files: dict[str, str] = {}
        self.mapped = None  # renderer.mapped, once an array shows up (it imports numpy)

    def reducer_override(self, obj):
        if type(obj).__name__ != "ndarray" or type(obj).__module__ != "numpy":
            return NotImplemented
        if self.mapped is None:
            from . import mapped

            self.mapped = mapped
        found = self.mapped.reference(obj)
        if found is None:
            return NotImplemented
        digest, path, offset = found
        self.files[digest] = path
        return self.mapped.resolve, (digest, offset, obj.shape, obj.dtype.str)


@contextmanager
def shipped(cs: CompiledScene, settings: IntegratorSettings) -> Iterator[Shipment]:
    """The scene written once to a temporary file for the workers, removed after the render."""
    buffers: list[pickle.PickleBuffer] = []
    stream = io.BytesIO()
    pickler = _ShipmentPickler(stream, buffers)
    pickler.dump((cs, tracer_settings(settings)))
    data = stream.getvalue()
    raws = [b.raw() for b in buffers]
    digest = hashlib.blake2b(data, digest_size=16)  # mapped files are in it by their digests
    for raw in raws:
        digest.update(raw)
    key = digest.hexdigest()
    _remove_leftovers()
    fd, path = tempfile.mkstemp(prefix=f"haze-scene-{key[:8]}-", suffix=".pkl")
    try:
        with os.fdopen(fd, "wb") as f:
            _write_shipment(f, data, raws, pickle.dumps(pickler.files))
        yield Shipment(key, path)
    finally:
        _remove(path)


def _write_shipment(f, data: bytes, raws: list[memoryview], files: bytes) -> None:
    offsets, at = [], _aligned(_HEADER.size + _ENTRY.size * len(raws) + len(data) + len(files))
    for raw in raws:
        offsets.append(at)
        at = _aligned(at + raw.nbytes)
    f.write(_HEADER.pack(len(data), len(raws), len(files)))
    for offset, raw in zip(offsets, raws):
        f.write(_ENTRY.pack(offset, raw.nbytes))
    f.write(data)
    f.write(files)
    for offset, raw in zip(offsets, raws):
        f.seek(offset)
        f.write(raw)
    f.truncate(at)


def _aligned(n: int) -> int:
    return -(-n // ALIGN) * ALIGN


def load_shipment(path: str):
    """What shipped() pickled, its arrays viewing a copy-on-write map of the file (pages
    shared with every other process that maps it, until one writes to them)."""
    with open(path, "rb") as f:
        mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
    view = memoryview(mm)
    size, count, table = _HEADER.unpack_from(view, 0)
    entries = [_ENTRY.unpack_from(view, _HEADER.size + _ENTRY.size * i) for i in range(count)]
    start = _HEADER.size + _ENTRY.size * count
    files = pickle.loads(view[start + size:start + size + table])
    buffers = [view[o:o + n] for o, n in entries]
    if not files:
        return pickle.loads(view[start:start + size], buffers=buffers)
    from .mapped import resolving

    with resolving(files):
        return pickle.loads(view[start:start + size], buffers=buffers)


def _remove(path: str) -> None:
    try:
        Path(path).unlink(missing_ok=True)
    except OSError:  # still mapped by a worker (Windows): removed later
        _leftovers.append(path)


def _remove_leftovers() -> None:
    paths = list(_leftovers)
    _leftovers.clear()
    for path in paths:
        _remove(path)


# --- worker processes -------------------------------------------------------------------


def _worker_main(conn: Connection) -> None:
    """A worker: trace the units it is sent, keeping the tracer of the last scene."""
    # Ctrl-C reaches the whole process group; the parent decides what stops, and a worker
    # interrupted mid-unit would only print a traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from .units import trace_unit  # the renderer and numba load now, before the first task

    key, tracer = None, None
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return  # the parent is gone
        if task is None:
            return
        shipment, unit, seed = task
        try:
            if shipment.key != key:
                tracer = None  # free the old scene before loading the new one
                tracer = _load_tracer(shipment, conn if unit is not None else None)
                key = shipment.key
            if unit is not None:
                conn.send(("done", unit.index, trace_unit(tracer, unit, seed)))
        except Exception as error:  # reported to the parent, which raises it there
            if unit is not None:  # a warm-up's failure is reported by the unit that follows it
                conn.send(("error", unit.index, _picklable(error), traceback.format_exc()))


def _load_tracer(shipment: Shipment, conn: Connection | None) -> Tracer:
    """The scene's tracer (its kernels compiled or loaded), saying "compile" and "ready" on
    conn; silently for a warm-up (conn None), whose messages nobody would read in time."""
    from .integrator.wavefront import Tracer

    cs, settings = load_shipment(shipment.path)
    if conn is None:
        return Tracer(cs, settings)
    tracer = Tracer(cs, settings, lambda names: conn.send(("compile", names)))
    conn.send(("ready",))
    return tracer


def _picklable(error: Exception) -> Exception:
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:
        return RuntimeError(f"{type(error).__name__}: {error}")


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while a worker starts: the new process inherits that (Python keeps an
    ignored SIGINT), so a Ctrl-C sent to the process group while it is still importing
    cannot interrupt it with a traceback; the parent decides what stops. Only the main
    thread may set handlers (F12 in Blender's UI renders on another thread; no Ctrl-C there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


_MAIN_LOCK = threading.RLock()


@contextmanager
def _main_script_hidden() -> Iterator[None]:
    """While child processes are spawned, __main__ is a bare module: spawn otherwise tells
    each child to run the parent's script again as __mp_main__ (it sends the path of
    __main__.__file__). A user's bpy script cannot import bpy there (a traceback in its
    output) and any other script would redo its work; the workers need nothing from it.
    A `python -m` main was already skipped by multiprocessing and is left alone."""
    with _MAIN_LOCK:
        real = sys.modules.get("__main__")
        if real is None or getattr(real, "__spec__", None) is not None or not hasattr(real, "__file__"):
            yield
            return
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            yield
        finally:
            sys.modules["__main__"] = real


@contextmanager
def spawning() -> Iterator[None]:
    """How every Haze child process is started (workers, a LocalCluster's): SIGINT ignored
    and the parent's script hidden."""
    with _sigint_ignored(), _main_script_hidden():
        yield


class Worker:
    def __init__(self) -> None:
        ctx = multiprocessing.get_context("spawn")  # Blender cannot fork; spawn everywhere alike
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child,), daemon=True, name="haze-worker")
        with spawning():
            self.process.start()
        child.close()
        self.unit: Unit | None = None  # the unit in flight
        self.compiling = False
        self.scene_key = ""  # the shipment it was last sent (warm-up or unit)

    def send(self, shipment: Shipment, unit: Unit, seed: int) -> None:
        self.unit, self.scene_key = unit, shipment.key
        try:
            self.conn.send((shipment, unit, seed))
        except OSError:
            pass  # it died: its sentinel says so at the next wait, and the unit is retried

    def warm(self, shipment: Shipment) -> None:
        """Load the scene's tracer without a unit: its kernels are compiled (or loaded) now,
        with nothing said back; a unit sent later waits in the pipe until that is done."""
        self.scene_key = shipment.key
        try:
            self.conn.send((shipment, None, 0))
        except OSError:
            pass

    def alive(self) -> bool:
        return self.process.is_alive()

    def stop(self, terminate: bool) -> None:
        """End the process: politely when idle, at once when it may be inside a kernel."""
        if not terminate and self.alive():
            try:
                self.conn.send(None)
            except OSError:
                terminate = True
        if terminate and self.alive():
            self.process.terminate()
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(timeout=5)
        self.conn.close()


class Pool:
    """The persistent workers of this process."""

    def __init__(self) -> None:
        self.workers: list[Worker] = []
        self.in_use = False  # by a render (see borrowed_pool)

    def resize(self, n: int) -> None:
        """n workers: idle ones that died are replaced. A busy one that died stays until the
        render has seen its death (events), so that its unit is traced again, not lost."""
        for dead in [w for w in self.idle() if not w.alive()]:
            dead.stop(terminate=True)  # reaps it and closes its pipe
            self.workers.remove(dead)
        while len(self.workers) > n and self.idle():
            self.stop_one(self.idle()[-1])
        while len(self.workers) < n:
            self.workers.append(Worker())

    def stop_one(self, worker: Worker) -> None:
        self.workers.remove(worker)
        worker.stop(terminate=False)

    def idle(self) -> list[Worker]:
        return [w for w in self.workers if w.unit is None]

    def busy(self) -> list[Worker]:
        return [w for w in self.workers if w.unit is not None]

    def replace(self, worker: Worker) -> None:
        """A new process in place of `worker`, which is terminated if still running."""
        worker.stop(terminate=True)
        self.workers[self.workers.index(worker)] = Worker()

    def terminate_busy(self) -> None:
        """Stop units in flight (their results would reach the next render otherwise)."""
        for worker in self.busy():
            worker.stop(terminate=True)
        self.workers = [w for w in self.workers if w.unit is None]

    def drain(self, timeout: float) -> None:
        """Let units in flight finish for up to `timeout` seconds, discarding their results,
        so that a cancelled render does not cost the next one its workers' start."""
        deadline = time.monotonic() + timeout
        while self.busy() and deadline > time.monotonic():
            for worker, message in self.events(deadline - time.monotonic()):
                if message is None or message[0] in ("done", "error"):
                    worker.unit = None

    def events(self, timeout: float) -> list[tuple[Worker, tuple | None]]:
        """Messages from busy workers, (worker, None) for one that died; [] on timeout."""
        busy = self.busy()
        handles = {}
        for w in busy:
            handles[w.conn] = w
            handles[w.process.sentinel] = w
        ready = wait_for(list(handles), timeout=max(0.0, timeout))
        out: list[tuple[Worker, tuple | None]] = []
        for w in dict.fromkeys(handles[h] for h in ready):  # each worker once, in order
            try:
                # A worker that sent its result and then died still delivers the result.
                while w.conn.poll():
                    out.append((w, w.conn.recv()))
            except (EOFError, OSError):
                pass
            if not w.alive():
                out.append((w, None))  # after its messages: a unit it finished is not lost
        return out

    def pids(self) -> list[int]:
        return [w.process.pid for w in self.workers if w.alive() and w.process.pid is not None]

    def shutdown(self) -> None:
        # Terminated, not asked: an idle worker holds nothing to save, and one still starting
        # would otherwise hold up the exit until its imports are done.
        for worker in self.workers:
            worker.stop(terminate=True)
        self.workers = []


pool = Pool()


@contextmanager
def borrowed_pool() -> Iterator[Pool]:
    """The shared pool for one render; a private one, stopped afterwards, for a render that
    starts while another still runs (two generators at once must not read each other's
    messages)."""
    if pool.in_use:
        private = Pool()
        try:
            yield private
        finally:
            private.shutdown()
        return
    pool.in_use = True
    try:
        yield pool
    finally:
        pool.in_use = False


def shutdown_workers() -> None:
    """Stop the worker processes (the add-on calls this when it is disabled; also at exit)."""
    pool.shutdown()
    _remove_leftovers()  # no worker maps them any more


def start_workers(n: int) -> None:
    """Have at least n workers (starting them now, without waiting): call it early, so that
    their start overlaps the caller's own imports and scene loading."""
    pool.resize(max(n, len(pool.workers)))


def worker_pids() -> list[int]:
    """Process ids of the live workers (a later render reuses them)."""
    return pool.pids()


atexit.register(shutdown_workers)
