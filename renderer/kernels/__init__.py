"""Numba kernels shared by the integrator, BSDFs, lights and media.

Vectors are plain 3-tuples of floats inside kernels (numba keeps them in registers);
arrays crossing the Python boundary are contiguous float32/int32 structure-of-arrays.
"""

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
# samples/s unchanged within this VM's noise; tools/golden_images.py bit-identical (41 of 41).
# A function that returns an array cannot be a separate function without numba's reference
# counting (off here), so such one-liners are written out where they are used.
# `kernel` leaves inlining to LLVM's cost model: for large helpers off the hot path (the
# medium's phase sampling, sample_distance, sample_segment, nee_vertex_on, shade_media's
# connect_light), which then compile and optimise once instead of once per call site. A
# scene without grids passes grid_md = None so that no grid tracker is compiled.
# A kernel also compiles once per argument type it meets while its caller is typed, literal
# constants included (Literal[int](0) and int64 are two compiles): pass int64 or bool
# variables to a kernel, not literals.


class Kernel(CPUDispatcher):
    """A numba function that compiles under its own inter-process lock (cache.function_lock):
    of two processes needing it on a cold cache, one compiles and saves it, the other waits
    and loads it."""

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
