"""Sparse (bricked) grids read exactly what the dense grid holds, across brick borders."""

import copy

import numpy as np
import pytest
from numba import njit

from examples.media_scenes import smoke_ball
from renderer.errors import SceneError
from renderer.media import compile_media
from renderer.media.bricks import BRICK, SparseGrid, sparse_from_dense, to_sparse
from renderer.media.grid import grid_lookup, grid_lookup3
from renderer.media.layout import GRID_BLACKBODY, GRID_DENSITY, I_MAJ_DIMS, I_MAJ_OFFSET
from renderer.render import render_progressive
from renderer.scene import Medium
from renderer.scenefile import load_scene, save_scene


def _blobby(shape, seed):
    """Mostly empty grid: a few dense blobs, so that many bricks are empty and many stencils
    straddle an occupied and an empty brick."""
    rng = np.random.default_rng(seed)
    values = rng.uniform(0.0, 2.0, shape).astype(np.float32)
    keep = np.zeros(shape, bool)
    for _ in range(3):
        c = [rng.integers(0, n) for n in shape]
        r = 4
        keep[max(0, c[0] - r):c[0] + r, max(0, c[1] - r):c[1] + r, max(0, c[2] - r):c[2] + r] = True
    return np.where(keep, values, np.float32(0.0))


def _medium(density, **kw):
    return Medium("grid", type="grid", sigma_a=(1, 1, 1), sigma_s=(1, 1, 1), density=density, **kw)


def _border_points(shape, rng, n):
    """Unit-cube points whose stencils straddle brick borders (voxel coordinate 7..8 on some
    axis, lower voxel 7 of a brick, upper voxel 0 of the next), plus the box's own edges."""
    nz, ny, nx = shape
    pts = rng.random((n, 3))
    for a, size in enumerate((nx, ny, nz)):
        pick = rng.random(n) < 0.6
        brick = rng.integers(0, max(1, size // BRICK), n)
        f = brick * BRICK + 7.0 + rng.random(n)  # between voxel 8b + 7 and 8b + 8
        pts[pick, a] = np.clip((f[pick] + 0.5) / size, 0.0, 1.0)
    pts[:8] = [(x, y, z) for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
    return pts


@njit(cache=True)
def _lookups(mt, m, which, pts):
    out = np.empty(len(pts))
    for i in range(len(pts)):
        out[i] = grid_lookup(mt, m, which, (pts[i, 0], pts[i, 1], pts[i, 2]))
    return out


@njit(cache=True)
def _lookups3(mt, m, which, pts):
    out = np.empty((len(pts), 3))
    for i in range(len(pts)):
        v = grid_lookup3(mt, m, which, (pts[i, 0], pts[i, 1], pts[i, 2]))
        out[i, 0], out[i, 1], out[i, 2] = v
    return out


@pytest.mark.parametrize("shape", [(19, 13, 27), (16, 8, 24), (1, 9, 3)])
def test_sparse_lookup_is_bit_identical_to_dense(shape):
    """Kernel level: at random points and at points whose stencil crosses a brick border
    (x, y or z between voxels 8b + 7 and 8b + 8), the sparse lookup gives exactly the
    dense lookup's value (same voxels, same arithmetic)."""
    density = _blobby(shape, 3)
    sparse = to_sparse(density)
    np.testing.assert_array_equal(sparse.to_dense(), density)
    bricks = int(np.prod(sparse.index.shape))
    assert 0 < len(sparse.bricks) <= bricks
    mt = compile_media([_medium(density), _medium(sparse)])
    pts = _border_points(shape, np.random.default_rng(7), 20_000)
    dense_values, sparse_values = _lookups(mt, 0, GRID_DENSITY, pts), _lookups(mt, 1, GRID_DENSITY, pts)
    np.testing.assert_array_equal(sparse_values, dense_values)
    assert np.count_nonzero(dense_values) > 100  # the points do see the blobs


def test_sparse_temperature_gives_the_dense_blackbody_emission():
    """A sparse temperature grid is stored as sparse RGB blackbody emission (3 channels per
    voxel) and reads the same as the dense one."""
    shape = (12, 17, 10)
    density = _blobby(shape, 5)
    temperature = np.where(density > 0.0, 1500.0 + 500.0 * density, 0.0).astype(np.float32)
    grids = sparse_from_dense({"density": density, "temperature": temperature})
    assert grids["density"].index is grids["temperature"].index  # one brick index for both
    kw = dict(blackbody_intensity=1.0)
    mt = compile_media([_medium(density, temperature=temperature, **kw),
                        _medium(grids["density"], temperature=grids["temperature"], **kw)])
    pts = _border_points(shape, np.random.default_rng(2), 5000)
    dense, sparse = _lookups3(mt, 0, GRID_BLACKBODY, pts), _lookups3(mt, 1, GRID_BLACKBODY, pts)
    np.testing.assert_array_equal(sparse, dense)
    assert np.count_nonzero(dense) > 100


@njit(cache=True)
def _worst_violation(mt, m, pts):
    """max over points of density - (majorant of the point's cell), and the fraction of
    points in cells whose majorant is 0."""
    cx, cy, cz = mt.index[m, I_MAJ_DIMS], mt.index[m, I_MAJ_DIMS + 1], mt.index[m, I_MAJ_DIMS + 2]
    worst, empty = -np.inf, 0
    for p in range(len(pts)):
        u = (pts[p, 0], pts[p, 1], pts[p, 2])
        i, j, k = min(int(u[0] * cx), cx - 1), min(int(u[1] * cy), cy - 1), min(int(u[2] * cz), cz - 1)
        maj = mt.maj_data[mt.index[m, I_MAJ_OFFSET] + (k * cy + j) * cx + i, 0]
        worst = max(worst, grid_lookup(mt, m, 0, u) - maj)
        empty += maj == 0.0
    return worst, empty / len(pts)


def test_sparse_majorant_bounds_and_skips_empty_bricks():
    """Per-brick majorants bound the trilinear density everywhere, and empty bricks get
    majorant 0 (the DDA merges them, so they cost no lookups)."""
    shape = (40, 33, 70)
    density = _blobby(shape, 9) ** 4
    mt = compile_media([_medium(to_sparse(density))])
    cells = mt.index[0, I_MAJ_DIMS:I_MAJ_DIMS + 3]
    assert list(cells) == [-(-n // BRICK) for n in shape[::-1]]
    worst, empty = _worst_violation(mt, 0, _border_points(shape, np.random.default_rng(1), 100_000))
    assert worst <= 0.0
    assert empty > 0.5  # most of this grid is empty space


def test_compiled_media_share_the_sparse_grids_bricks():
    """A built sparse grid is compiled without a copy: grid_data views its zero-led brick
    array (a 512^3 cloud's bricks are 100s of MB), and that array's brick 0 is zero."""
    grid = to_sparse(_blobby((20, 17, 30), 4))
    assert not grid.zero_led()[0].any()
    mt = compile_media([_medium(grid)])
    assert np.shares_memory(mt.grid_data, grid.bricks)
    assert np.array_equal(mt.grid_data, grid.zero_led().ravel())


def test_a_bad_sparse_grid_is_refused_by_name():
    good = to_sparse(_blobby((9, 9, 9), 1))
    bad = SparseGrid(good.shape, good.index, -good.bricks)
    with pytest.raises(SceneError, match=r"media\[0\]\.density.*negative"):
        compile_media([_medium(bad)])
    wrong = SparseGrid(good.shape, good.index[:1], good.bricks)
    with pytest.raises(SceneError, match=r"media\[0\]\.density.*brick index"):
        compile_media([_medium(wrong)])


# ------------------------------------------------------------------------------ images


def _render(scene):
    last = None
    for last in render_progressive(scene, workers=1):  # noqa: B007
        pass
    return last.film


def _sparse_copy(scene):
    """The scene with its grid media's density stored as bricks."""
    scene = copy.deepcopy(scene)
    for medium in scene.media:
        if medium.type == "grid":
            medium.density = to_sparse(medium.density)
    return scene


def test_sparse_smoke_ball_renders_the_dense_image():
    """Same scene, density dense or sparse. With one majorant for the whole grid (equal for
    both: the grid's maximum) every path draws the same numbers and reads the same
    densities, so the images are bit-identical. With the majorant grid the sparse grid's
    per-brick cells differ from the dense grid's 4-voxel cells, so only the estimates
    agree: within Z standard errors of their difference, per channel and 2x2 block."""
    scene = smoke_ball(16, 8)
    scene.integrator.majorant_grid = False
    np.testing.assert_array_equal(_render(_sparse_copy(scene)).mean(), _render(scene).mean())
    scene = smoke_ball(16, 16)
    dense, sparse = _render(scene), _render(_sparse_copy(scene))
    for blocks in (1, 2):
        means, ses = [], []
        for film in (dense, sparse):
            h = film.height // blocks
            m = film.mean().reshape(blocks, h, blocks, h, 3)
            v = film.variance_of_mean().reshape(blocks, h, blocks, h, 3)
            means.append(m.mean(axis=(1, 3)))
            ses.append(np.sqrt(v.sum(axis=(1, 3))) / (h * h))
        se = np.hypot(ses[0], ses[1])
        assert np.all(np.abs(means[0] - means[1]) <= 5.0 * se + 1e-5 * np.abs(means[0])), (means, se)
    assert not np.array_equal(dense.mean(), sparse.mean())  # a different estimator indeed


def test_scene_folder_writes_a_sparse_grid_dense(tmp_path):
    """The scene folder format holds dense grids: a sparse one is written out in full and
    reads back as the same voxels."""
    scene = smoke_ball(8, 1)
    medium = next(m for m in scene.media if m.type == "grid")
    dense = medium.density.copy()
    medium.density = to_sparse(dense)
    save_scene(scene, tmp_path)
    loaded = next(m for m in load_scene(tmp_path).media if m.type == "grid")
    np.testing.assert_array_equal(loaded.density, dense)
