"""Embree intersection for whole batches of rays.

All meshes are merged into one Embree triangle geometry, so a hit's primID is the global
triangle index that every per-triangle table in `renderer.compile` is indexed by.
embreex takes float32 only, has no tnear (callers offset origins) and holds Python's lock
during `run()`, so parallelism comes from processes, not threads.
"""

from __future__ import annotations

import numpy as np
from embreex import rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh


class Intersector:
    """Closest-hit and occlusion queries over one triangle soup."""

    def __init__(self, vertices: np.ndarray, indices: np.ndarray):
        """vertices (V, 3) float32 world space; indices (T, 3) int32."""
        self.num_triangles = int(indices.shape[0])
        self._scene = rtcs.EmbreeScene()
        if self.num_triangles > 0:
            TriangleMesh(
                self._scene,
                np.ascontiguousarray(vertices, dtype=np.float32),
                np.ascontiguousarray(indices, dtype=np.int32),
            )

    def intersect(self, origins: np.ndarray, dirs: np.ndarray, tmax: np.ndarray):
        """Closest hits of n rays. origins, dirs (n, 3) float32; tmax (n,) float32, overwritten
        with the hit distance (unchanged on a miss). Returns (prim (n,) int32, -1 on a miss,
        u (n,) float32, v (n,) float32) with the hit point = (1-u-v) v0 + u v1 + v v2."""
        n = origins.shape[0]
        if self.num_triangles == 0 or n == 0:
            return np.full(n, -1, np.int32), np.zeros(n, np.float32), np.zeros(n, np.float32)
        hits = self._scene.run(origins, dirs, dists=tmax, output=1)
        return hits["primID"], hits["u"], hits["v"]

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """True where something lies between origin and origin + tmax * dir. (n,) bool."""
        n = origins.shape[0]
        if self.num_triangles == 0 or n == 0:
            return np.zeros(n, np.bool_)
        return self._scene.run(origins, dirs, dists=tmax, query="OCCLUDED") != -1
