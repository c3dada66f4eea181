"""Procedural media (renderer.media.procedural): a shader program gives the density, the
majorant is the program's interval bound per cell (renderer.shading.intervals).

The estimators stay unbiased if no density the program produces exceeds its cell's
majorant: checked here, on the density the trackers get (shading.evaluate's entry, which
the suite compiles for surface programs anyway, so these tests compile nothing of their
own). That the trackers then match exp(-sigma_t * integral of the density) is checked by
`python -m bench procedural_tracking` (ratio and delta tracking against a quadrature of the
same program; bench/procedural_tracking.py holds the cloud): it compiles the trackers for
the procedural table type, about 5 min of CPU on a cold cache, beyond the suite's budget."""

from __future__ import annotations

import numpy as np
import pytest

from bench.procedural_tracking import cloud_program, procedural
from renderer.errors import SceneError
from renderer.media import compile_media
from renderer.media.layout import MediaTable, ProceduralMediaTable
from renderer.media.procedural import bound_violations
from renderer.scene import Medium
from renderer.shading.names import MATH_OPS
from renderer.shading.program import INSTR, OP, ShaderProgram


def _row(op: str, dst: int, a: int = 0, b: int = 0, c: int = 0, d: int = 0, i0: int = 0,
         i1: int = 0, i2: int = 0) -> list[int]:
    row = [0] * INSTR.size
    row[:10] = [OP[op], dst, a, b, c, d, 0, i0, i1, i2]
    return row


def test_only_scenes_with_programs_get_the_procedural_table_type():
    """Scenes without procedural media keep the plain MediaTable type, so their kernels
    compile exactly as before; a procedural medium makes the table a type of its own."""
    grid = Medium("g", "grid", sigma_s=(1.0, 1.0, 1.0), density=np.ones((2, 2, 2), np.float32))
    assert type(compile_media([grid])) is MediaTable
    program, reg = cloud_program()
    assert type(compile_media([grid, procedural(program, reg)])) is ProceduralMediaTable


@pytest.mark.parametrize("kind", ["normalized", "fbm", "ramp"])
def test_density_never_exceeds_its_cell_majorant(kind):
    program, reg = cloud_program(normalize=kind != "fbm", to_max=6.0 if kind != "fbm" else 3.0,
                                 ramp=kind == "ramp")
    mt = compile_media([procedural(program, reg)])
    count, worst = bound_violations(mt, 0, 200_000, seed=1)
    assert count == 0, f"{count} densities above their cell majorant (worst excess {worst:g})"
    assert worst < 0.0


@pytest.mark.parametrize("dim, kind", [(4, "FBM"), (4, "MULTIFRACTAL"), (2, "HYBRID_MULTIFRACTAL"),
                                       (1, "RIDGED_MULTIFRACTAL"), (3, "HETERO_TERRAIN")])
def test_every_noise_dimension_and_type_renders_within_its_majorants(dim, kind):
    """4D noise (W constant here; it may be animated), and every fractal type, has a proved
    bound (shading.noise_intervals): such clouds compile, and no density exceeds its cell's
    majorant."""
    program, reg = cloud_program(normalize=False, to_max=3.0, dim=dim, kind=kind)
    mt = compile_media([procedural(program, reg)])
    count, worst = bound_violations(mt, 0, 100_000, seed=2)
    assert count == 0, f"{count} densities above their cell majorant (worst excess {worst:g})"


def test_unclamped_map_range_with_copied_parameters_is_bounded():
    """The exporter copies a node's inputs into a parameter block (program_builder.block):
    a copy is exact, so Map Range's copied constants stay constants for the interval rules,
    and an unclamped Map Range (its Clamp off) of the noise gets a finite bound instead of
    refusing the medium (copies used to pad each value as if rounded, and a padded From Min
    made the map unbounded)."""
    program, reg = cloud_program()
    code = np.array(program.code).reshape(-1, INSTR.size).copy()
    code[2, INSTR.offset("i1")] = 0  # Clamp off
    code[2, INSTR.offset("b")] = 24  # the block read from registers 24..28, copies of 12..16
    copies = [_row("copy", 24 + k, a=12 + k, i0=1) for k in range(5)]
    regs = np.concatenate([program.registers, np.zeros(5, np.float32)])
    unclamped = ShaderProgram(np.vstack([copies, code]), regs, program.bindings, program.data)
    mt = compile_media([procedural(unclamped, reg)])
    count, worst = bound_violations(mt, 0, 100_000, seed=3)
    assert count == 0, f"{count} densities above their cell majorant (worst excess {worst:g})"


def test_noise_with_an_unbounded_parameter_is_refused_naming_the_medium():
    """A Multifractal's roughness from a division by the position (no finite bound) and the
    noise as the density (no clamp after it): the density has no bound, so the medium is
    refused by name."""
    program, reg = cloud_program(normalize=False, kind="MULTIFRACTAL")
    code = np.array(program.code).reshape(-1, INSTR.size).copy()
    divide = _row("math", 6, a=18, b=0, i0=MATH_OPS.index("DIVIDE"))  # roughness = 1.7 / x
    bad = ShaderProgram(np.vstack([code[:1], [divide], code[1:]]), program.registers, program.bindings,
                        program.data)
    with pytest.raises(SceneError, match="cloud"):
        compile_media([procedural(bad, 20)])


def test_unbounded_program_is_refused_naming_the_medium():
    program, reg = cloud_program()
    code = np.vstack([program.code, _row("math", 20, a=0, b=1, i0=MATH_OPS.index("DIVIDE"))])
    bad = ShaderProgram(code, program.registers, program.bindings, program.data)
    with pytest.raises(SceneError, match="cloud"):
        compile_media([procedural(bad, 20)])


def test_surface_operation_is_refused():
    program, reg = cloud_program()
    code = np.vstack([program.code, _row("normal", 20)])
    bad = ShaderProgram(code, program.registers, program.bindings, program.data)
    with pytest.raises(SceneError, match="normal"):
        compile_media([procedural(bad, reg)])
