"""Compile (or load) a set of kernels before they are first called, once per machine.

Numba compiles a kernel the first time it is called with new argument types. Left to
that, two worker processes starting on a cold cache both compile everything (minutes, and
about 2 GB each), and nothing can tell the user why the first image is late. Instead, the
tracer lists the calls it will make (kernel and example arguments of the right types) and
`warm_up` compiles their signatures up front: if every one is already in the cache it just
loads them. Otherwise it compiles the cold ones, each under its own inter-process lock
(renderer.kernels.cache.function_lock): kernels another process is compiling are left for
last, so two workers on a cold cache compile different kernels at once (one core each),
and a kernel one has compiled the other waits for and loads.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from numba.core.dispatcher import Dispatcher
from numba.core.registry import CPUDispatcher

from .cache import function_lock

KernelCall = tuple[CPUDispatcher, tuple]


def signature(kernel: CPUDispatcher, args: tuple) -> tuple:
    """The numba types `kernel` would be compiled for when called with `args`."""
    return tuple(kernel.typeof_pyval(a) for a in args)


def is_ready(kernel: CPUDispatcher, sig: tuple) -> bool:
    """True if this process has the signature compiled, or the cache holds it."""
    if sig in kernel.overloads:
        return True
    cache = getattr(kernel, "_cache", None)
    try:
        index = cache._cache_file._load_index()
        return cache._index_key(sig, kernel.targetctx.codegen()) in index
    except (AttributeError, OSError, EOFError, ValueError):
        return False  # no cache or an unreadable index: compiling is the safe answer


def warm_up(calls: Sequence[KernelCall], on_compile: Callable[[list[str]], None] | None = None) -> float:
    """Make every call's signature ready: load it, or compile it under the compile lock.
    `on_compile(names)` is called first when something must be compiled. Returns the
    seconds spent compiling (0.0 when everything was cached)."""
    # Stand-ins for kernels (a test's wrapper, a profiler's timer) are left to run as they are.
    sigs = [(k, signature(k, args)) for k, args in calls if isinstance(k, Dispatcher)]
    cold = [k.py_func.__name__ for k, sig in sigs if not is_ready(k, sig)]
    if not cold:
        for k, sig in sigs:
            k.compile(sig)
        return 0.0
    if on_compile is not None:
        on_compile(cold)
    t = time.perf_counter()
    pending = [(k, sig) for k, sig in sigs if not is_ready(k, sig)]
    while pending:
        pending = _compile_unclaimed(pending)
        if pending:  # all claimed by other processes: wait for one, then load it
            k, sig = pending.pop(0)
            k.compile(sig)
    for k, sig in sigs:
        k.compile(sig)  # the cached ones: load
    return time.perf_counter() - t


def _compile_unclaimed(pending: list[tuple[CPUDispatcher, tuple]]) -> list[tuple[CPUDispatcher, tuple]]:
    """Compile every pending kernel no other process holds the lock of; return the rest."""
    left = []
    for k, sig in pending:
        name = getattr(k, "lock_name", None)
        if name is None:
            k.compile(sig)
            continue
        with function_lock(name, blocking=False) as held:
            if held:
                k.compile(sig)
            else:
                left.append((k, sig))
    return left
