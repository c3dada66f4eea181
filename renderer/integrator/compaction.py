"""Compaction: after each bounce, move the live rows of the path (and shadow-ray) arrays to
the front, in order, so that the next Embree call and every kernel see rows [0, k) as one
contiguous batch. A path keeps its radiance slot (pid) wherever its row moves.
"""

from ..kernels import kernel
from .paths import PATH_ACTIVE, PATH_DEAD


@kernel
def compact_paths(n, ps):
    """Move live paths to rows 0..k-1 (stable), each PATH_ACTIVE again, and return k."""
    k = 0
    for i in range(n):
        if ps.alive[i] == PATH_DEAD:
            continue
        if k != i:
            for c in range(3):
                ps.o[k, c] = ps.o[i, c]
                ps.d[k, c] = ps.d[i, c]
                ps.beta[k, c] = ps.beta[i, c]
                ps.mis_o[k, c] = ps.mis_o[i, c]
            ps.tmax[k] = ps.tmax[i]
            ps.gap[k] = ps.gap[i]
            ps.pid[k] = ps.pid[i]
            ps.key[k] = ps.key[i]
            ps.dim[k] = ps.dim[i]
            ps.depth[k] = ps.depth[i]
            ps.crossings[k] = ps.crossings[i]
            ps.mis_pdf[k] = ps.mis_pdf[i]
            for j in range(ps.stack.shape[1]):
                ps.stack[k, j] = ps.stack[i, j]
        ps.alive[k] = PATH_ACTIVE
        k += 1
    return k


@kernel
def compact_shadows(n, sh, remaining):
    """Keep live shadow rays (rows 0..k-1); `remaining` (S,) float32 holds each ray's length
    left to its light and moves along."""
    k = 0
    for i in range(n):
        if sh.alive[i] == 0:
            continue
        if k != i:
            for c in range(3):
                sh.o[k, c] = sh.o[i, c]
                sh.d[k, c] = sh.d[i, c]
                sh.contrib[k, c] = sh.contrib[i, c]
            sh.pid[k] = sh.pid[i]
            sh.gap[k] = sh.gap[i]
            sh.key[k] = sh.key[i]
            sh.dim[k] = sh.dim[i]
            sh.col[k] = sh.col[i]
            for j in range(sh.stack.shape[1]):
                sh.stack[k, j] = sh.stack[i, j]
            sh.alive[k] = 1
        remaining[k] = remaining[i]
        k += 1
    return k
