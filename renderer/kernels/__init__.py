"""Numba kernels shared by the integrator, BSDFs, lights and media.

Vectors are plain 3-tuples of floats inside kernels (numba keeps them in registers);
arrays crossing the Python boundary are contiguous float32/int32 structure-of-arrays.
"""

import numpy as np
from numba import njit
from numba.core import sigutils
from numba.core.registry import CPUDispatcher

from . import cache
from .cache import function_lock

# Before any kernel is defined: every kernel goes to the shared, content-keyed cache.
cache.install()

# The flags of every kernel, in one place: cached machine code, numpy's error model (no
# exceptions on division by zero), no reference counting, and fused multiply-adds (fastmath
# "contract" only: no other fast-math assumption, so NaN/inf tests and rounding-sensitive
# formulas keep their meaning). Measured: "contract" made the fog box 3-6% faster.
JIT_OPTIONS = {"cache": True, "error_model": "numpy", "fastmath": {"contract"}, "_nrt": False}
#
# Which decorator (the cold compile, issue 19). Both compile a function once per argument
# types, in numba, and cache it; they differ in what LLVM does at a call site.
# `inline_kernel` marks the function alwaysinline for LLVM (numba's `forceinline`): every
# caller gets the callee's optimised LLVM body, so the hot helpers cost no call and LLVM sees
# whole loops to vectorise. It replaced numba's own `inline="always"`, which re-translated,
# re-typed and SSA-converted a fresh copy of the callee's Python at every call site (and of
# everything inlined into it in turn): shade_surface spent 85 of its 118 s of compile there.
# Measured (fog box, cold cache, CPU seconds to the first pass, machine loaded): 180 s -> 77 s;
# samples/s unchanged within this VM's noise; python -m bench golden bit-identical (41 of 41).
# A function that returns an array cannot be a separate function without numba's reference
# counting (off here), so such one-liners are written out where they are used.
# `kernel` leaves inlining to LLVM's cost model: for large helpers off the hot path (the
# medium's phase sampling, sample_distance, sample_segment, nee_vertex_on, shade_media's
# connect_light), which then compile and optimise once instead of once per call site. A
# scene without grids passes grid_md = None so that no grid tracker is compiled.
# A kernel also compiles once per argument type it meets while its caller is typed, literal
# constants included (Literal[int](0) and int64 are two compiles): pass int64 or bool
# variables to a kernel, not literals.


_SCALARS = (int, float, bool, type(None), np.integer, np.floating, np.bool_)


def _arg_key(value) -> object:
    """What decides an argument's numba type, cheaply: an array's class, dtype, dimensions,
    layout and writability; a scalar's type; anything else (tuples of arrays, whose
    elements' types count) the object itself, by identity (the key keeps it alive, so `is`
    cannot meet a new object at a reused address)."""
    if isinstance(value, np.ndarray):
        flags = value.flags
        return (type(value), value.dtype, value.ndim, flags.c_contiguous, flags.f_contiguous,
                flags.writeable, flags.aligned)
    if isinstance(value, _SCALARS):
        return type(value)
    return _Same(value)


class _Same:
    """Equal only to the same object (identity), for argument keys."""

    __slots__ = ("value",)

    def __init__(self, value) -> None:
        self.value = value

    def __eq__(self, other) -> bool:
        return isinstance(other, _Same) and other.value is self.value

    def __hash__(self) -> int:
        return id(self.value)


class Kernel(CPUDispatcher):
    """A numba function that compiles under its own inter-process lock (cache.function_lock):
    of two processes needing it on a cold cache, one compiles and saves it, the other waits
    and loads it.

    A call from Python reuses the compiled entry point of its previous call when every
    argument has the same key (_arg_key): numba resolves the types of tuple arguments
    (the driver's structures of arrays: Geometry, Shadows, the media table) in Python on
    every call, about 0.1-0.4 ms each, which the driver's many small per-bounce calls on the
    last paths of a batch paid over and over (10% of a smoke ball render's time).
    """

    def __call__(self, *args):
        memo = self.__dict__.get("_last_call")
        keys = tuple(_arg_key(a) for a in args)
        if memo is not None and memo[0] == keys:
            return memo[1](*args)
        result = super().__call__(*args)
        types = tuple(self.typeof_pyval(a) for a in args)
        compiled = self.overloads.get(types)
        if compiled is not None:
            self.__dict__["_last_call"] = (keys, compiled.entry_point)
        return result

    def compile(self, sig):
        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in self.overloads:
            return super().compile(sig)  # already here: nothing to compile or lock
        with function_lock(self.lock_name):
            return super().compile(sig)  # loads from the cache if another process saved it

    @property
    def lock_name(self) -> str:
        return f"{self.py_func.__module__}.{self.py_func.__qualname__}"


class InlineDispatcher(Kernel):
    """A helper without the wrappers through which Python calls a numba function.

    Numba builds a CPython wrapper (unboxing every argument, boxing the result) and a C
    wrapper for every function it compiles. A helper only ever runs inlined into kernels, so
    its wrappers were pure compile time: about a third of the fog box's cold compile. Without
    them a direct call from Python would crash the process, so such calls (tests, tools) go
    through a small jitted entry compiled on first use instead.
    """

    def __call__(self, *args):
        entry = self.__dict__.get("_python_entry")
        if entry is None:
            entry = self.__dict__["_python_entry"] = _python_entry(self)
        return entry(*args)


def _python_entry(helper: InlineDispatcher):
    def call(*args):
        return helper(*args)

    return njit(**{**JIT_OPTIONS, "cache": False})(call)  # a closure: nothing for the cache to key on


def _make(cls: type[Kernel], func, **extra) -> Kernel:
    options = {k: v for k, v in JIT_OPTIONS.items() if k != "cache"}
    options.update(nopython=True, **extra)
    dispatcher = cls(py_func=func, locals={}, targetoptions=options)
    dispatcher.enable_caching()
    return dispatcher


def kernel(func) -> Kernel:
    """Compiled once per argument types; LLVM inlines it only where its cost model says so."""
    return _make(Kernel, func)


def helper_kernel(func) -> InlineDispatcher:
    """A large helper that several kernels call (the shader interpreter): compiled and
    optimised once, then called, without Python's wrappers. Forced inlining would optimise
    its whole body again inside every caller."""
    return _make(InlineDispatcher, func, no_cpython_wrapper=True, no_cfunc_wrapper=True)


def inline_kernel(func) -> InlineDispatcher:
    """Compiled once per argument types, inlined by LLVM at every call (see above)."""
    return _make(InlineDispatcher, func, forceinline=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)


def exact_kernel(func) -> InlineDispatcher:
    """An inline_kernel compiled without fast-math: one float32 rounding per operation and no
    contraction of a * b + c, for code that must round as the C++ it mirrors does
    (renderer.kernels.exact)."""
    return _make(InlineDispatcher, func, fastmath=False, forceinline=True, no_cpython_wrapper=True,
                 no_cfunc_wrapper=True)
