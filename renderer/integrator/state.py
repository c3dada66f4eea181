"""Structure-of-arrays state of a batch of paths, and of their shadow rays, and the records
the stages take them in (Batch, Slots).

A path owns slot `pid` of the batch's radiance array for its whole life; its other state
moves when the batch is compacted, so rows [0, n) are always the live paths and feed
Embree as contiguous arrays.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..compile import MAX_STACK


class Paths(NamedTuple):
    """N rows; float32 unless noted.

    o, d (N, 3): next ray origin and unit direction; tmax (N,): its length (Embree writes
    the hit distance into it). gap (N,): how far o was pushed off the surface it leaves
    (Embree has no tnear), measured along d; media integrate from o - gap d, so an
    interface crossing loses no medium. beta (N, 3): throughput. pid (N,) int32: slot in the batch's
    radiance array. key (N,) uint64, dim (N,) int32: the path's random-number key and next
    dimension. depth (N,) int32: scattering events so far (Cycles' bounce count).
    crossings (N,) int32: pass-throughs (interfaces, transparent lobes), capped to end
    loops. mis_pdf (N,): solid-angle pdf of the last scattering direction (0 after a delta
    event or at the camera, meaning "no MIS"). mis_o (N, 3): where that direction started.
    stack (N, MAX_STACK) int32: media the path is in (-1 = free slot). alive (N,) uint8.
    """

    o: np.ndarray
    d: np.ndarray
    tmax: np.ndarray
    gap: np.ndarray
    beta: np.ndarray
    pid: np.ndarray
    key: np.ndarray
    dim: np.ndarray
    depth: np.ndarray
    crossings: np.ndarray
    mis_pdf: np.ndarray
    mis_o: np.ndarray
    stack: np.ndarray
    alive: np.ndarray


class Shadows(NamedTuple):
    """Up to 2 shadow rays per path per bounce (a medium next-event vertex and a surface or
    medium-scattering one). o, d (S, 3), tmax (S,), gap (S,) (as for paths: the push off
    the surface, integrated by media), contrib (S, 3) unoccluded radiance,
    pid (S,) int32, key (S,) uint64, dim (S,) int32 (random numbers for tracking through
    media while walking interfaces), stack (S, MAX_STACK) int32, alive (S,) uint8,
    col (S,) int32: the light pass column of L its arrival also adds to (paths.NO_PASS:
    none), fixed where it is emitted (the path's depth moves on before it is traced)."""

    o: np.ndarray
    d: np.ndarray
    tmax: np.ndarray
    gap: np.ndarray
    contrib: np.ndarray
    pid: np.ndarray
    key: np.ndarray
    dim: np.ndarray
    stack: np.ndarray
    alive: np.ndarray
    col: np.ndarray


class Batch(NamedTuple):
    """What the stages of a batch share and write: its paths, their shadow rays, and the
    radiance array L (B, paths.RADIANCE columns, float64), row pid for the path of slot pid."""

    paths: Paths
    shadows: Shadows
    L: np.ndarray


class Slots(NamedTuple):
    """Per radiance slot (B,) int32: pixel, the tile's pixel its path samples; half, 1 for an
    odd sample (kernels.rng.SAMPLE_HALVES). Written by start_paths, read by splat."""

    pixel: np.ndarray
    half: np.ndarray


def allocate_paths(n: int) -> Paths:
    return Paths(
        o=np.zeros((n, 3), np.float32), d=np.zeros((n, 3), np.float32), tmax=np.zeros(n, np.float32),
        gap=np.zeros(n, np.float32), beta=np.zeros((n, 3), np.float32), pid=np.zeros(n, np.int32),
        key=np.zeros(n, np.uint64),
        dim=np.zeros(n, np.int32), depth=np.zeros(n, np.int32), crossings=np.zeros(n, np.int32),
        mis_pdf=np.zeros(n, np.float32), mis_o=np.zeros((n, 3), np.float32),
        stack=np.full((n, MAX_STACK), -1, np.int32), alive=np.zeros(n, np.uint8),
    )


def allocate_shadows(n: int) -> Shadows:
    s = 2 * n
    return Shadows(
        o=np.zeros((s, 3), np.float32), d=np.zeros((s, 3), np.float32), tmax=np.zeros(s, np.float32),
        gap=np.zeros(s, np.float32), contrib=np.zeros((s, 3), np.float32), pid=np.zeros(s, np.int32),
        key=np.zeros(s, np.uint64),
        dim=np.zeros(s, np.int32), stack=np.full((s, MAX_STACK), -1, np.int32), alive=np.zeros(s, np.uint8),
        col=np.full(s, -1, np.int32),
    )
