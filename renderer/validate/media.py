"""The medium part of the scene validator (renderer.validate): a medium's type and
coefficients, its grids (dense or sparse bricks), its box and transform, and the products
of its values that the kernels form, all within what float32 holds.
"""

from __future__ import annotations

import numpy as np

from renderer.scene import MEDIUM_TYPES, Medium
from renderer.validate.checks import (
    check_choice,
    check_coordinates,
    check_magnitude,
    check_nonnegative_rgb,
    check_transform,
    check_transform_range,
    is_singular,
)
from renderer.validate.conform import conform_object, require
from renderer.validate.program import check_medium_program

GRID_ARRAYS = ("density", "flame", "temperature")
# Stefan-Boltzmann radiance scaled as Cycles does (renderer/media/blackbody.py): times T^4.
_BLACKBODY_FACTOR = 5.670373e-8 / np.pi * 1e-6


def validate_medium(medium: Medium, path: str) -> None:
    """Conform and check one medium as validate_scene does (names and references aside).

    renderer.media.compile calls it for every medium it flattens, so a scene compiled without
    validate_scene still never hands the kernels a bad grid or transform.
    """
    conform_object(medium, (Medium,), path)
    check_medium(medium, path)


def check_medium(medium: Medium, path: str) -> None:
    check_choice(medium.type, MEDIUM_TYPES, f"{path}.type", "medium type")
    for name in ("sigma_a", "sigma_s", "emission"):
        check_nonnegative_rgb(getattr(medium, name), f"{path}.{name}")
    require(medium.scale >= 0.0, f"{path}.scale", f"must be >= 0, got {medium.scale}")
    check_magnitude(medium.scale, f"{path}.scale")
    require(abs(medium.g) < 1.0, f"{path}.g", f"must satisfy |g| < 1, got {medium.g}")
    bb = medium.blackbody_intensity
    require(bb >= 0.0, f"{path}.blackbody_intensity", f"must be >= 0, got {bb}")
    check_magnitude(bb, f"{path}.blackbody_intensity")
    if medium.type == "homogeneous":
        for name in GRID_ARRAYS:
            carries = getattr(medium, name) is not None
            require(
                not carries, f"{path}.{name}", "only grid media take grid arrays (type is 'homogeneous')"
            )
        require(medium.program is None, f"{path}.program",
                "only grid media take a program (type is 'homogeneous')")
        _check_medium_products(medium, path, 1.0, 1.0, 0.0)
        return
    procedural = medium.program is not None
    require(medium.density is not None or procedural, f"{path}.density",
            "required for grid media (or a program, for a procedural density)")
    require(not (procedural and medium.density is not None), f"{path}.program",
            "a grid medium takes a density grid or a program, not both")
    if procedural:
        require(medium.flame is None and medium.temperature is None, f"{path}.program",
                "a procedural medium takes no flame or temperature grid")
        check_medium_program(medium.program, medium.program_density, path)
    for name in GRID_ARRAYS:
        if getattr(medium, name) is not None:
            _check_grid_array(getattr(medium, name), f"{path}.{name}")
    check_coordinates(medium.p0, f"{path}.p0")
    check_coordinates(medium.p1, f"{path}.p1")
    _check_grid_box(medium, path)
    flame = _grid_max(medium.flame, 1.0)
    hottest = _grid_max(medium.temperature, 0.0)
    # (a procedural density's bound is checked where it is built: renderer.media.procedural)
    _check_medium_products(medium, path, _grid_max(medium.density, 0.0), flame, hottest)


def _grid_max(grid: np.ndarray | None, default: float) -> float:
    return float(grid.max()) if grid is not None else default


def _check_medium_products(
    medium: Medium, path: str, density: float, flame: float, temperature: float
) -> None:
    """The products the kernels form from a medium's values stay below MAX_MAGNITUDE.

    Each factor may be fine alone while their product overflows float32, e.g. sigma_s 1e18
    times a density of 1e30. Python floats (float64) hold every product checked here.
    """
    extinction = max(a + s for a, s in zip(medium.sigma_a, medium.sigma_s)) * medium.scale * density
    check_magnitude(extinction, f"{path}.scale", "(sigma_a + sigma_s) * scale * max density")
    emission = max(medium.emission) * max(density, 1.0) * flame
    check_magnitude(emission, f"{path}.emission", "emission * max density * max flame")
    blackbody = _BLACKBODY_FACTOR * medium.blackbody_intensity * temperature**4 * max(density, 1.0)
    check_magnitude(blackbody, f"{path}.temperature", "blackbody radiance * max density")


def _check_grid_array(grid, path: str) -> None:
    from renderer.media.bricks import SparseGrid  # lazily: renderer.media imports this module

    if isinstance(grid, SparseGrid):
        _check_sparse_grid(grid, path)
        return
    require(grid.ndim == 3, path, f"must be 3-D (nz, ny, nx), got shape {grid.shape}")
    require(grid.size > 0, path, f"must not be empty, got shape {grid.shape}")
    require(bool((grid >= 0.0).all()), path, f"must not be negative, got minimum {float(grid.min())}")


def _check_sparse_grid(grid, path: str) -> None:
    """A SparseGrid (renderer.media.bricks) whose index and bricks agree."""
    from renderer.media.bricks import SPAN, lattice_shape

    require(len(grid.shape) == 3 and min(grid.shape) > 0, path, f"must have a 3-D shape, got {grid.shape}")
    require(grid.index.shape == lattice_shape(grid.shape) and grid.index.dtype == np.int32, path,
            f"brick index must be int32 of shape {lattice_shape(grid.shape)}, got {grid.index.dtype} "
            f"{grid.index.shape}")
    require(grid.bricks.ndim == 4 and grid.bricks.shape[1:] == (SPAN, SPAN, SPAN), path,
            f"bricks must be (B, {SPAN}, {SPAN}, {SPAN}), got {grid.bricks.shape}")
    used = grid.index[grid.index >= 0]
    require(bool(used.size == 0 or used.max() < len(grid.bricks)) and bool((grid.index >= -1).all()), path,
            f"brick index refers to bricks outside 0..{len(grid.bricks) - 1}")
    require(bool(np.isfinite(grid.bricks).all()), path, "must be finite")
    require(grid.min() >= 0.0, path, f"must not be negative, got minimum {grid.min()}")


def _check_grid_box(medium: Medium, path: str) -> None:
    for axis, low, high in zip("xyz", medium.p0, medium.p1):
        require(low != high, f"{path}.p1", f"equals p0 on the {axis} axis ({high}): the grid box is flat")
    check_transform(medium.to_world, f"{path}.to_world", check_range=False)
    with np.errstate(over="ignore"):  # an overflowing box is caught as singular just below
        box_to_world = medium.to_world[:3, :3] @ np.diag(np.subtract(medium.p1, medium.p0))
    require(not is_singular(box_to_world), f"{path}.to_world", "singular matrix (combined with p0..p1)")
    # The kernels map the unit cube to the world by this product, so its scale is what must fit.
    combined = medium.to_world.copy()
    combined[:3, :3] = box_to_world
    check_transform_range(combined, f"{path}.to_world")
