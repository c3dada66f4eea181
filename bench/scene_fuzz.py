"""Seeded mutational fuzzing of a scene folder with shader programs, images and attributes.

    .venv/bin/python -m bench scene_fuzz [--mutants 10000] [--seed 37]

A valid folder (a plane and a box whose materials run programs: UVs, a checker, an image,
a colour ramp, noise, math, a bump, bindings of colour, roughness, weight and normal) is
mutated MUTANTS times: integer cells of the code and bindings set to out-of-range or nearby
values, tables reshaped or truncated, register files and data emptied, attribute and image
lists and arrays changed, numbers of the scene.json set to extreme values. Each mutant is
loaded; one that loads is rendered in this process at a tiny size. Every mutant must be
refused with one SceneError line or render finite pixels; anything else (another exception,
a non-finite pixel) is a failure, and a signal death (a kernel reading outside its arrays)
kills this process, which tests/test_scene_fuzz.py runs as a child to see it. Each mutant
is named on stderr before it runs, so a death names its mutant.

Prints one JSON line: {"mutants", "refused", "rendered", "failures", "seconds"}; exits 1
when there are failures.
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import SceneError
from renderer.scene import (
    Camera,
    CornerAttribute,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Mesh,
    PointLight,
    Scene,
)
from renderer.scenefile import load_scene, save_scene
from renderer.shading.names import MATH_OPS, RAMP_SIZE, VECTOR_OPS
from renderer.shading.program import BIND_FIELDS, BIND_SCALE, BIND_SET, OP, ImageTexture, ShaderProgram

RENDER_SIDE = 8  # pixels of a rendered mutant's film side, at most
INTS = [-1, -2, -(2**31), 2**31 - 1, 10**8, 10**6, 999, 64, 60, 57, 52, 51, 50, 48, 9, 4, 3, 2, 1, 0]
NUMBERS: list[Any] = [0, -1, 1e-30, 1e30, 3.5e38, 2**31, 2**62, 2**63 - 1, 2**64 - 1, 2**64, 0.5, "x", None,
                      [], True]


def _instr(op: str, dst: int, a=0, b=0, c=0, d=0, e=0, i0=0, i1=0, i2=0) -> list[int]:
    return [OP[op], dst, a, b, c, d, e, i0, i1, i2]


def textured_program() -> ShaderProgram:
    """A program touching every kind of table reference. Registers: 0-2 UV, 3-5 and 6-8
    checker colours, 9 scale, 10-13 checker, 14-17 image, 18-21 ramp, 22 math, 26-29 noise
    with its parameters at 30-37, 38-40 vector sum, 41-43 bump, 44-46 normal, 47-51 heights."""
    regs = np.zeros(52, np.float32)
    regs[3:6], regs[6:9], regs[9] = (0.8, 0.2, 0.1), (0.1, 0.3, 0.9), 4.0
    regs[30:38] = (0.0, 3.0, 2.0, 0.5, 2.0, 0.0, 1.0, 0.0)  # W, scale, detail, roughness, lacunarity...
    regs[47:52] = (0.1, 0.12, 0.09, 1.0, 0.1)
    code = np.array([
        _instr("attribute", 0, i0=0, i1=2),
        _instr("checker", 10, a=0, b=3, c=6, d=9),
        _instr("image", 14, a=0, i0=0, i1=1, i2=0),
        _instr("math", 22, a=10, b=14, c=9, i0=MATH_OPS.index("MULTIPLY")),
        _instr("ramp", 18, a=22, i0=0, i1=1),
        _instr("noise_nd", 26, a=0, b=30, i0=3, i1=1, i2=1),
        _instr("vector_math", 38, a=10, b=14, c=18, d=9, i0=VECTOR_OPS.index("ADD")),
        _instr("normal", 44),
        _instr("bump_eval", 0, i0=0, i1=1),
        _instr("bump", 41, a=44, b=47, i0=0, i1=1),
    ], np.int32)
    ramp = np.linspace(0.0, 1.0, RAMP_SIZE * 4, dtype=np.float32)
    binds = np.array([
        [0, BIND_FIELDS.index("color"), 3, 38, BIND_SET],
        [1, BIND_FIELDS.index("roughness"), 1, 22, BIND_SET],
        [1, BIND_FIELDS.index("weight"), 3, 26, BIND_SCALE],
        [-1, BIND_FIELDS.index("normal"), 3, 41, BIND_SET],
    ], np.int32)
    return ShaderProgram(code, regs, binds, ramp, attributes=["uv:UVMap", "corner_position"], images=["grid"])


def _quad(z: float, half: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], np.float32)
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int32)


def _uv(v: np.ndarray, idx: np.ndarray) -> np.ndarray:
    span = np.ptp(v[:, :2], axis=0)
    return ((v[:, :2] - v[:, :2].min(axis=0)) / span)[idx].astype(np.float32)  # (T, 3, 2)


def base_scene() -> Scene:
    """The valid scene every mutant starts from: two textured quads under a sky and a lamp."""
    meshes = []
    for k, (z, half) in enumerate(((0.0, 1.0), (0.5, 0.3))):
        v, idx = _quad(z, half)
        uv = CornerAttribute("uv:UVMap", _uv(v, idx))
        meshes.append(Mesh(f"quad{k}", v, idx, ["textured"], attributes=[uv]))
    material = Material("textured", lobes=[Lobe("diffuse", color=(0.5, 0.5, 0.5)),
                                           Lobe("rough_conductor", weight=(0.3, 0.3, 0.3), roughness=0.4)],
                        program=textured_program())
    pixels = np.random.default_rng(3).random((3, 5, 4), dtype=np.float32)
    to_world = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]], float)
    return Scene(camera=Camera(to_world=to_world, fov=40.0), film=Film(width=RENDER_SIDE, height=RENDER_SIDE),
                 integrator=IntegratorSettings(spp=1, max_bounces=3, seed=5), materials=[material],
                 meshes=meshes, lights=[PointLight((0.0, 0.0, 3.0), (5.0, 5.0, 5.0))],
                 environment=Environment((0.3, 0.3, 0.3)), images=[ImageTexture("grid", pixels)])


# --------------------------------------------------------------------------- the mutations


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    found = []
    for key, child in items:
        found.append((*prefix, key))
        found.extend(_paths(child, (*prefix, key)))
    return found


def _get(data: Any, path: tuple) -> Any:
    for key in path:
        data = data[key]
    return data


def _set(data: Any, path: tuple, value: Any) -> None:
    _get(data, path[:-1])[path[-1]] = value


def _array_files(data: dict, folder: Path, suffix: str = "") -> list[tuple[tuple, Path]]:
    """(JSON path, file) of every array reference whose key ends with `suffix`."""
    refs = [p for p in _paths(data) if isinstance(_get(data, p), str) and _get(data, p).endswith(".npy")]
    return [(p, folder / _get(data, p)) for p in refs if str(p[-1]).endswith(suffix)]


def _int_cell(rng: random.Random, data: dict, folder: Path) -> str:
    """One integer of a program's code or bindings set to an extreme or nearby value."""
    path, file = rng.choice(_array_files(data, folder, "code") + _array_files(data, folder, "bindings"))
    array = np.load(file)
    if not array.size:
        return f"leave {path} alone"
    flat = array.reshape(-1).copy()
    at = rng.randrange(flat.size)
    old = int(flat[at])
    new = rng.choice(INTS) if rng.random() < 0.6 else old + rng.choice([-3, -2, -1, 1, 2, 3, 8, 40])
    flat[at] = np.int32(max(min(new, 2**31 - 1), -(2**31)))
    np.save(file, flat.reshape(array.shape))
    return f"{path}[{at}] {old} -> {new}"


def _reshape_table(rng: random.Random, data: dict, folder: Path) -> str:
    path, file = rng.choice(_array_files(data, folder, "code") + _array_files(data, folder, "bindings"))
    array = np.load(file)
    kind = rng.choice(["flat", "columns", "drop row", "transpose", "empty", "float"])
    if kind == "flat":
        array = array.reshape(-1)
    elif kind == "columns":
        flat = array.reshape(-1)
        array = flat[: flat.size - flat.size % 9].reshape(-1, 9)
    elif kind == "drop row":
        array = array[:-1]
    elif kind == "transpose":
        array = np.ascontiguousarray(array.T)
    elif kind == "empty":
        array = array[:0]
    else:
        array = array.astype(np.float32)
    np.save(file, array)
    return f"{path}: {kind}"


def _shrink_floats(rng: random.Random, data: dict, folder: Path) -> str:
    """A register file or data table truncated (or emptied, or made 2-D)."""
    path, file = rng.choice(_array_files(data, folder, "registers") + _array_files(data, folder, "data"))
    array = np.load(file)
    kind = rng.choice(["truncate", "empty", "2-D"])
    if kind == "truncate" and array.size:
        array = array[: rng.randrange(array.size)]
    elif kind == "2-D":
        array = array.reshape(1, -1)
    else:
        array = array[:0]
    np.save(file, array)
    return f"{path}: {kind}"


def _mesh_attribute(rng: random.Random, data: dict, folder: Path) -> str:
    path, file = rng.choice(_array_files(data, folder, "values"))
    array = np.load(file)
    kind = rng.choice(["fewer triangles", "more triangles", "k=4", "k=0", "2-D", "corners"])
    if kind == "fewer triangles":
        array = array[:1]
    elif kind == "more triangles":
        array = np.concatenate([array] * 6)
    elif kind == "k=4":
        array = np.concatenate([array, array], axis=2)
    elif kind == "k=0":
        array = array[:, :, :0]
    elif kind == "2-D":
        array = array.reshape(array.shape[0], -1)
    else:
        array = array[:, :2]
    np.save(file, array)
    return f"{path}: {kind}"


def _image_pixels(rng: random.Random, data: dict, folder: Path) -> str:
    path, file = rng.choice(_array_files(data, folder, "pixels"))
    array = np.load(file)
    kind = rng.choice(["rgb", "empty", "flat", "one texel"])
    if kind == "rgb":
        array = np.ascontiguousarray(array[:, :, :3])
    elif kind == "empty":
        array = array[:0]
    elif kind == "flat":
        array = array.reshape(-1, 4)
    else:
        array = array[:1, :1]
    np.save(file, array)
    return f"{path}: {kind}"


def _name_list(rng: random.Random, data: dict, folder: Path) -> str:
    """A program's attribute or image list, or an image's name, changed."""
    lists = [p for p in _paths(data) if p[-1] in ("attributes", "images") and isinstance(_get(data, p), list)
             and all(isinstance(x, str) for x in _get(data, p))]
    path = rng.choice(lists + [("images", 0, "name")])
    value = _get(data, path)
    if isinstance(value, str):
        _set(data, path, value + "_renamed")
        return f"rename {path}"
    kind = rng.choice(["drop", "rename", "add", "empty"])
    if kind == "drop" and value:
        value.pop(rng.randrange(len(value)))
    elif kind == "rename" and value:
        value[rng.randrange(len(value))] = "nowhere"
    elif kind == "add":
        value.append(rng.choice(["uv:other", "corner_position", "grid", "generated"]))
    else:
        value.clear()
    return f"{path}: {kind}"


def _number(rng: random.Random, data: dict, folder: Path) -> str:
    """Any number of the scene.json (integrator settings most often) set to an extreme value."""
    numbers = [p for p in _paths(data)
               if isinstance(_get(data, p), int | float) and not isinstance(_get(data, p), bool)]
    settings = [p for p in numbers if p[0] == "integrator"]
    path = rng.choice(settings if rng.random() < 0.5 else numbers)
    value = rng.choice(NUMBERS)
    _set(data, path, value)
    return f"set {path} = {str(value)[:30]}"


MUTATIONS = [_int_cell, _int_cell, _int_cell, _int_cell, _reshape_table, _shrink_floats, _mesh_attribute,
             _image_pixels, _name_list, _number]


def mutate(rng: random.Random, folder: Path) -> str:
    """One to three mutations of the folder; what was done."""
    scene_file = folder / "scene.json"
    data = json.loads(scene_file.read_text())
    done = [_apply(rng.choice(MUTATIONS), rng, data, folder) for _ in range(rng.choice([1, 1, 2, 3]))]
    scene_file.write_text(json.dumps(data))
    return "; ".join(done)


def _apply(mutation, rng: random.Random, data: dict, folder: Path) -> str:
    """One mutation; one that does not apply to what earlier ones left (an array already
    reshaped, a list already gone) is skipped: the fuzzer's own limits are not findings."""
    try:
        return mutation(rng, data, folder)
    except (ValueError, IndexError, KeyError, TypeError, OSError) as error:
        return f"skip {mutation.__name__} ({type(error).__name__})"


# ------------------------------------------------------------------------------- the runs


def render_finite(scene: Scene) -> bool:
    """Render `scene` in this process at most RENDER_SIDE pixels wide, 1 spp, as a worker
    traces a unit (renderer.units.trace_unit): finite pixels?"""
    from renderer.compile import compile_scene
    from renderer.integrator.wavefront import Tracer
    from renderer.units import Unit, trace_unit

    scene.film.width = min(scene.film.width, RENDER_SIDE)
    scene.film.height = min(scene.film.height, RENDER_SIDE)
    scene.film.region = None
    cs = compile_scene(scene)
    film = trace_unit(Tracer(cs, scene.integrator), Unit(0, 0, 1, 0, cs.height), scene.integrator.seed)
    return bool(np.isfinite(film.image()).all())


def run(mutants: int, seed: int, log=sys.stderr) -> dict:
    """Fuzz `mutants` mutants of base_scene() with random seed `seed`; the counts."""
    rng = random.Random(seed)
    counts = {"mutants": mutants, "refused": 0, "rendered": 0, "failures": 0}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="haze_fuzz_") as tmp:
        base = Path(tmp) / "base"
        save_scene(base_scene(), base)
        render_finite(load_scene(base))  # the base itself must render
        for k in range(mutants):
            case = Path(tmp) / "case"
            shutil.rmtree(case, ignore_errors=True)
            shutil.copytree(base, case)
            what = mutate(rng, case)
            print(f"mutant {k}: {what}", file=log, flush=True)
            outcome = _outcome(case)
            if outcome in ("refused", "rendered"):
                counts[outcome] += 1
            else:
                counts["failures"] += 1
                print(f"FAILURE mutant {k} ({what}): {outcome}", file=sys.stderr, flush=True)
    counts["seconds"] = round(time.perf_counter() - t0, 2)
    return counts


def _outcome(case: Path) -> str:
    try:
        scene = load_scene(case)
    except SceneError as error:
        message = str(error)
        return "refused" if "\n" not in message and len(message) < 400 else f"long message {message[:200]!r}"
    except Exception as error:  # noqa: BLE001 - anything else is what the fuzzer looks for
        return f"{type(error).__name__} on load: {str(error)[:300]}"
    try:
        return "rendered" if render_finite(scene) else "non-finite pixels"
    except SceneError as error:  # refused by compile_scene's checks
        return "refused" if "\n" not in str(error) else f"long message {str(error)[:200]!r}"
    except Exception as error:  # noqa: BLE001
        return f"{type(error).__name__} on render: {str(error)[:300]}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench scene_fuzz", description=__doc__.splitlines()[0])
    ap.add_argument("--mutants", type=int, default=10000, help="mutants to try (default 10000)")
    ap.add_argument("--seed", type=int, default=37, help="the mutations' random seed")
    ap.add_argument("--quiet", action="store_true", help="name failures only, not every mutant")
    args = ap.parse_args(argv)
    log = open("/dev/null", "w") if args.quiet else sys.stderr  # noqa: SIM115 - lives as long as the run
    counts = run(args.mutants, args.seed, log)
    print(json.dumps(counts), flush=True)
    return 1 if counts["failures"] else 0
