"""Numba kernels shared by the integrator, BSDFs, lights and media.

Vectors are plain 3-tuples of floats inside kernels (numba keeps them in registers);
arrays crossing the Python boundary are contiguous float32/int32 structure-of-arrays.
"""

import llvmlite.binding as llvm
from numba import njit

# LLVM vectorises a loop only if it can check at run time that its arrays do not overlap, and
# by default gives up beyond 8 such checks; the SIMD loops over packed batches
# (renderer.integrator.nee_batch) read ~50 array rows, so they need a few hundred. Set once
# per process: LLVM rejects an option given twice (a reloaded add-on imports this again).
if not getattr(llvm, "_haze_vectorizer_options", False):
    llvm.set_option("", "-runtime-memory-check-threshold=2048")
    llvm.set_option("", "-pragma-vectorize-memory-check-threshold=2048")
    llvm._haze_vectorizer_options = True

# The flags of every kernel, in one place: cached machine code, numpy's error model (no
# exceptions on division by zero), no reference counting, and fused multiply-adds (fastmath
# "contract" only: no other fast-math assumption, so NaN/inf tests and rounding-sensitive
# formulas keep their meaning). Measured: "contract" made the fog box 3-6% faster.
JIT_OPTIONS = {"cache": True, "error_model": "numpy", "fastmath": {"contract"}, "_nrt": False}
kernel = njit(**JIT_OPTIONS)
inline_kernel = njit(**JIT_OPTIONS, inline="always")  # inlined into its callers at numba IR level
