"""Films in tests: a complete render's film, and bit-for-bit comparison of two films."""

from __future__ import annotations

import dataclasses

import numpy as np

from renderer.film import Film
from renderer.render import render_progressive
from renderer.scene import Scene


def render_film(scene: Scene, workers: int = 1) -> Film:
    """The film of a complete progressive render (its sums, counts and passes)."""
    last = None
    for last in render_progressive(scene, workers=workers):  # noqa: B007
        pass
    assert last is not None
    return last.film


def film_fields(film: Film) -> list[str]:
    """The names of every field the film holds: its dataclass fields, or (a plain class) its
    instance attributes, so a field added to Film is compared without editing the tests."""
    if dataclasses.is_dataclass(film):
        return [field.name for field in dataclasses.fields(film)]
    return sorted(vars(film))


def assert_same_bits(a: Film, b: Film) -> None:
    """Every field of the two films equal: each array of the same dtype, shape and values
    (the sums, counts, odd-sample sums, alpha, non-finite count, passes), each scalar (size,
    first row) the same, and a field that is None in one None in the other."""
    names = film_fields(a)
    assert names == film_fields(b), "the films hold different fields"
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert isinstance(x, np.ndarray) and isinstance(y, np.ndarray), f"{name}: one is not an array"
            assert (x.dtype, x.shape) == (y.dtype, y.shape), f"{name}: {x.dtype}{x.shape}, {y.dtype}{y.shape}"
            assert np.array_equal(x, y), f"{name} differs"
        else:
            assert x == y, f"{name}: {x!r} != {y!r}"
