"""The persistent worker processes of renderer.render (the local back-end of renderer.schedule).

Spawned processes (Blender cannot fork; spawn everywhere alike) that live across renders
in this process: a second render or the next animation frame reuses them. Each task carries
the scene's shipment (renderer.shipment: a file named by the scene's hash), and a worker
loads the scene and builds its tracer only for a key it has not got (it keeps one tracer).
The parent (renderer.render) watches each worker's pipe and process sentinel, so it can
terminate one stuck inside a kernel and notice one that died. Every child process Haze
starts (these, a LocalCluster's) is started under `spawning()`.

Workers die with their parent whatever ends it: on Linux each asks the kernel for SIGKILL
when its parent goes (prctl PR_SET_PDEATHSIG), which ends it even inside a kernel call,
where no Python code of its own could run. That signal follows the parent *thread* that
started the process, so workers are started by the main thread, or else by one thread that
lives as long as the process (_Spawner: Blender renders on threads that end with each
render). The multiprocessing resource tracker exits once its last client is gone; scene
files a killed parent left are removed by the next render (renderer.shipment).

This module imports only the standard library, so a caller can start workers before it
imports numba (`start_workers`): the workers' imports then overlap its own. A worker
imports the renderer as soon as it starts, before its first task.
"""

from __future__ import annotations

import atexit
import ctypes
import multiprocessing
import os
import pickle
import queue
import signal
import sys
import threading
import time
import traceback
import types
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_for
from typing import TYPE_CHECKING

from .shipment import Shipment, load_shipment, remove_leftovers

if TYPE_CHECKING:
    from .integrator.wavefront import Tracer
    from .units import Unit

# prctl(2) option: the signal this process gets when its parent thread ends (Linux).
PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int) -> None:
    """Have the kernel SIGKILL this process when its parent ends (Linux); exit now if the
    parent (process id `parent`) is already gone, which the signal would never report."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the parent's pipe still ends idle workers
            pass
    if os.getppid() != parent:
        os._exit(1)


def _worker_main(conn: Connection, parent: int | None = None) -> None:
    """A worker: trace the units it is sent, keeping the tracer of the last scene. `parent`:
    the process id of the process that started it (None: the loop runs in its caller's
    process, as tests run it, which must not die with its parent)."""
    if parent is not None:
        die_with_parent(parent)
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


class _Spawner:
    """The thread that starts workers for threads other than the main one. It lives as long
    as the process, so a worker's parent-death signal (die_with_parent) fires only when the
    process ends, not when the render thread that wanted the worker does."""

    def __init__(self) -> None:
        self.requests: queue.Queue = queue.Queue()
        self.thread: threading.Thread | None = None
        self.lock = threading.Lock()

    def start(self, process) -> None:
        """process.start() on a thread that outlives the caller's; its exception, raised here."""
        if threading.current_thread() is threading.main_thread():
            process.start()
            return
        with self.lock:
            if self.thread is None:
                self.thread = threading.Thread(target=self._serve, daemon=True, name="haze-spawner")
                self.thread.start()
        done: queue.Queue = queue.Queue(maxsize=1)
        self.requests.put((process, done))
        error = done.get()
        if error is not None:
            raise error

    def _serve(self) -> None:
        while True:
            process, done = self.requests.get()
            try:
                process.start()
                done.put(None)
            except BaseException as error:  # noqa: BLE001 - handed to the caller
                done.put(error)


_spawner = _Spawner()


class Worker:
    def __init__(self) -> None:
        ctx = multiprocessing.get_context("spawn")  # Blender cannot fork; spawn everywhere alike
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child, os.getpid()), daemon=True,
                                   name="haze-worker")
        with spawning():  # SIGINT ignored and __main__ hidden process-wide, for the spawner too
            _spawner.start(self.process)
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
    remove_leftovers()  # no worker maps them any more


def start_workers(n: int) -> None:
    """Have at least n workers (starting them now, without waiting): call it early, so that
    their start overlaps the caller's own imports and scene loading."""
    pool.resize(max(n, len(pool.workers)))


def worker_pids() -> list[int]:
    """Process ids of the live workers (a later render reuses them)."""
    return pool.pids()


atexit.register(shutdown_workers)
