"""Issue 37, item 1: every index a kernel reads a shader program with is checked at load.

The cases the issue found (a code entry of 10^8, a binding width of 10^6, negative
registers, unknown opcodes, 9-column and 1-D code, an image index past the images, an
attribute with values for 3 of 12 triangles, an empty register file) are each refused with
one SceneError naming the field; a valid program passes; the validator's tables agree with
the kernels' vocabularies; integrator numbers that reach the kernels are range-checked.
All in-process, no rendering (tests/test_scene_fuzz.py renders mutants).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from bench.scene_fuzz import base_scene, textured_program
from renderer.errors import SceneError
from renderer.scene import CornerAttribute, Medium
from renderer.shading import bump, fractal, patterns, voronoi_cells
from renderer.shading.program import BIND, INSTR, OP, OPCODES
from renderer.validate import program as pv
from renderer.validate import validate_scene


def _refused(edit) -> str:
    """The message validate_scene gives base_scene() after `edit(scene)`."""
    scene = base_scene()
    edit(scene)
    with pytest.raises(SceneError) as caught:
        validate_scene(scene)
    message = str(caught.value)
    assert "\n" not in message
    return message


def _code(scene):
    return scene.materials[0].program.code


def _set_code(row: int, field: str, value: int):
    def edit(scene):
        _code(scene)[row, INSTR.offset(field)] = value
    return edit


def test_the_base_program_is_valid() -> None:
    validate_scene(base_scene())


def test_every_opcode_has_its_operands_declared() -> None:
    assert set(pv.OPERANDS) == set(OPCODES)
    assert set(pv.PARAMETERS) <= set(OPCODES)


def test_the_validators_vocabularies_match_the_kernels() -> None:
    assert pv.NOISE_TYPE_COUNT == len(fractal.TYPES)
    assert pv.VORONOI_FEATURE_COUNT == len(voronoi_cells.FEATURES)
    assert pv.WAVE_TYPE_COUNT == len(patterns.WAVE_TYPES)
    assert pv.WAVE_DIRECTION_COUNT == len(patterns.RINGS_DIRECTIONS) == len(patterns.BANDS_DIRECTIONS)
    assert pv.WAVE_PROFILE_COUNT == len(patterns.WAVE_PROFILES)
    assert pv.CORNER_POSITION == bump.CORNER_POSITION


@pytest.mark.parametrize(("row", "field", "value", "where"), [
    (1, "a", 10**8, "code[1].a"),  # checker's vector far past the registers
    (1, "dst", 50, "code[1].dst"),  # four registers from 50 overrun the 52
    (3, "b", -1, "code[3].b"),  # a negative register
    (5, "b", 45, "code[5].b"),  # noise's eight parameters from 45 overrun
    (0, "op", 999, "code[0].op"),
    (0, "op", -1, "code[0].op"),
    (5, "i0", 7, "code[5].i0"),  # a 7-D noise: kernels index offset tables by dimension
    (3, "i0", len(pv.MATH_OPS), "code[3].i0"),
    (2, "i0", 1, "code[2].i0"),  # image 1 of one image
    (4, "i0", 1, "code[4].i0"),  # the ramp's table would overrun the data
    (0, "i0", 2, "code[0].i0"),  # attribute 2 of two
    (9, "i1", 0, "code[9].i1"),  # bump must read the corner positions, not the UVs
])
def test_out_of_range_code_entries_are_refused_by_field(row: int, field: str, value: int, where: str) -> None:
    message = _refused(_set_code(row, field, value))
    assert message.startswith(f"materials[0].program.{where}:"), message


@pytest.mark.parametrize(("row", "field", "value"), [
    (0, "width", 10**6), (0, "reg", 50), (0, "lobe", 2), (1, "lobe", -1), (0, "field", 7), (0, "mode", 2),
    (3, "reg", 50),  # the normal binding reads three registers
])
def test_out_of_range_bindings_are_refused_by_field(row: int, field: str, value: int) -> None:
    def edit(scene):
        scene.materials[0].program.bindings[row, BIND.offset(field)] = value
    message = _refused(edit)
    assert message.startswith(f"materials[0].program.bindings[{row}].{field}:"), message


@pytest.mark.parametrize("shape", [(-1, 9), (-1,), (1, -1)])
def test_code_of_the_wrong_shape_is_refused(shape: tuple) -> None:
    def edit(scene):
        code = _code(scene).reshape(-1)
        code = code[: code.size - code.size % 9] if shape == (-1, 9) else code[:-1]
        scene.materials[0].program.code = code.reshape(shape)
    assert _refused(edit).startswith("materials[0].program.code:")


def test_flattened_bindings_are_refused_and_empty_tables_pass() -> None:
    """The table builders count bindings by len(): a flat array's would be five times its rows
    (the fuzzer's first find, a SIGSEGV in the stage)."""
    def flat(scene):
        scene.materials[0].program.bindings = scene.materials[0].program.bindings.reshape(-1)
    assert _refused(flat).startswith("materials[0].program.bindings:")
    scene = base_scene()
    scene.materials[0].program.code = np.zeros(0, np.int32)
    scene.materials[0].program.bindings = np.zeros(0, np.int32)
    validate_scene(scene)


def test_an_empty_register_file_is_refused_where_an_instruction_reads_it() -> None:
    def edit(scene):
        scene.materials[0].program.registers = np.zeros(0, np.float32)
    assert _refused(edit).startswith("materials[0].program.code[0].dst:")


def test_an_attribute_for_too_few_triangles_is_refused() -> None:
    def edit(scene):
        mesh = scene.meshes[0]
        mesh.attributes = [CornerAttribute("uv:UVMap", mesh.attributes[0].values[:1])]
    assert _refused(edit).startswith("meshes[0].attributes[0].values:")


def test_an_image_of_the_wrong_shape_or_name_is_refused() -> None:
    def rgb(scene):
        scene.images[0].pixels = np.ascontiguousarray(scene.images[0].pixels[:, :, :3])

    def renamed(scene):
        scene.images[0].name = "other"
    assert _refused(rgb).startswith("images[0].pixels:")
    assert "not in the scene's images" in _refused(renamed)


def test_compile_scene_checks_programs_of_an_unvalidated_scene() -> None:
    from renderer.compile import compile_scene

    scene = base_scene()
    _code(scene)[1, INSTR.offset("a")] = 10**8
    with pytest.raises(SceneError, match=r"code\[1\]\.a"):
        compile_scene(scene)


def _procedural_medium(program) -> Medium:
    return Medium("fog", "grid", sigma_s=(1.0, 1.0, 1.0), program=program, program_density=0)


def _density_program():
    program = copy.deepcopy(textured_program())
    program.code = np.array([[OP["position"], 0, 0, 0, 0, 0, 0, 0, 0, 0]], np.int32)
    return program


def test_a_medium_program_may_not_read_a_surface() -> None:
    pv.check_medium_program(_density_program(), 0, "media[0]")
    surface = _density_program()
    surface.code = np.array([[OP["bump_eval"], 0, 0, 0, 0, 0, 0, 1, 1, 0]], np.int32)
    with pytest.raises(SceneError, match=r"media\[0\]\.program\.code\[0\]\.op: operation 'bump_eval'"):
        pv.check_medium_program(surface, 0, "media[0]")
    with pytest.raises(SceneError, match=r"media\[0\]\.program_density"):
        pv.check_medium_program(_density_program(), 52, "media[0]")


@pytest.mark.parametrize(("field", "value"), [
    ("seed", 2**64), ("max_bounces", 2**62), ("max_bounces", 1025), ("spp", 2**40),
    ("rr_depth", 2**63),
])
def test_integrator_numbers_the_kernels_hold_are_range_checked(field: str, value: int) -> None:
    def edit(scene):
        setattr(scene.integrator, field, value)
    assert _refused(edit).startswith(f"integrator.{field}:")


EXPORT_MAIN = r'''

def main():
    """Every bake case's program as the exporter builds it, through the validator."""
    H.enable_addon()
    scene, obj = plane()
    report = {}
    for name in CASES:
        try:
            _, material, emission = bake(obj, name)
            haze_values(obj, material, emission, np.zeros((1, 2)))
            report[name] = "valid"
        except Exception as error:  # reported per case
            report[name] = repr(error)
    return report
'''
NO_BAKE = '    bpy.ops.object.bake(type="EMIT", margin=0, use_clear=True)\n'
EVALUATE = "    return evaluate_program(tables, 0, reg.index, 3, np.zeros(len(u), np.int32), bary, x, n)\n"
VALIDATE = ("    from renderer.validate.program import check_corner_attributes, check_program\n"
            "    check_program(program, 'program', {image.name for image in images.list()}, 1)\n"
            "    check_corner_attributes(mesh, 1, 'mesh')\n")


@pytest.mark.bpy
@pytest.mark.slow
def test_every_exported_bake_case_program_is_valid(tmp_path) -> None:
    """The exporter's programs (every node case tests/test_shader_programs.py bakes against
    Cycles) pass the validator: it refuses no program Blender makes."""
    import test_shader_programs as bakes

    from bench.blender import run_blender, shared_numba_cache

    assert NO_BAKE in bakes.BAKE_BODY and EVALUATE in bakes.BAKE_BODY
    body = bakes.BAKE_BODY.replace(NO_BAKE, "").replace(EVALUATE, VALIDATE)
    body = body.replace("for name in CASES:", f"for name in {bakes.CASES!r}:") + EXPORT_MAIN
    body = body.replace("for name in CASES:", f"for name in {bakes.CASES!r}:")
    run = run_blender(body, tmp_path, timeout=1800, numba_cache=shared_numba_cache())
    assert run.returncode == 0 and run.result, run.describe()
    invalid = {name: outcome for name, outcome in run.result.items() if outcome != "valid"}
    assert not invalid and len(run.result) == len(bakes.CASES), invalid


def test_the_largest_seed_renders_and_seeds_keep_their_64_bits() -> None:
    """A seed of 2**64 - 1 renders (it was a typing error in the kernels); the kernels get the
    int64 with its bits, so seeds below 2**63 pass unchanged."""
    from bench.scene_fuzz import render_finite
    from renderer.units import kernel_seed

    assert kernel_seed(2**64 - 1) == -1 and kernel_seed(2**63) == -(2**63) and kernel_seed(12345) == 12345
    scene = base_scene()
    scene.integrator.seed = 2**64 - 1
    validate_scene(scene)
    assert render_finite(scene)
