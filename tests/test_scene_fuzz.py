"""Seeded fuzzing of scene folders (issues 17, 37): every run ends in a clean error or a finite image.

A valid scene.json and its arrays are mutated a few hundred times (values, types, keys,
nesting, huge integers, array files, array paths leaving the folder). Each mutant is loaded
and validated in-process and must either load or raise SceneError with a one-line message;
a handful more are rendered by the command line at a tiny size and must exit 0 with a
finite image or exit 2 with one "error:" line. No run may change a file outside its output.

Issue 37: the shader programs' tables are what a kernel indexes with, and numba checks no
bounds. bench/scene_fuzz.py mutates a folder whose materials run programs (code and
binding cells out of range, tables reshaped, registers emptied, attribute and image lists
and arrays changed) and renders every mutant that loads, in its own process, so that a
kernel reading outside its arrays shows as a signal death; `python -m bench scene_fuzz`
runs 10,000 mutants.
"""

from __future__ import annotations

import copy
import json
import random
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from examples.scenes import cornell_fog
from renderer.errors import SceneError
from renderer.imageio import read_exr
from renderer.scene import Medium
from renderer.scenefile import load_scene, save_scene

ROOT = Path(__file__).resolve().parents[1]
IN_PROCESS_RUNS = 400
RENDER_RUNS = 5
PROGRAM_MUTANTS = 300
EXTREME_VALUES: list[Any] = [
    0, -1, -0.0, 1e-320, 1e-45, 3.5e38, 1e39, 1e300, -1e300, 2**64, 10**50, 0.5, 179.999999,
    "x", "", None, True, [], {}, [1, 2], [[1, 2, 3]] * 4, [1e300] * 3, [0.0, 0.0, 0.0],
]
BAD_ARRAY_PATHS = [
    "../outside/data.npy", "../outside/missing.npy", "/etc/passwd", "arrays", "", "arrays/missing.npy",
    "arrays/../../outside/data.npy", "arrays/link_out.npy", "arrays/link_missing.npy", "a\u0000b.npy",
]


# ----------------------------------------------------------------------------- the folders


def _base_scene_folder(folder: Path, grid: bool) -> None:
    """A valid small scene; with `grid` its fog is a grid medium with all three arrays."""
    scene = cornell_fog(size=4, spp=1, max_bounces=2)
    if grid:
        rng = np.random.default_rng(5)
        fog = scene.media[0]
        scene.media[0] = Medium(
            fog.name, "grid", sigma_a=fog.sigma_a, sigma_s=fog.sigma_s, emission=(0.5, 0.2, 0.1),
            density=rng.random((3, 4, 5), dtype=np.float32), p0=(-1.0, 0.0, -1.0), p1=(1.0, 2.0, 1.0),
            flame=rng.random((2, 2, 2), dtype=np.float32),
            temperature=rng.random((2, 3, 2), dtype=np.float32) * 2000, blackbody_intensity=0.5,
        )
    save_scene(scene, folder)


def _outside_folder(root: Path) -> Path:
    """Files a mutant may point at but must never change."""
    outside = root / "outside"
    outside.mkdir()
    np.save(outside / "data.npy", np.ones((4, 3), np.float32))
    (outside / "notes.txt").write_text("not the renderer's")
    return outside


def _snapshot(root: Path, skip: set[str] = frozenset()) -> dict[str, tuple]:
    """Every file and link under `root` (but `skip` names) with its bytes or link target."""
    found = {}
    for path in sorted(root.rglob("*")):
        if path.name in skip:
            continue
        if path.is_symlink():
            found[str(path)] = ("link", str(path.readlink()))
        elif path.is_file():
            found[str(path)] = ("file", path.read_bytes(), path.stat().st_mtime_ns)
    return found


# --------------------------------------------------------------------------- the mutations


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Paths (tuples of keys and indices) to every value in a JSON tree, the root excluded."""
    found = []
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        found.append((*prefix, key))
        found.extend(_paths(child, (*prefix, key)))
    return found


def _parent(data: Any, path: tuple) -> Any:
    for key in path[:-1]:
        data = data[key]
    return data


def _array_refs(data: dict) -> list[tuple]:
    return [p for p in _paths(data) if isinstance(_get(data, p), str) and _get(data, p).endswith(".npy")]


def _get(data: Any, path: tuple) -> Any:
    return _parent(data, path)[path[-1]]


def _set_extreme(rng: random.Random, data: dict, folder: Path) -> str:
    path = rng.choice(_paths(data))
    value = copy.deepcopy(rng.choice(EXTREME_VALUES))
    _parent(data, path)[path[-1]] = value
    return f"set {path} = {str(value)[:40]}"


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _scale_number(rng: random.Random, data: dict, folder: Path) -> str:
    numbers = [p for p in _paths(data) if _is_number(_get(data, p))]
    path = rng.choice(numbers)
    factor = 10.0 ** rng.uniform(-40, 40) * rng.choice([1, -1])
    _parent(data, path)[path[-1]] = _get(data, path) * factor
    return f"scale {path} by {factor:.3g}"


def _drop_or_add_key(rng: random.Random, data: dict, folder: Path) -> str:
    objects = [p for p in _paths(data) if isinstance(_get(data, p), dict)]
    target = _get(data, rng.choice(objects)) if objects and rng.random() < 0.8 else data
    if target and rng.random() < 0.6:
        key = rng.choice(list(target))
        del target[key]
        return f"drop key {key}"
    target["unknown_" + str(rng.randrange(100))] = 1
    return "add an unknown key"


def _deepen(rng: random.Random, data: dict, folder: Path) -> str:
    path = rng.choice(_paths(data))
    value = _get(data, path)
    for _ in range(rng.choice([2, 20, 400])):
        value = [value]
    _parent(data, path)[path[-1]] = value
    return f"nest {path} deeply"


def _redirect_array(rng: random.Random, data: dict, folder: Path) -> str:
    path = rng.choice(_array_refs(data))
    _parent(data, path)[path[-1]] = value = rng.choice(BAD_ARRAY_PATHS)
    return f"point {path} at {value!r}"


def _corrupt_array(rng: random.Random, data: dict, folder: Path) -> str:
    path = rng.choice(_array_refs(data))
    file = folder / _get(data, path)
    if file.is_symlink() or not file.resolve().is_relative_to(folder.resolve()):
        return f"leave {path} alone"  # the fuzzer itself must not write outside the case either
    try:
        array = np.load(file)
    except (OSError, ValueError):  # an earlier mutation pointed it elsewhere or broke it
        return f"leave {path} alone"
    kind = rng.choice(["dtype", "shape", "nan", "huge", "negative", "empty", "truncate", "garbage", "header"])
    if kind == "dtype":
        np.save(file, array.astype(rng.choice([np.float64, np.int64, np.float16, np.uint8, np.bool_])))
    elif kind == "shape":
        np.save(file, array.reshape(-1) if array.ndim > 1 else array.reshape(1, -1))
    elif kind in ("nan", "huge", "negative"):
        if array.size:
            flat = array.reshape(-1).copy()
            flat[rng.randrange(flat.size)] = {"nan": np.nan, "huge": 3e38, "negative": -7}[kind] \
                if array.dtype.kind == "f" else {"nan": -1, "huge": 2**31 - 1, "negative": -5}[kind]
            np.save(file, flat.reshape(array.shape))
    elif kind == "empty":
        np.save(file, np.zeros((0,) + array.shape[1:], array.dtype))
    elif kind == "truncate":
        file.write_bytes(file.read_bytes()[: rng.randrange(1, file.stat().st_size)])
    elif kind == "garbage":
        file.write_bytes(rng.randbytes(rng.randrange(0, 300)))
    else:
        text = file.read_bytes().replace(b"'shape': (", b"'shape': (-", 1)
        file.write_bytes(text)
    return f"corrupt {path} ({kind})"


ValueMutation = Callable[[random.Random, dict, Path], str]
JSON_MUTATIONS: list[ValueMutation] = [
    _set_extreme, _set_extreme, _scale_number, _scale_number, _drop_or_add_key, _deepen, _redirect_array,
    _corrupt_array, _corrupt_array,
]


def _mutate_text(rng: random.Random, text: str) -> tuple[str, str]:
    """Mutations of scene.json's text that no JSON value can express."""
    kind = rng.choice(["truncate", "huge integer", "deep", "bytes"])
    if kind == "truncate":
        return text[: rng.randrange(len(text))], kind
    if kind == "huge integer":
        at = text.index(":", rng.randrange(len(text) // 2)) + 1
        return text[:at] + " " + "9" * rng.choice([400, 4400, 50000]) + ", \"x\":" + text[at:], kind
    if kind == "deep":
        depth = rng.choice([50, 5000, 200000])
        return text[:-2] + ', "deep": ' + "[" * depth + "]" * depth + "}\n", kind
    position = rng.randrange(len(text))
    return text[:position] + "\x00\ud800"[rng.randrange(2)] + text[position + 1:], kind


def mutate(rng: random.Random, folder: Path) -> str:
    """Apply one to three random mutations to the scene folder; returns what was done."""
    scene_file = folder / "scene.json"
    data = json.loads(scene_file.read_text())
    done = [rng.choice(JSON_MUTATIONS)(rng, data, folder) for _ in range(rng.choice([1, 1, 2, 3]))]
    text = json.dumps(data)
    if rng.random() < 0.15:
        text, kind = _mutate_text(rng, text)
        done.append(f"text: {kind}")
    scene_file.write_text(text, encoding="utf-8", errors="surrogatepass")
    return "; ".join(done)


def _plant_links(folder: Path, outside: Path) -> None:
    (folder / "arrays" / "link_out.npy").symlink_to(outside / "data.npy")
    (folder / "arrays" / "link_missing.npy").symlink_to(outside / "missing.npy")


# ------------------------------------------------------------------------------- the tests


def test_mutated_scenes_load_or_fail_with_one_clean_line(tmp_path: Path) -> None:
    rng = random.Random(17)
    base = tmp_path / "base"
    _base_scene_folder(base, grid=True)
    load_scene(base)
    outside = _outside_folder(tmp_path)
    before = _snapshot(outside)
    outcomes = {"loaded": 0, "refused": 0}
    for run in range(IN_PROCESS_RUNS):
        case = tmp_path / "case"
        shutil.rmtree(case, ignore_errors=True)
        shutil.copytree(base, case)
        _plant_links(case, outside)
        what = mutate(rng, case)
        try:
            load_scene(case)
            outcomes["loaded"] += 1
        except SceneError as error:
            message = str(error)
            assert "\n" not in message and len(message) < 400, f"run {run} ({what}): {message!r}"
            outcomes["refused"] += 1
        except Exception as error:  # anything else is a bug: say which mutation found it
            pytest.fail(f"run {run} ({what}): {type(error).__name__}: {str(error)[:300]}")
    assert _snapshot(outside) == before
    assert outcomes["refused"] > IN_PROCESS_RUNS // 2 and outcomes["loaded"] > 0, outcomes


def _render_mutation(rng: random.Random, data: dict, folder: Path) -> str:
    """A value mutation the renderer is likely to get past validation: numbers scaled or extreme."""
    return rng.choice([_scale_number, _scale_number, _set_extreme])(rng, data, folder)


def test_mutated_scenes_render_finite_images_or_fail_cleanly(tmp_path: Path) -> None:
    rng = random.Random(1717)
    base = tmp_path / "base"
    _base_scene_folder(base, grid=False)
    outside = _outside_folder(tmp_path)
    for run in range(RENDER_RUNS):
        case = tmp_path / f"case{run}"
        shutil.copytree(base, case)
        data = json.loads((case / "scene.json").read_text())
        what = _render_mutation(rng, data, case)
        (case / "scene.json").write_text(json.dumps(data))
        out = tmp_path / f"out{run}.exr"
        before = _snapshot(tmp_path, skip={out.name, out.with_suffix(".png").name})
        command = [sys.executable, "-m", "renderer", "render", str(case), "-o", str(out), "--workers", "1",
                   "--spp", "1"]
        result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600)
        label = f"run {run} ({what})"
        assert "Traceback" not in result.stderr, f"{label}: {result.stderr[-2000:]}"
        if result.returncode == 0:
            assert np.isfinite(read_exr(out)).all(), label
        else:
            errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
            assert result.returncode == 2 and len(errors) == 1, f"{label}: {result.stderr[-2000:]}"
        assert _snapshot(tmp_path, skip={out.name, out.with_suffix(".png").name}) == before, label
    assert outside.exists()


def test_program_mutants_are_refused_or_render_finite_pixels() -> None:
    """PROGRAM_MUTANTS mutants of bench.scene_fuzz's textured folder, each loaded and (if it
    loads) rendered in one child process: no signal death, no traceback, no hang, no
    non-finite pixel; refusals are one SceneError line."""
    command = [sys.executable, "-m", "bench", "scene_fuzz", "--mutants", str(PROGRAM_MUTANTS), "--seed", "37"]
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=1800)
    tail = result.stderr[-3000:]
    assert result.returncode >= 0, f"killed by signal {-result.returncode} after:\n{tail}"
    counts = json.loads(result.stdout.strip().splitlines()[-1])
    assert result.returncode == 0 and counts["failures"] == 0, tail
    assert counts["refused"] > PROGRAM_MUTANTS // 3 and counts["rendered"] > 0, counts
