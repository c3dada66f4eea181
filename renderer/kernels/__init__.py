"""Numba kernels shared by the integrator, BSDFs, lights and media.

Vectors are plain 3-tuples of floats inside kernels (numba keeps them in registers);
arrays crossing the Python boundary are contiguous float32/int32 structure-of-arrays.
"""

from numba import njit

from . import cache

# Before any kernel is defined: every kernel goes to the shared, content-keyed cache.
cache.install()

# The flags of every kernel, in one place: cached machine code, numpy's error model (no
# exceptions on division by zero), no reference counting, and fused multiply-adds (fastmath
# "contract" only: no other fast-math assumption, so NaN/inf tests and rounding-sensitive
# formulas keep their meaning). Measured: "contract" made the fog box 3-6% faster.
JIT_OPTIONS = {"cache": True, "error_model": "numpy", "fastmath": {"contract"}, "_nrt": False}
#
# Which decorator (the cold compile, issue 19). `inline_kernel` inlines at numba IR level: at
# every call site numba translates, re-types and SSA-converts a fresh copy of the callee and
# of everything it inlines in turn, so a big callee reached from several places costs its
# whole compile again at each. A `kernel` is compiled once per signature and cached, and
# LLVM may still inline it where it links the callee's module into the caller. So the large
# helpers of the scalar medium path are plain kernels (the phase sampling and evaluation of
# a stack, sample_distance, sample_segment, nee_vertex_on, and shade_media's connect_light),
# and a scene without grids passes grid_md = None so that no grid tracker is compiled.
# Measured (tools/compile_profile.py fog, cold cache, two builds at once, one core each):
# 415 s -> 148 s to the first pass, shade_media 240 -> 21 s of its own. Still inlined:
# the small vector, random-number and table helpers; whatever takes the path or shadow
# tables (ps, sh: a call passes every array's fields, and _medium_nee as a call cost 50 ns,
# commit 9706474); everything the SIMD batch loops call (LLVM must see it all to
# vectorise); and the surface stage's light and BSDF calls, which are hot (as kernels they
# cut the surface stage's compile 3x but cost about 15% of the surface box's speed).
# A kernel also compiles once per argument type it meets while its caller is typed, literal
# constants included (Literal[int](0) and int64 are two compiles): pass int64 or bool
# variables to a kernel, not literals.
kernel = njit(**JIT_OPTIONS)
inline_kernel = njit(**JIT_OPTIONS, inline="always")  # inlined into its callers at numba IR level
