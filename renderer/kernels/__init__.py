"""Numba kernels shared by the integrator, BSDFs, lights and media.

Vectors are plain 3-tuples of floats inside kernels (numba keeps them in registers);
arrays crossing the Python boundary are contiguous float32/int32 structure-of-arrays.
"""
