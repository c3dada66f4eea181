"""Helpers for tests that render through renderer.render (no bpy)."""

from __future__ import annotations

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
