"""The shader-program part of the scene validator (renderer.validate): every index a kernel
reads a program with, checked once at load.

numba does no bounds checks, so a register, table or binding index out of range in a scene
file would read or write outside the kernels' arrays. Each opcode's operands are declared
here (OPERANDS: which fields name registers and how many consecutive registers each reads
or writes; PARAMETERS: the range of each integer parameter that selects a table, an
enumeration, a dimension or a width), from what renderer.shading.interpreter and the
functions it calls index with; table references (attribute, image and data offsets) are
checked against the program's own lists, bindings against the material's lobes and the
lobe layout. Everything is Python over the program's few rows: it runs once per load.

Also here: the scene's images (the texel table the `image` operation reads) and the
meshes' corner attributes (the corner table `attribute` and `bump` read).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from renderer.bsdfs.layout import LOBE
from renderer.errors import SceneError
from renderer.shading.names import (
    BLEND_TYPES,
    GRADIENT_TYPES,
    MAP_RANGE_TYPES,
    MAPPING_TYPES,
    MATH_OPS,
    NORMAL_MAP_SPACES,
    RAMP_SIZE,
    VECTOR_OPS,
)
from renderer.shading.program import (
    BIND,
    BIND_FIELDS,
    BIND_SCALE,
    BIND_SET,
    EXTENSIONS,
    INSTR,
    INTERPOLATIONS,
    OPCODES,
    ImageTexture,
    ShaderProgram,
)
from renderer.validate.conform import require

# Vocabularies of kernel modules (which import numba, which the validator must not: the
# add-on validates before numba loads), by count; tests/test_program_validation.py checks
# them against renderer.shading.fractal.TYPES, patterns.WAVE_*, voronoi_cells.FEATURES and
# bump.CORNER_POSITION.
NOISE_TYPE_COUNT, VORONOI_FEATURE_COUNT = 5, 5
WAVE_TYPE_COUNT, WAVE_DIRECTION_COUNT, WAVE_PROFILE_COUNT = 2, 4, 3
CORNER_POSITION = "corner_position"
# Offsets the kernels form from table sizes are int32 (renderer.shading.table).
MAX_TABLE_ROWS = 2**31 - 1
# Dimensions of Noise, White Noise and Voronoi (1D to 4D; the kernels index offset tables by it).
DIMENSIONS = range(1, 5)

# A register operand's width: a number of registers, or the name of the parameter that
# gives it (copy: i0 components; curve: i1 channels).
Width = int | str


@dataclass(frozen=True)
class Operands:
    """The registers one opcode reads and writes: `dst` written over `dst_width` registers
    (0: none), and each source field (a..e) read over its width."""

    dst_width: Width = 0
    sources: tuple[tuple[str, Width], ...] = ()


def _o(dst: Width, **sources: Width) -> Operands:
    return Operands(dst, tuple(sources.items()))


OPERANDS: dict[str, Operands] = {
    "attribute": _o(3),
    "position": _o(3),
    "normal": _o(3),
    "math": _o(1, a=1, b=1, c=1),
    "vector_math": _o("vector_math", a=3, b=3, c=3, d=1),
    "mix": _o(3, a=1, b=3, c=3),
    "mix_float": _o(1, a=1, b=1, c=1),
    "mapping": _o(3, a=3, b=3, c=3, d=3),
    "checker": _o(4, a=3, b=3, c=3, d=1),
    "image": _o(4, a=3),
    "ramp": _o(4, a=1),
    "curve": _o("i1", a=1, b="i1", c=1, d=1),
    "combine": _o(3, a=1, b=1, c=1),
    "copy": _o("i0", a="i0"),
    "invert": _o(3, a=1, b=3),
    "rgb_to_bw": _o(1, a=3),
    "clamp": _o(1, a=1, b=1, c=1),
    "map_range": _o(1, a=1, b=5),
    "gradient": _o(1, a=3),
    "gamma": _o(3, a=3, b=1),
    "bright_contrast": _o(3, a=3, b=1, c=1),
    "hsv": _o(3, a=3, b=4),
    "hsv_convert": _o(3, a=3),
    "fresnel": _o(1, a=1, b=3),
    "layer_weight": _o(1, a=1, b=3),
    "normal_map": _o(3, a=3, b=1, c=3, d=1),
    "noise_nd": _o(4, a=3, b=8),
    "white_noise": _o(4, a=3, b=1),
    "voronoi": _o(9, a=3, b=8),
    "wave": _o(1, a=3, b=6),
    "magic": _o(4, a=3, b=2),
    "brick": _o(4, a=3, b=8, c=3, d=3, e=3),
    "bump_eval": _o(0),
    "bump": _o(3, a=3, b=5),
    "spectrum": _o(3, a=1, b=9),
}

# Integer parameters with a fixed range: enumerations the kernels branch on, dimensions
# they index offset tables with, widths they loop over. Parameters not listed are flags or
# counts every value of which is safe (e.g. math's clamp, magic's depth, brick's
# frequencies); table references are checked by _check_references.
PARAMETERS: dict[str, dict[str, range]] = {
    "attribute": {"i1": range(1, 4)},
    "math": {"i0": range(len(MATH_OPS))},
    "vector_math": {"i0": range(len(VECTOR_OPS))},
    "mix": {"i0": range(len(BLEND_TYPES))},
    "mapping": {"i0": range(len(MAPPING_TYPES))},
    "image": {"i1": range(len(INTERPOLATIONS)), "i2": range(len(EXTENSIONS))},
    "curve": {"i1": range(1, 4, 2)},  # 1 (Float Curve) or 3 (RGB, Vector Curves)
    "copy": {"i0": range(0, 1 << 20)},  # bounded again by the register file
    "clamp": {"i0": range(2)},
    "map_range": {"i0": range(len(MAP_RANGE_TYPES))},
    "gradient": {"i0": range(len(GRADIENT_TYPES))},
    "hsv_convert": {"i0": range(4)},
    "normal_map": {"i0": range(len(NORMAL_MAP_SPACES))},
    "noise_nd": {"i0": DIMENSIONS, "i1": range(NOISE_TYPE_COUNT), "i2": range(4)},
    "white_noise": {"i0": DIMENSIONS},
    "voronoi": {"i0": DIMENSIONS, "i1": range(VORONOI_FEATURE_COUNT), "i2": range(8)},
    "wave": {"i0": range(WAVE_TYPE_COUNT), "i1": range(WAVE_DIRECTION_COUNT),
             "i2": range(WAVE_PROFILE_COUNT)},
    "bump_eval": {"i0": range(3)},
    "spectrum": {"i0": range(2)},
}
# Operations a medium's program may not hold: they read a surface (its triangle's corners,
# normal, view side or UVs), which a point in a volume has not (renderer.media.procedural).
SURFACE_OPS = frozenset(("attribute", "normal", "fresnel", "layer_weight", "image", "bump_eval", "bump"))
# Registers each binding field writes (renderer.shading.stage): a lobe field's width in the
# lobe layout; emission and normal three registers of no lobe.
FIELD_WIDTHS = tuple(LOBE.width(name) if name in dict(LOBE.fields) else 3 for name in BIND_FIELDS)
BIND_COLUMNS = ("lobe", "field", "width", "reg", "mode")
NO_LOBE_FIELDS = frozenset((BIND_FIELDS.index("emission"), BIND_FIELDS.index("normal")))


def _width(width: Width, row: np.ndarray) -> int:
    if width == "vector_math":  # i1 set: the scalar result (one register), else a vector
        return 1 if row[INSTR.offset("i1")] else 3
    if isinstance(width, str):
        return int(row[INSTR.offset(width)])
    return width


def program_rows(array: np.ndarray, width: int, path: str) -> np.ndarray:
    """An int32 table of rows of `width` (code, bindings): 2-D, or empty. Not flattened:
    the table builders count a program's bindings by len() (a flat array's length is five
    times its rows, and the stage would read bindings past the table)."""
    array = np.asarray(array)
    require(array.dtype.kind in "iu", path, f"must be an integer array, got dtype {array.dtype}")
    shape_ok = (array.ndim == 2 and array.shape[1] == width) or array.size == 0
    require(shape_ok, path, f"must have shape (rows, {width}), got {array.shape}")
    return array.reshape(-1, width).astype(np.int64)


def check_program(program: ShaderProgram, path: str, image_names: set[str] | None = None,
                  lobes: int = 0) -> None:
    """Every index `program`'s code and bindings hold (see the module docstring).

    `image_names`: the scene's images a surface program may read; None for a medium's
    program, which may not hold SURFACE_OPS. `lobes`: the material's lobe count, the range
    of its bindings' lobe indices.
    """
    require(isinstance(program, ShaderProgram), path, "must be a shader program")
    registers = np.asarray(program.registers)
    require(registers.ndim == 1, f"{path}.registers", f"must be 1-D, got shape {registers.shape}")
    data = np.asarray(program.data)
    require(data.ndim == 1, f"{path}.data", f"must be 1-D, got shape {data.shape}")
    code = program_rows(program.code, INSTR.size, f"{path}.code")
    for name, size in (("code", len(code)), ("registers", registers.size), ("data", data.size)):
        require(size <= MAX_TABLE_ROWS, f"{path}.{name}", f"has {size} entries, at most {MAX_TABLE_ROWS}")
    for j, row in enumerate(code):
        _check_instruction(program, row, f"{path}.code[{j}]", registers.size, data.size, image_names)
    bindings = program_rows(program.bindings, BIND.size, f"{path}.bindings")
    if image_names is not None:  # a medium's bindings are never read
        for k, row in enumerate(bindings):
            _check_binding(row, f"{path}.bindings[{k}]", registers.size, lobes)


def _check_instruction(program: ShaderProgram, row: np.ndarray, path: str, registers: int, data: int,
                       image_names: set[str] | None) -> None:
    op = int(row[INSTR.offset("op")])
    require(0 <= op < len(OPCODES), f"{path}.op", f"unknown opcode {op} (0 to {len(OPCODES) - 1})")
    name = OPCODES[op]
    if image_names is None:
        require(name not in SURFACE_OPS, f"{path}.op", f"operation {name!r} has no meaning inside a volume")
    for parameter, allowed in PARAMETERS.get(name, {}).items():
        value = int(row[INSTR.offset(parameter)])
        shown = f"{allowed.start} to {allowed.stop - 1}" if allowed.step == 1 else str(tuple(allowed))
        require(value in allowed, f"{path}.{parameter}", f"{name}: {value} is not one of {shown}")
    operands = OPERANDS[name]
    for field, width in (("dst", operands.dst_width), *operands.sources):
        first = int(row[INSTR.offset(field)])
        _check_registers(first, _width(width, row), registers, f"{path}.{field}", name)
    _REFERENCES.get(name, _no_reference)(program, row, path, data, image_names)


def _check_registers(first: int, width: int, registers: int, path: str, name: str) -> None:
    if width == 0:
        return
    inside = 0 <= first and first + width <= registers
    require(inside, path, f"{name}: registers {first}..{first + width - 1} are outside the program's "
            f"{registers} registers")


def _no_reference(program, row, path, data, image_names) -> None:
    pass


def _attribute_index(program: ShaderProgram, index: int, path: str) -> str:
    count = len(program.attributes)
    require(0 <= index < count, path, f"attribute {index} is not in the program's {count} attributes")
    return program.attributes[index]


def _attribute_reference(program, row, path, data, image_names) -> None:
    _attribute_index(program, int(row[INSTR.offset("i0")]), f"{path}.i0")


def _corner_reference(program, row, path, data, image_names) -> None:
    """bump and bump_eval read three columns of the triangles' world-space corners."""
    name = _attribute_index(program, int(row[INSTR.offset("i1")]), f"{path}.i1")
    require(name == CORNER_POSITION, f"{path}.i1", f"must name attribute {CORNER_POSITION!r}, got {name!r}")


def _image_reference(program, row, path, data, image_names) -> None:
    index = int(row[INSTR.offset("i0")])
    count = len(program.images)
    require(0 <= index < count, f"{path}.i0", f"image {index} is not in the program's {count} images")
    name = program.images[index]
    require(name in image_names, f"{path}.i0", f"reads image {name!r}, not in the scene's images")


def _table_reference(program, row, path, data, image_names) -> None:
    """ramp: RAMP_SIZE RGBA entries at data[i0]; curve: RAMP_SIZE entries of i1 channels."""
    start = int(row[INSTR.offset("i0")])
    channels = 4 if OPCODES[int(row[0])] == "ramp" else int(row[INSTR.offset("i1")])
    end = start + RAMP_SIZE * channels
    require(0 <= start and end <= data, f"{path}.i0",
            f"table data[{start}:{end}] is outside the program's {data} data values")


_REFERENCES: dict[str, Callable] = {
    "attribute": _attribute_reference,
    "image": _image_reference,
    "ramp": _table_reference,
    "curve": _table_reference,
    "bump_eval": _corner_reference,
    "bump": _corner_reference,
}


def _check_binding(row: np.ndarray, path: str, registers: int, lobes: int) -> None:
    lobe, field, width, reg, mode = (int(row[BIND.offset(f)]) for f in BIND_COLUMNS)
    known = 0 <= field < len(BIND_FIELDS)
    require(known, f"{path}.field", f"unknown field {field} (0 to {len(BIND_FIELDS) - 1})")
    mode_ok = mode in (BIND_SET, BIND_SCALE)
    require(mode_ok, f"{path}.mode", f"must be {BIND_SET} (set) or {BIND_SCALE} (scale), got {mode}")
    name = BIND_FIELDS[field]
    if field in NO_LOBE_FIELDS:
        _check_registers(reg, 3, registers, f"{path}.reg", name)
        return
    require(0 <= lobe < lobes, f"{path}.lobe", f"lobe {lobe} is not one of the material's {lobes} lobes")
    most = FIELD_WIDTHS[field]
    require(1 <= width <= most, f"{path}.width", f"{name} takes 1 to {most} registers, got {width}")
    _check_registers(reg, 1 if mode == BIND_SCALE else width, registers, f"{path}.reg", name)


def check_images(images: list[ImageTexture], path: str) -> set[str]:
    """The scene's images as the texel table holds them: (H, W, 4), unique names, int32 offsets."""
    names: set[str] = set()
    texels = 0
    for i, image in enumerate(images):
        where = f"{path}[{i}]"
        require(isinstance(image, ImageTexture), where, "must be an image texture")
        pixels = np.asarray(image.pixels)
        ok = pixels.ndim == 3 and pixels.shape[2] == 4 and pixels.shape[0] >= 1 and pixels.shape[1] >= 1
        require(ok, f"{where}.pixels", f"must have shape (height, width, 4), got {pixels.shape}")
        require(image.name not in names, f"{where}.name", f"duplicate image name {image.name!r}")
        names.add(image.name)
        texels += pixels.shape[0] * pixels.shape[1]
        require(texels <= MAX_TABLE_ROWS, f"{where}.pixels", f"the scene's images hold more than "
                f"{MAX_TABLE_ROWS} texels")
    return names


def check_corner_attributes(mesh, triangles: int, path: str) -> None:
    """Each corner attribute holds (T, 3, k) values, k in 1..3, for the mesh's T triangles."""
    for i, attribute in enumerate(mesh.attributes):
        values = np.asarray(attribute.values)
        shape = values.shape
        ok = values.ndim == 3 and shape[0] == triangles and shape[1] == 3 and 1 <= shape[2] <= 3
        require(ok, f"{path}.attributes[{i}].values",
                f"must have shape ({triangles}, 3, k) with k in 1..3 (the mesh's triangles), got {shape}")


def check_shading(scene) -> None:
    """Programs, images and corner attributes of `scene` (validate_scene calls it, and
    renderer.compile before it builds the shading tables, for scenes compiled unvalidated)."""
    image_names = check_images(scene.images, "images")
    for i, material in enumerate(scene.materials):
        if material.program is not None:
            check_program(material.program, f"materials[{i}].program", image_names, len(material.lobes))
    for i, mesh in enumerate(scene.meshes):
        check_corner_attributes(mesh, int(np.asarray(mesh.indices).reshape(-1, 3).shape[0]), f"meshes[{i}]")


def check_medium_program(program: ShaderProgram, density: int, path: str) -> None:
    """A medium's program reads only the position and leaves its density in register `density`."""
    check_program(program, f"{path}.program")
    count = np.asarray(program.registers).size
    if not 0 <= density < count:
        raise SceneError(f"{path}.program_density", f"register {density} is not in the program "
                         f"({count} registers)")
