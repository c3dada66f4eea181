"""Density grids for the Add > Volume operators, and OpenVDB files to hold them (no bpy here).

Grids are (nz, ny, nx) float32 arrays, x fastest, as in Haze's scene format and in pbrt's
'heterogeneous' medium (density[(z * ny + y) * nx + x]). A grid filling the box p0..p1 has
voxel (i, j, k) centred at p0 + (i + 0.5) h with h = (p1 - p0) / n: that is Haze's
convention and, written as an OpenVDB index-to-object transform, Blender's and Cycles' too.

The generators (the paper's Fig. 3 smoke ball and Fig. 6 gaussian smoke) live in
renderer/media/generators.py, shared with examples/media_scenes.py; they are re-exported here,
imported when first called: importing renderer.media imports numba and defines kernels,
which registering the add-on must not wait for.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import re
import sys
from pathlib import Path

import numpy as np


def smoke_ball_density(*args, **kwargs) -> np.ndarray:
    """renderer.media.generators.smoke_ball_density (the paper's Fig. 3 smoke ball)."""
    from renderer.media.generators import smoke_ball_density as generate

    return generate(*args, **kwargs)


def gaussian_smoke_density(*args, **kwargs) -> np.ndarray:
    """renderer.media.generators.gaussian_smoke_density (the paper's Fig. 6 smoke)."""
    from renderer.media.generators import gaussian_smoke_density as generate

    return generate(*args, **kwargs)

__all__ = ["GridFileError", "box_index_to_object", "check_grid", "gaussian_smoke_density", "import_openvdb",
           "read_npy", "read_pbrt", "smoke_ball_density", "write_pbrt", "write_vdb"]


class GridFileError(ValueError):
    """A density file that cannot be read; the message says what is wrong with it."""


def box_index_to_object(p0, p1, shape) -> np.ndarray:
    """Index-to-object matrix of a (nz, ny, nx) grid filling the box p0..p1."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    h = (p1 - p0) / np.array(shape[::-1], np.float64)
    matrix = np.eye(4)
    matrix[:3, :3] = np.diag(h)
    matrix[:3, 3] = p0 + 0.5 * h
    return matrix


# ------------------------------------------------------------------------------ reading


def check_grid(values: np.ndarray, source: str) -> np.ndarray:
    """A usable density grid from `values`, or GridFileError saying what is wrong."""
    if values.ndim != 3 or min(values.shape) < 1:
        raise GridFileError(f"{source}: a density grid must be 3-D (nz, ny, nx), got shape {values.shape}")
    if not np.issubdtype(values.dtype, np.number) or np.iscomplexobj(values):
        raise GridFileError(f"{source}: density values must be real numbers, got {values.dtype}")
    values = values.astype(np.float32)
    if not np.all(np.isfinite(values)):
        raise GridFileError(f"{source}: {int(np.count_nonzero(~np.isfinite(values)))} density values are NaN "
                            "or infinite")
    if np.any(values < 0.0):
        raise GridFileError(f"{source}: {int(np.count_nonzero(values < 0.0))} density values are negative")
    return values


def read_npy(path: Path) -> np.ndarray:
    try:
        values = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise GridFileError(f"{path.name}: not a readable .npy array ({error})") from error
    return check_grid(np.asarray(values), path.name)


# pbrt-v3 parameter: "type name" followed by a value or a [ list ].
PBRT_PARAMETER = re.compile(r'"\s*(\w+)\s+(\w+)\s*"\s*(\[[^\]]*\]|"[^"]*"|[^\s"\[]+)', re.S)


def pbrt_parameters(text: str) -> dict[str, str]:
    """The parameters of the first 'heterogeneous' MakeNamedMedium in a pbrt-v3 scene text."""
    text = re.sub(r"#[^\n]*", "", text)
    for match in re.finditer(r"MakeNamedMedium\s+\"[^\"]*\"(.*?)(?=\n\s*[A-Z][A-Za-z]+\s|\Z)", text, re.S):
        body = match.group(1)
        parameters = {name: value for _, name, value in PBRT_PARAMETER.findall(body)}
        if parameters.get("type", "").strip('"') == "heterogeneous":
            return parameters
    raise GridFileError("no MakeNamedMedium of type \"heterogeneous\" found")


def pbrt_numbers(parameters: dict[str, str], name: str, count: int | None = None) -> np.ndarray:
    if name not in parameters:
        raise GridFileError(f"the heterogeneous medium has no \"{name}\" parameter")
    try:
        values = np.array(parameters[name].strip("[]").split(), np.float64)
    except ValueError as error:
        raise GridFileError(f"parameter \"{name}\" is not a list of numbers") from error
    if count is not None and values.size != count:
        raise GridFileError(f"parameter \"{name}\" has {values.size} values, expected {count}")
    return values


def read_pbrt(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(density (nz, ny, nx), p0, p1) of the first heterogeneous medium in a pbrt-v3 file."""
    try:
        text = path.read_text(errors="replace")
    except OSError as error:
        raise GridFileError(f"{path.name}: cannot be read ({error})") from error
    try:
        parameters = pbrt_parameters(text)
        nx, ny, nz = (int(pbrt_numbers(parameters, n, 1)[0]) for n in ("nx", "ny", "nz"))
        if min(nx, ny, nz) < 1:
            raise GridFileError(f"nx, ny, nz must be >= 1, got {nx}, {ny}, {nz}")
        density = pbrt_numbers(parameters, "density", nx * ny * nz).reshape(nz, ny, nx)
        p0 = pbrt_numbers(parameters, "p0", 3) if "p0" in parameters else np.zeros(3)
        p1 = pbrt_numbers(parameters, "p1", 3) if "p1" in parameters else np.ones(3)
    except GridFileError as error:
        raise GridFileError(f"{path.name}: {error}") from error
    if np.any(p1 <= p0):
        raise GridFileError(f"{path.name}: p1 {tuple(p1)} must exceed p0 {tuple(p0)} on every axis")
    return check_grid(density, path.name), p0, p1


def write_pbrt(path: Path, density: np.ndarray, p0, p1, sigma_a=(1.0, 1.0, 1.0),
               sigma_s=(1.0, 1.0, 1.0)) -> None:
    """A pbrt-v3 heterogeneous medium description of `density` (examples and tests)."""
    nz, ny, nx = density.shape
    numbers = " ".join(f"{v:.9g}" for v in density.reshape(-1))
    path.write_text(
        f'MakeNamedMedium "grid" "string type" "heterogeneous"\n'
        f'  "rgb sigma_a" [{" ".join(map(str, sigma_a))}] "rgb sigma_s" [{" ".join(map(str, sigma_s))}]\n'
        f'  "integer nx" {nx} "integer ny" {ny} "integer nz" {nz}\n'
        f'  "point p0" [{" ".join(map(str, p0))}] "point p1" [{" ".join(map(str, p1))}]\n'
        f'  "float density" [{numbers}]\n')


# ------------------------------------------------------------------------------ OpenVDB


def import_openvdb():
    """Blender's bundled OpenVDB Python module, or None if this Blender has none.

    Blender ships it in its own site-packages, which is on sys.path in Blender but not when
    bpy is a Python module; then it is loaded from there directly (nothing else is added)."""
    try:
        import openvdb

        return openvdb
    except ImportError:
        pass
    try:
        import bpy

        folder = Path(bpy.utils.resource_path("LOCAL")) / "python" / "lib" / \
            f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    except (ImportError, AttributeError):
        return None
    for candidate in sorted(folder.glob("openvdb*.so")) + sorted(folder.glob("openvdb*.pyd")):
        loader = importlib.machinery.ExtensionFileLoader("openvdb", str(candidate))
        spec = importlib.util.spec_from_file_location("openvdb", candidate, loader=loader)
        if spec is None:
            continue
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
        sys.modules["openvdb"] = module
        return module
    return None


def write_vdb(path: Path, grids: dict[str, np.ndarray], index_to_object: np.ndarray) -> None:
    """Write float grids ((nz, ny, nx) arrays, voxel [0, 0, 0] at index (0, 0, 0)) to an OpenVDB
    file, exactly (float32, no tolerance); zero voxels stay inactive (the background, 0)."""
    vdb = import_openvdb()
    if vdb is None:
        raise RuntimeError("this Blender has no OpenVDB Python module (openvdb) to write volume files")
    written = []
    for name, values in grids.items():
        grid = vdb.FloatGrid()
        grid.copyFromArray(np.ascontiguousarray(np.asarray(values, np.float32).transpose(2, 1, 0)),
                           ijk=(0, 0, 0), tolerance=0.0)
        grid.name = name
        grid.gridClass = vdb.GridClass.FOG_VOLUME
        # OpenVDB matrices act on row vectors: the transpose of ours.
        grid.transform = vdb.createLinearTransform(np.asarray(index_to_object, np.float64).T.tolist())
        written.append(grid)
    path.parent.mkdir(parents=True, exist_ok=True)
    vdb.write(str(path), grids=written)
