"""Volumes authored in Blender without a Volume object, through bpy, exported by the add-on.

* The usual procedural cloud (Texture Coordinate Object -> Noise -> Map Range -> Principled
  Volume Density, inside a rotated, scaled cube, under a sun) exports as a procedural
  medium (renderer.media.procedural).
* A mesh object whose geometry nodes output a volume (Volume Cube with a Noise density, Set
  Material to a Principled Volume) exports its grid (it used to be skipped).

Both export as they should (quick, no kernel compiles), and both render as Cycles renders
them (slow): RUNS renders with independent seeds per renderer in one Blender process,
compared by image means and block z-scores from the renders' own variance
(bench.comparison.compare_images). `python -m bench procedural_volume_cycles` prints the same
comparison (bench/procedural_volume_cycles.py holds both scenes' Blender script).
The renders became affordable when the trackers started calling the shader interpreter
through its address (renderer.kernels.native_call): before, a procedural medium's first
render spent over 15 CPU minutes compiling the interpreter again inside each tracker."""

from __future__ import annotations

import numpy as np
import pytest

from bench.comparison import assert_agree, compare_images
from bench.procedural_volume_cycles import RUNS, SIZE, scene_body
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy]

# Both scenes exported, not rendered (no kernel compiles: quick).
exported = blender_fixture(scene_body, "exported", timeout=600, compiles=False)


def test_cloud_exports_as_a_procedural_medium(exported):
    assert [(t, p) for _, t, p in exported["media"]] == [("grid", True)], exported["media"]
    assert not exported["warnings"], exported["warnings"]


def test_volume_cube_modifier_exports_its_grid(exported):
    case = exported["volume_cube"]
    assert [(t, p) for _, t, p in case["media"]] == [("grid", False)], case["media"]
    assert not case["warnings"], case["warnings"]


# Both scenes rendered RUNS times by Cycles and by Haze (one Blender process).
rendered = blender_fixture(scene_body, "rendered", timeout=2400, env={"HAZE_TEST_RENDER": "1"})


def _assert_renders_agree(case: dict) -> None:
    haze = np.stack([read_exr(p) for p in case["renders"]["haze"]])
    cycles = np.stack([read_exr(p) for p in case["renders"]["cycles"]])
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    assert np.isfinite(haze).all()
    assert_agree(compare_images(haze, cycles))


@pytest.mark.slow
def test_procedural_cloud_agrees_with_cycles(rendered):
    _assert_renders_agree(rendered)


@pytest.mark.slow
def test_volume_cube_agrees_with_cycles(rendered):
    _assert_renders_agree(rendered["volume_cube"])
