"""The checks every part of the scene validator shares (renderer.validate.scene,
renderer.validate.media): a choice among words, a non-negative colour, magnitudes and
coordinates the float32 kernels hold, directions, references by name, unique names and
invertible transforms. Each raises SceneError naming the field path it was given.
"""

from __future__ import annotations

from collections.abc import Collection

import numpy as np

from renderer.errors import SceneError
from renderer.validate.conform import require

# Relative singularity threshold, see is_singular.
_SINGULAR_TOLERANCE = 1e-12
# Limits that keep the float32 kernels finite. A float32 holds at most 3.4e38; a path value
# multiplies radiance by weights, coefficients and geometry terms (distances squared among
# them), so radiometric inputs and their products stay below MAX_MAGNITUDE and coordinates
# below MAX_COORDINATE, leaving about twenty orders of magnitude of headroom.
MAX_MAGNITUDE = 1e18
MAX_COORDINATE = 1e15
# A transform's columns scale by at most this factor either way; beyond it float32 loses all
# precision (or overflows) when the kernels apply it.
MAX_SCALE = 1e12
# Directions are normalised; below this length their square underflows float32.
MIN_DIRECTION_LENGTH = 1e-12


def check_choice(value: str, allowed: Collection[str], path: str, what: str) -> None:
    """`value` is one of `allowed` (a tuple of words or a dict keyed by them)."""
    expected = ", ".join(repr(a) for a in allowed)
    require(value in allowed, path, f"unknown {what} {value!r} (expected one of {expected})")


def check_nonnegative_rgb(rgb: tuple[float, ...], path: str) -> None:
    """A colour, coefficient or radiometric quantity: >= 0 and small enough for float32 paths."""
    require(min(rgb) >= 0.0, path, f"must not be negative, got {rgb}")
    check_magnitude(max(rgb), path)


def check_magnitude(value: float, path: str, what: str = "") -> None:
    """`value` (or the product `what` describes) is at most MAX_MAGNITUDE."""
    shown = f"{what} = {value:.3g}" if what else f"got {value:.3g}"
    limit = f"must be at most {MAX_MAGNITUDE:g} (float32 kernels overflow)"
    require(value <= MAX_MAGNITUDE, path, f"{limit}, {shown}")


def check_coordinates(values: np.ndarray | tuple[float, ...], path: str) -> None:
    largest = float(np.max(np.abs(values))) if np.size(values) else 0.0
    ok = largest <= MAX_COORDINATE
    require(ok, path, f"coordinates must be within +-{MAX_COORDINATE:g} (float32 kernels), got {largest:.3g}")


def check_direction(vector: tuple[float, ...], path: str) -> None:
    """A direction the kernels normalise: neither (nearly) zero nor so long its square overflows."""
    require(any(x != 0.0 for x in vector), path, "must be a non-zero vector")
    largest = max(abs(x) for x in vector)
    long_enough = largest >= MIN_DIRECTION_LENGTH
    problem = f"too short to normalise: length {largest:.3g} (at least {MIN_DIRECTION_LENGTH:g})"
    require(long_enough, path, problem)
    check_coordinates(vector, path)


def check_reference(name: str | None, known: set[str], path: str, what: str) -> None:
    require(name is None or name in known, path, f"unknown {what} {name!r}")


def check_unique_names(items: list, path: str) -> set[str]:
    """The names of `items`, which must be non-empty and unique."""
    first_index: dict[str, int] = {}
    for i, item in enumerate(items):
        require(item.name != "", f"{path}[{i}].name", "must not be empty")
        if item.name in first_index:
            also = f"{path}[{first_index[item.name]}]"
            raise SceneError(f"{path}[{i}].name", f"duplicate name {item.name!r} (also {also})")
        first_index[item.name] = i
    return set(first_index)


def is_singular(linear: np.ndarray) -> bool:
    """Whether a 3x3 matrix is singular relative to its scale: |det| <= tol * prod(column norms).

    Columns are first divided by their largest entry, so huge or tiny scales neither
    overflow nor count as singular; a column that overflowed to inf does.
    """
    largest = np.abs(linear).max(axis=0)
    if not np.all(largest > 0.0) or not np.all(np.isfinite(largest)):
        return True
    scaled = linear / largest
    return abs(np.linalg.det(scaled)) <= _SINGULAR_TOLERANCE * np.prod(np.linalg.norm(scaled, axis=0))


def check_transform(matrix: np.ndarray, path: str, check_range: bool = True) -> None:
    """An invertible affine 4x4 transform (the kernels use only its top three rows).

    `check_range=False` leaves the scale check to a caller that checks the transform's
    product with another scale (a grid medium's box).
    """
    affine = np.allclose(matrix[3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-9)
    require(affine, path, f"last row must be (0, 0, 0, 1), got {tuple(matrix[3].tolist())}")
    require(not is_singular(matrix[:3, :3]), path, "singular matrix")
    if check_range:
        check_transform_range(matrix, path)


def check_transform_range(matrix: np.ndarray, path: str) -> None:
    """Scale and translation the float32 kernels can apply without overflow or losing all precision."""
    scales = np.abs(matrix[:3, :3]).max(axis=0)  # the largest entry of each column
    for axis, scale in zip("xyz", scales):
        ok = 1.0 / MAX_SCALE <= scale <= MAX_SCALE
        bounds = f"[{1 / MAX_SCALE:g}, {MAX_SCALE:g}]"
        require(ok, path, f"scales the {axis} axis by {scale:.3g}; must be within {bounds}")
    check_coordinates(matrix[:3, 3], path)
