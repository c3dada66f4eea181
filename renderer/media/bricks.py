"""Sparse grids: 8^3 bricks of voxels (an OpenVDB leaf's size) and an index of occupied ones.

A SparseGrid holds the same voxels as a dense (nz, ny, nx) array but stores only bricks
that can give a non-zero trilinear value. Brick (bk, bj, bi) of the brick lattice covers
voxels 8 bk .. 8 bk + 7 (z) and likewise in y and x; it is stored with a one-voxel apron
on its upper side, SPAN = 9 voxels per axis, so the 8 voxels of any trilinear stencil
whose lower corner lies in the brick are in that one stored block. We chose the apron
over looking neighbours up through the index: a lookup then costs one index read and the
same eight loads and arithmetic as the dense grid (so sparse and dense lookups give
bit-identical values), for 729 / 512 = 1.42x the memory of the bare voxels. A brick is
occupied when any of its 9^3 stored voxels is non-zero; every other brick reads as 0,
which is exact because its stencils touch only its own (all zero) block.

Apron voxels past the grid's last voxel repeat the edge voxel; lookups never read them
(a clamped axis steps 0, see grid.py).

Large grids are written brick row by brick row into a file that every process maps
(renderer.mapped), never held whole in a process's own memory; each brick's least and
largest stored value are kept beside the bricks as they are built, so majorants need not
read the bricks again.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import as_strided

from renderer.mapped import MIN_BYTES, FileWriter

BRICK = 8  # voxels per brick and axis
SPAN = BRICK + 1  # stored voxels per brick and axis: the brick's own and the next brick's first


def lattice_shape(shape: tuple[int, int, int]) -> tuple[int, int, int]:
    """(bz, by, bx) bricks covering a grid of (nz, ny, nx) voxels."""
    return tuple(-(-int(n) // BRICK) for n in shape)


@dataclass(frozen=True, eq=False)
class SparseGrid:
    """A grid of (nz, ny, nx) voxels stored as bricks.

    index   (bz, by, bx) int32   brick number of lattice cell (bk, bj, bi) in `bricks`, -1 = empty
    bricks  (B, SPAN, SPAN, SPAN) float32, or (B, SPAN, SPAN, SPAN, 3) for an RGB grid:
            brick b's voxels 8 bk + z, 8 bj + y, 8 bi + x for z, y, x in 0..8 (z slowest)
    """

    shape: tuple[int, int, int]  # (nz, ny, nx) voxels, as a dense array's shape (channels aside)
    index: np.ndarray
    bricks: np.ndarray
    # (B + 1, SPAN, SPAN, SPAN[, 3]): an all-zero brick, then `bricks` (which view it), or None.
    # The renderer stores a sparse grid that way (empty bricks point at the zero brick), so a
    # grid built in it is compiled without a copy: at 512^3 the bricks are 100s of MB.
    zero_led_storage: np.ndarray | None = field(default=None, repr=False)
    # (2, B) float32: each brick's least and largest stored value (channels included), as
    # the builder saw them, or None (then computed from the bricks when asked for).
    bounds: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def from_zero_led(cls, shape: tuple[int, int, int], index: np.ndarray, storage: np.ndarray,
                      bounds: np.ndarray | None = None) -> SparseGrid:
        """The grid whose bricks are storage[1:]; storage[0] must be all zero."""
        return cls(shape, index, storage[1:], storage, bounds)

    def zero_led(self) -> np.ndarray:
        """(B + 1, SPAN, SPAN, SPAN[, 3]) float32: a zero brick, then the bricks (no copy when
        the grid was built that way, as BrickBuilder and map build them)."""
        if self.zero_led_storage is not None:
            return self.zero_led_storage
        zero = np.zeros((1,) + self.bricks.shape[1:], np.float32)
        return np.concatenate([zero, np.asarray(self.bricks, np.float32)])

    @property
    def ndim(self) -> int:
        return 3 + (self.bricks.ndim - 4)

    @property
    def channels(self) -> int:
        return 1 if self.bricks.ndim == 4 else int(self.bricks.shape[-1])

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @property
    def nbytes(self) -> int:
        return self.index.nbytes + self.bricks.nbytes

    def max(self) -> float:
        return float(self._per_brick(np.max).max()) if len(self.bricks) else 0.0

    def min(self) -> float:
        """Least voxel value (0 when some brick is empty)."""
        lowest = float(self._per_brick(np.min).min()) if len(self.bricks) else 0.0
        return min(lowest, 0.0) if (self.index < 0).any() else lowest

    def _per_brick(self, reduce) -> np.ndarray:
        """(B,) `reduce` over each brick's stored block (channels too)."""
        if self.bounds is not None and reduce in (np.min, np.max):
            return self.bounds[0 if reduce is np.min else 1]
        return reduce(self.bricks, axis=tuple(range(1, self.bricks.ndim)))

    def brick_reduce(self, reduce=np.max) -> np.ndarray:
        """(bz, by, bx) float64 `reduce` over each brick's stored 9^3 block (channels too);
        empty bricks give 0."""
        out = np.zeros(self.index.shape, np.float64)
        if len(self.bricks):
            out[self.index >= 0] = self._per_brick(reduce)[self.index[self.index >= 0]]
        return out

    def shell_max(self) -> float:
        """Largest value on the grid's six outer voxel layers (from the bricks on them)."""
        largest = 0.0
        for axis, n in enumerate(self.shape):
            for position in {0, n - 1}:
                ids = np.take(self.index, position // BRICK, axis=axis)
                ids = ids[ids >= 0]
                if ids.size:
                    layer = np.take(self.bricks[ids], position % BRICK, axis=axis + 1)
                    largest = max(largest, float(np.abs(layer).max()))
        return largest

    def map(self, function) -> SparseGrid:
        """The grid with `function` applied to every stored voxel (function(0) must be 0,
        which keeps brick 0 and the empty bricks zero), a chunk of bricks at a time."""
        storage = BrickStore(None)
        source = self.zero_led()
        for first in range(0, len(source), MAP_CHUNK):
            storage.add(np.asarray(function(source[first:first + MAP_CHUNK]), np.float32))
        return storage.grid(self.shape, self.index)

    def to_dense(self) -> np.ndarray:
        """The (nz, ny, nx[, 3]) array (for tests and small grids)."""
        nz, ny, nx = self.shape
        bz, by, bx = self.index.shape
        tail = self.bricks.shape[4:]
        out = np.zeros((bz * BRICK, by * BRICK, bx * BRICK) + tail, np.float32)
        for k, j, i in np.argwhere(self.index >= 0):
            block = self.bricks[self.index[k, j, i], :BRICK, :BRICK, :BRICK]
            out[k * BRICK:(k + 1) * BRICK, j * BRICK:(j + 1) * BRICK, i * BRICK:(i + 1) * BRICK] = block
        return out[:nz, :ny, :nx]


def brick_views(slab: np.ndarray) -> np.ndarray:
    """(by, bx, SPAN, SPAN, SPAN[, c]) view of the bricks of one brick row (no copy).

    `slab` is (SPAN, 8 by + 1, 8 bx + 1[, c]): the voxels of one z-row of bricks with the
    apron (the next row's first layer, and one voxel past the last brick in y and x)."""
    depth, height, width = slab.shape[:3]
    assert depth == SPAN and (height - 1) % BRICK == 0 and (width - 1) % BRICK == 0
    s = slab.strides
    shape = ((height - 1) // BRICK, (width - 1) // BRICK, SPAN, SPAN, SPAN) + slab.shape[3:]
    strides = (BRICK * s[1], BRICK * s[2], s[0], s[1], s[2]) + s[3:]
    return as_strided(slab, shape, strides, writeable=False)


MAP_CHUNK = 1024  # bricks per chunk of SparseGrid.map (3 MB of scalar bricks; its float64 temporaries)


class BrickStore:
    """A zero-led brick array under construction (see SparseGrid.zero_led), appended to a
    block of bricks at a time, and every brick's least and largest value. It stays in this
    process's memory until it passes mapped.MIN_BYTES, then goes to a mapped file."""

    def __init__(self, tail: tuple[int, ...] | None) -> None:
        """tail: () for scalar bricks, (c,) for c channels; None takes the first block's."""
        self.tail = tail
        self.parts: list[np.ndarray] = []
        self.lows: list[np.ndarray] = []
        self.highs: list[np.ndarray] = []
        self.held = 0
        self.writer: FileWriter | None = None
        if tail is not None:
            self.add(np.zeros((1, SPAN, SPAN, SPAN) + tail, np.float32))

    def add(self, blocks: np.ndarray) -> None:
        """Append (n, SPAN, SPAN, SPAN[, c]) float32 bricks (the first call: brick 0, all zero)."""
        blocks = np.ascontiguousarray(blocks, np.float32)
        if self.tail is None:
            self.tail = blocks.shape[4:]
        axes = tuple(range(1, blocks.ndim))
        self.lows.append(blocks.min(axis=axes) if len(blocks) else np.zeros(0, np.float32))
        self.highs.append(blocks.max(axis=axes) if len(blocks) else np.zeros(0, np.float32))
        if self.writer is None and self.held + blocks.nbytes >= MIN_BYTES:
            self.writer = FileWriter()
            for part in self.parts:
                self.writer.write(part)
            self.parts.clear()
        if self.writer is not None:
            self.writer.write(blocks)
        else:
            self.parts.append(blocks)
        self.held += blocks.nbytes

    def grid(self, shape: tuple[int, int, int], index: np.ndarray) -> SparseGrid:
        """The SparseGrid over these bricks (brick 0 excluded from its `bricks`)."""
        count = sum(len(low) for low in self.lows)
        full = (count, SPAN, SPAN, SPAN) + tuple(self.tail or ())
        if self.writer is not None:
            storage = self.writer.array(full)
        else:
            storage = np.concatenate(self.parts) if self.parts else np.zeros(full, np.float32)
        bounds = np.stack([np.concatenate(self.lows)[1:], np.concatenate(self.highs)[1:]]).astype(np.float32)
        self.parts, self.writer = [], None
        return SparseGrid.from_zero_led(shape, index, storage, bounds)


class BrickBuilder:
    """Builds SparseGrids that share one brick index, one z-row of bricks at a time, so a
    grid is never held dense: memory is one row's slab plus the occupied bricks.

    `channels` maps each grid name to 1 (scalar) or 3 (RGB). A brick is kept in every grid
    when any grid has a non-zero value in it (their voxels must line up for per-voxel
    material evaluation)."""

    def __init__(self, shape: tuple[int, int, int], channels: dict[str, int]) -> None:
        self.shape = tuple(int(n) for n in shape)
        self.channels = dict(channels)
        self.index = np.full(lattice_shape(self.shape), -1, np.int32)
        self.stores = {name: BrickStore(() if c == 1 else (c,)) for name, c in self.channels.items()}
        self.count = 0

    def slab_shape(self, name: str) -> tuple[int, ...]:
        """Shape of the slab add_row wants for grid `name`."""
        _, by, bx = self.index.shape
        tail = () if self.channels[name] == 1 else (self.channels[name],)
        return (SPAN, by * BRICK + 1, bx * BRICK + 1) + tail

    def add_row(self, bk: int, slabs: dict[str, np.ndarray]) -> None:
        """Keep the occupied bricks of brick row bk; slabs[name] has slab_shape(name) and
        holds voxels 8 bk .. 8 bk + 8 (z), 0 .. 8 by (y), 0 .. 8 bx (x), edge-clamped past
        the grid (any value there is never read)."""
        views = {name: brick_views(slab) for name, slab in slabs.items()}
        occupied = None
        for view in views.values():
            nonzero = np.any(view != 0.0, axis=tuple(range(2, view.ndim)))
            occupied = nonzero if occupied is None else occupied | nonzero
        where = np.nonzero(occupied)
        found = len(where[0])
        self.index[bk][where] = np.arange(self.count, self.count + found, dtype=np.int32)
        self.count += found
        for name, view in views.items():
            if found:
                self.stores[name].add(view[where])

    def finish(self) -> dict[str, SparseGrid]:
        """The grids, each in one zero-led array (SparseGrid.zero_led): a large one in a
        mapped file written row by row, so the grids are never held twice."""
        return {name: store.grid(self.shape, self.index) for name, store in self.stores.items()}


def dense_slab(values: np.ndarray, bk: int, slab_shape: tuple[int, ...]) -> np.ndarray:
    """Brick row bk's slab (see BrickBuilder.add_row) cut from a dense array, edge-clamped."""
    nz, ny, nx = values.shape[:3]
    z = np.minimum(np.arange(bk * BRICK, bk * BRICK + SPAN), nz - 1)
    y = np.minimum(np.arange(slab_shape[1]), ny - 1)
    x = np.minimum(np.arange(slab_shape[2]), nx - 1)
    return values[z][:, y][:, :, x]


def sparse_from_dense(grids: dict[str, np.ndarray]) -> dict[str, SparseGrid]:
    """Dense (nz, ny, nx[, 3]) arrays of one shape as SparseGrids sharing one brick index."""
    shape = next(iter(grids.values())).shape[:3]
    builder = BrickBuilder(shape, {n: 1 if v.ndim == 3 else v.shape[3] for n, v in grids.items()})
    for bk in range(builder.index.shape[0]):
        builder.add_row(bk, {n: dense_slab(v, bk, builder.slab_shape(n)) for n, v in grids.items()})
    return builder.finish()


def to_sparse(values: np.ndarray) -> SparseGrid:
    """One dense grid as a SparseGrid."""
    return sparse_from_dense({"grid": np.asarray(values, np.float32)})["grid"]
