"""Export helpers that need no Blender: stand-in datablocks and plain arrays."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from addon.display import ResultBuffer, render_region
from addon.export.camera import aperture_radius, contract_shift, field_of_view, film_size, projection_of
from addon.export.lights import area_outline, fan_triangles
from addon.export.materials import choose_emission, close_open_sides, convert_material
from addon.export.mesh import LocalGeometry, edge_problems, transform
from addon.export.messages import ExportError, Messages
from addon.export.node_closures import (
    F82_COS,
    Term,
    adjusted_specular_ior,
    conductor_as_f82,
    conductor_reflectance,
    merge_sides,
    scale_terms,
)
from addon.export.node_values import value_map_range, value_math
from renderer.scene import Lobe
from renderer.shading.math_arrays import math_array
from renderer.shading.math_ops import math_op
from renderer.shading.names import MATH_OPS

CUBE = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)


def test_material_without_node_tree_is_its_viewport_colour():
    old = SimpleNamespace(name_full="Old", node_tree=None, use_nodes=False,
                          diffuse_color=(0.3, 0.4, 0.5, 1.0))
    exported = convert_material(old, Messages())
    assert exported.medium is None
    assert [(lobe.kind, lobe.color) for lobe in exported.material.lobes] == [("diffuse", (0.3, 0.4, 0.5))]


def test_open_sides_get_black_opaque_lobes():
    front_only = [Lobe("diffuse", color=(1, 0, 0), sides="front")]
    assert [(lobe.color, lobe.sides) for lobe in close_open_sides(front_only)[1:]] == [((0, 0, 0), "back")]
    assert [lobe.sides for lobe in close_open_sides([])] == ["both"]
    assert close_open_sides([Lobe("transparent")]) == [Lobe("transparent")]


def test_emission_sides():
    messages = Messages()
    assert choose_emission(np.ones(3), np.zeros(3), "M", messages) == ((1, 1, 1), "front")
    assert choose_emission(np.zeros(3), np.ones(3), "M", messages) == ((1, 1, 1), "back")
    assert choose_emission(np.ones(3), np.ones(3), "M", messages) == ((1, 1, 1), "both")
    assert messages.warnings == []
    choose_emission(np.ones(3), 2 * np.ones(3), "M", messages)
    assert messages.warnings == [
        "M: emission differs between front and back faces; the front value is used on both"]


def test_side_dependent_factors_split_terms():
    terms = [Term("diffuse", np.ones(3))]
    split = scale_terms(terms, np.array([[0.25], [1.0]]))
    assert [(t.sides, float(t.weight[0])) for t in split] == [("front", 0.25), ("back", 1.0)]
    assert [t.sides for t in merge_sides(terms, terms)] == ["both"]
    assert scale_terms(terms, np.array([[0.0], [0.0]])) == []


def test_specular_ior_level_matches_cycles():
    assert adjusted_specular_ior(1.5, 0.5) == 1.5
    f0 = 2.0 * 0.8 * 0.04  # level 0.8 scales F0 = 0.04 by 1.6
    assert adjusted_specular_ior(1.5, 0.8) == pytest.approx((1 + math.sqrt(f0)) / (1 - math.sqrt(f0)))
    assert adjusted_specular_ior(1.5, 0.0) == 1.0


def test_physical_conductor_as_f82_curve():
    """Metallic BSDF, Physical Conductor: the F82-tint curve passes through the exact conductor
    Fresnel at normal incidence and at cos = 1/7; a dielectric (k = 0) gives Fresnel's F0."""
    assert conductor_reflectance(1.0, np.array([1.5]), np.array([0.0]))[0] == pytest.approx(0.04)
    assert conductor_reflectance(0.0, np.array([0.2]), np.array([3.0]))[0] == pytest.approx(1.0)
    n, k = np.array([0.27, 0.68, 1.32]), np.array([3.61, 2.63, 2.27])  # gold-like
    f0, tint = conductor_as_f82(n, k)
    np.testing.assert_allclose(f0, conductor_reflectance(1.0, n, k))
    c = F82_COS
    f82 = (f0 + (1 - f0) * (1 - c) ** 5) * tint
    np.testing.assert_allclose(f82, conductor_reflectance(c, n, k), rtol=1e-12)
    assert np.all((tint > 0.0) & (tint <= 1.0))


def test_safe_power_follows_cycles():
    bases, exponents = np.array([-8.0, -8.0, 4.0]), np.array([1.0 / 3.0, 3.0, 0.5])
    assert math_array(MATH_OPS.index("POWER"), bases, exponents, 0.0).tolist() == [0.0, -512.0, 2.0]


class ConstantInputs:
    """A value graph whose node inputs (sockets named by strings here) are given arrays."""

    def __init__(self, **values: np.ndarray) -> None:
        self.values = values

    def input_value(self, socket, scope: tuple = ()) -> np.ndarray:
        return self.values[socket]


def fold_math(name: str, a, b, c) -> np.ndarray:
    node = SimpleNamespace(operation=name, use_clamp=False, inputs=("a", "b", "c"))
    return value_math(ConstantInputs(a=a, b=b, c=c), node, None, ())


def test_math_nodes_fold_to_the_bits_the_kernels_compute():
    """Export-time folding runs the kernels' own math_op: every Math operation, on inputs of
    both signs and of every magnitude (past int64 too), folds to the float64 the kernel's
    scalar function gives (non-finite results folded to 0, as the exporter does)."""
    values = np.array([-1e20, -7.25, -2.5, -1.0, -0.3, -0.0, 0.0, 1e-8, 0.5, 1.0, 2.0, 3.0, 100.0, 1e20])
    a, b, c = (x.reshape(-1, 1) for x in np.meshgrid(values, values, [0.0, 0.25, 3.0], indexing="ij"))
    for op, name in enumerate(MATH_OPS):
        kernel = [math_op(op, x, y, z) for x, y, z in zip(a[:, 0], b[:, 0], c[:, 0], strict=True)]
        kernel = np.nan_to_num(kernel, nan=0.0, posinf=0.0, neginf=0.0)
        folded = fold_math(name, a, b, c)
        assert folded.shape == a.shape and folded[:, 0].tobytes() == kernel.tobytes(), name


def test_folded_nodes_follow_cycles_where_the_numpy_folding_did_not():
    """Cycles' semantics the exporter's own numpy maths missed: Compare within max(c,
    FLT_EPSILON), not 1e-5; Floor past int64; Ping-Pong, Wrap, Snap and Smooth Minimum folded,
    not passed through; a Map Range whose From range is empty gives 0, not To Min."""
    def fold(name: str, a: float, b: float = 0.0, c: float = 0.0) -> float:
        return float(fold_math(name, *(np.array([[x]]) for x in (a, b, c)))[0, 0])

    assert fold("COMPARE", 1.0, 1.0 + 5e-6) == 0.0 and fold("COMPARE", 1.0, 1.0 + 5e-8) == 1.0
    assert fold("FLOOR", 1e20) == 1e20 and fold("FLOOR", -2.5) == -3.0
    assert fold("PINGPONG", 2.5, 1.0) == 0.5 and fold("WRAP", 5.5, 2.0, 1.0) == 1.5
    assert fold("SNAP", 7.3, 2.0) == 6.0 and fold("SMOOTH_MIN", 1.0, 1.0, 1.0) == pytest.approx(5.0 / 6.0)
    node = SimpleNamespace(data_type="FLOAT", interpolation_type="LINEAR", clamp=True, inputs=tuple("vabcds"))
    inputs = {name: np.array([[x]]) for name, x in zip("vabcds", (0.5, 1.0, 1.0, 2.0, 3.0, 4.0), strict=True)}
    assert value_map_range(ConstantInputs(**inputs), node, None, ()).tolist() == [[0.0]]
    inputs["b"] = np.array([[3.0]])  # From 1 .. 3: 0.5 maps below To Min and clamps to it
    assert value_map_range(ConstantInputs(**inputs), node, None, ()).tolist() == [[2.0]]


def test_closed_and_open_meshes():
    assert edge_problems(CUBE) == (0, 0)
    assert edge_problems(CUBE[2:])[0] == 4  # one face removed: a square hole
    flipped = CUBE.copy()
    flipped[0] = flipped[0, ::-1]
    assert edge_problems(flipped)[1] > 0


def test_mirroring_transform_reverses_winding():
    geometry = LocalGeometry(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.int32), None,
                             np.zeros(1, np.int32), np.array([[0, 1, 2]], np.int32))
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    world = transform(geometry, mirror)
    assert world.triangles.tolist() == [[2, 1, 0]]
    assert world.vertices[0].tolist() == [-1.0, 0.0, 0.0]


def test_area_light_outlines_have_cycles_area_and_face_down():
    disk = SimpleNamespace(shape="ELLIPSE", size=2.0, size_y=1.0)
    points, area = area_outline(disk)
    assert area == pytest.approx(math.pi / 4 * 2.0)
    triangles = points[fan_triangles(len(points))]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert 0.5 * np.linalg.norm(normals, axis=1).sum() == pytest.approx(area)
    assert np.all(normals[:, 2] < 0)


def test_camera_fit_and_shift():
    camera = SimpleNamespace(sensor_fit="AUTO", sensor_width=36.0, sensor_height=24.0, lens=50.0,
                             shift_x=0.1, shift_y=0.2)
    assert field_of_view(camera, 100, 200) == (pytest.approx(math.degrees(2 * math.atan(18 / 50))), "y")
    camera.sensor_fit = "HORIZONTAL"
    assert field_of_view(camera, 100, 200)[1] == "x"
    assert contract_shift(camera, "x", 100, 200) == pytest.approx((0.05, 0.1))
    render = SimpleNamespace(resolution_x=1920, resolution_y=1080, resolution_percentage=50)
    assert film_size(render) == (960, 540)


def test_render_region_is_blenders_truncated_border_from_the_top():
    render = SimpleNamespace(use_border=True, border_min_x=0.3, border_max_x=0.8, border_min_y=0.15,
                             border_max_y=0.6)
    # x: 12..32 of 40; y from the bottom: 4..18 of 30, so rows 12..25 from the top.
    assert render_region(render, 40, 30) == (12, 12, 20, 14)
    assert render_region(SimpleNamespace(use_border=False), 40, 30) is None
    whole = SimpleNamespace(use_border=True, border_min_x=0.0, border_max_x=1.0, border_min_y=0.0,
                            border_max_y=1.0)
    assert render_region(whole, 40, 30) is None


def test_alpha_is_flipped_into_the_fourth_channel():
    buffer = ResultBuffer(2, 2)
    image = np.zeros((2, 2, 3), np.float32)
    buffer.fill(image)
    assert (buffer.rgba[..., 3] == 1.0).all()
    buffer.fill(image, np.array([[0.25, 0.5], [0.75, 1.0]], np.float32))
    assert buffer.rgba[..., 3].tolist() == [[0.75, 1.0], [0.25, 0.5]]  # Blender's rows go up


def test_aperture_radius_follows_cycles_sync():
    dof = SimpleNamespace(use_dof=True, aperture_fstop=2.0)
    lens = SimpleNamespace(dof=dof, lens=50.0)
    assert aperture_radius(lens, "perspective") == pytest.approx(0.05 / 4.0)
    assert aperture_radius(lens, "orthographic") == pytest.approx(0.25)
    pinhole = SimpleNamespace(dof=SimpleNamespace(use_dof=False), lens=50.0)
    assert aperture_radius(pinhole, "perspective") == 0.0


def test_unsupported_panorama_types_are_errors():
    assert projection_of(SimpleNamespace(type="PANO", panorama_type="MIRRORBALL"), "c") == "mirrorball"
    with pytest.raises(ExportError, match="equiangular cubemap face"):
        projection_of(SimpleNamespace(type="PANO", panorama_type="EQUIANGULAR_CUBEMAP_FACE"), "c")
