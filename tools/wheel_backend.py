"""A small PEP 517 / PEP 660 build backend for the renderer package (pyproject.toml's
`[build-system] build-backend = "wheel_backend"`, `backend-path = ["tools"]`).

It needs nothing but the standard library, so `pip install .` and `pip wheel .` download
nothing to build. It writes:

- the wheel `haze_renderer-<version>-py3-none-any.whl`: the `renderer` package (its .py
  sources and the .npz tables it loads at run time, no caches) and a dist-info folder whose
  METADATA comes from pyproject.toml's [project] table, with entry_points.txt, WHEEL and a
  RECORD of sha256 hashes. The bytes depend only on those files: entries are sorted, with a
  fixed time and permissions, so two builds are identical. tools/build_extension.py bundles
  this same wheel in the Blender extension.
- the sdist `haze_renderer-<version>.tar.gz` (renderer/, pyproject.toml, this file, README.md
  and PKG-INFO; also reproducible), from which the same wheel builds.
- an editable wheel (`pip install -e .`): a .pth file whose import line adds a finder for
  `renderer` only, pointing at this checkout (not the checkout's other folders).

Only the [project] keys below are supported; any other one is an error rather than
silently left out of the metadata.
"""

from __future__ import annotations

import base64
import gzip
import hashlib
import io
import os
import re
import tarfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the source tree: the checkout, or an unpacked sdist
PACKAGE = "renderer"  # the one top-level package the wheel holds
PACKAGE_SUFFIXES = (".py", ".npz")  # sources and the BSDF tables renderer/bsdfs/ loads
SDIST_EXTRA = ("pyproject.toml", "tools/wheel_backend.py", "README.md")
FIXED_ZIP_TIME = (2024, 1, 1, 0, 0, 0)
FIXED_EPOCH = 1704067200  # the same instant, for the sdist's tar entries
FILE_MODE = 0o644
WHEEL_TAG = "py3-none-any"
SUPPORTED_KEYS = {"name", "version", "description", "requires-python", "classifiers", "keywords", "urls",
                  "dependencies", "optional-dependencies", "scripts"}


# -- pyproject.toml ---------------------------------------------------------------------------------

def project(root: Path = ROOT) -> dict:
    """pyproject.toml's [project] table, checked to hold only what this backend writes."""
    table = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8")).get("project")
    if not isinstance(table, dict):
        raise ValueError("pyproject.toml has no [project] table")
    unknown = sorted(set(table) - SUPPORTED_KEYS)
    if unknown:
        raise ValueError(f"pyproject.toml [project] keys {unknown} are not supported by "
                         f"tools/wheel_backend.py (it writes {sorted(SUPPORTED_KEYS)})")
    for key in ("name", "version"):
        if not isinstance(table.get(key), str) or not table[key]:
            raise ValueError(f"pyproject.toml [project] needs a static {key}")
    if not re.fullmatch(r"[A-Za-z0-9]([A-Za-z0-9._-]*[A-Za-z0-9])?", table["name"]):
        raise ValueError(f"invalid project name {table['name']!r}")
    if not re.fullmatch(r"\d+(\.\d+)*((a|b|rc)\d+)?(\.post\d+)?(\.dev\d+)?", table["version"]):
        raise ValueError(f"version {table['version']!r} is not a normalised PEP 440 version")
    return table


def distribution_name(table: dict | None = None) -> str:
    """The name as it appears in file names: haze-renderer -> haze_renderer."""
    table = project() if table is None else table
    return re.sub(r"[-_.]+", "_", table["name"]).lower()


def wheel_name(table: dict | None = None) -> str:
    table = project() if table is None else table
    return f"{distribution_name(table)}-{table['version']}-{WHEEL_TAG}.whl"


def _extra_name(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()  # PEP 685


def _with_extra(requirement: str, extra: str) -> str:
    """`requirement` needed only with `extra`: its own marker, if any, and the extra's."""
    spec, _, marker = requirement.partition(";")
    condition = f'extra == "{extra}"'
    return f"{spec.strip()}; ({marker.strip()}) and {condition}" if marker.strip() else \
        f"{spec.strip()}; {condition}"


def metadata(table: dict) -> str:
    """The core metadata (METADATA in the wheel, PKG-INFO in the sdist)."""
    lines = ["Metadata-Version: 2.1", f"Name: {table['name']}", f"Version: {table['version']}"]
    if table.get("description"):
        lines.append(f"Summary: {table['description']}")
    if table.get("keywords"):
        lines.append(f"Keywords: {','.join(table['keywords'])}")
    lines += [f"Classifier: {c}" for c in table.get("classifiers", [])]
    lines += [f"Project-URL: {label}, {url}" for label, url in table.get("urls", {}).items()]
    if table.get("requires-python"):
        lines.append(f"Requires-Python: {table['requires-python']}")
    lines += [f"Requires-Dist: {r}" for r in table.get("dependencies", [])]
    for extra, requirements in table.get("optional-dependencies", {}).items():
        name = _extra_name(extra)
        lines.append(f"Provides-Extra: {name}")
        lines += [f"Requires-Dist: {_with_extra(r, name)}" for r in requirements]
    return "\n".join(lines) + "\n"


def entry_points(table: dict) -> str | None:
    scripts = table.get("scripts", {})
    if not scripts:
        return None
    return "[console_scripts]\n" + "".join(f"{name} = {target}\n" for name, target in scripts.items())


# -- files --------------------------------------------------------------------------------------

def package_files(root: Path = ROOT) -> list[str]:
    """The package's files, as sorted posix paths relative to `root`."""
    names = []
    for path in (root / PACKAGE).rglob("*"):
        relative = path.relative_to(root)
        if (path.is_file() and path.suffix in PACKAGE_SUFFIXES and "__pycache__" not in relative.parts
                and not any(part.startswith(".") for part in relative.parts)):
            names.append(relative.as_posix())
    if f"{PACKAGE}/__init__.py" not in names:
        raise ValueError(f"{root / PACKAGE} is not a package (no __init__.py)")
    return sorted(names)


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _dist_info(table: dict) -> dict[str, bytes]:
    """The dist-info files but RECORD, by name inside the dist-info folder."""
    files = {
        "METADATA": metadata(table),
        "WHEEL": "Wheel-Version: 1.0\nGenerator: haze wheel_backend\nRoot-Is-Purelib: true\n"
                 f"Tag: {WHEEL_TAG}\n",
    }
    if (points := entry_points(table)) is not None:
        files["entry_points.txt"] = points
    files["top_level.txt"] = PACKAGE + "\n"
    return {name: text.encode("utf-8") for name, text in files.items()}


def _write_wheel(dest: Path, table: dict, contents: list[tuple[str, bytes]]) -> Path:
    """A wheel of `contents` (archive name, bytes) plus the dist-info, written atomically."""
    info = f"{distribution_name(table)}-{table['version']}.dist-info"
    entries = list(contents) + [(f"{info}/{name}", data) for name, data in _dist_info(table).items()]
    record = "".join(_record_line(name, data) + "\n" for name, data in entries) + f"{info}/RECORD,,\n"
    entries.append((f"{info}/RECORD", record.encode("utf-8")))
    dest.mkdir(parents=True, exist_ok=True)
    path = dest / wheel_name(table)
    partial = path.with_name(path.name + ".part")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in entries:
            entry = zipfile.ZipInfo(name, FIXED_ZIP_TIME)
            entry.external_attr = (0o100000 | FILE_MODE) << 16  # a regular file, rw-r--r--
            entry.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(entry, data)
    os.replace(partial, path)
    return path


def write_wheel(dest: Path, root: Path = ROOT) -> Path:
    """Build the wheel of `root`'s package into folder `dest`; its path."""
    table = project(root)
    contents = [(name, (root / name).read_bytes()) for name in package_files(root)]
    return _write_wheel(Path(dest), table, contents)


def write_editable_wheel(dest: Path, root: Path = ROOT) -> Path:
    """A PEP 660 wheel: importing `renderer` loads it from `root` (the checkout)."""
    table = project(root)
    finder = f"__editable___{distribution_name(table)}_finder"
    package_dir = (Path(root).resolve() / PACKAGE).as_posix()
    source = f'''"""Editable install of {table['name']}: `{PACKAGE}` is imported from {package_dir}."""
import importlib.util
import sys

PACKAGE_DIR = {package_dir!r}


class EditableFinder:
    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name != {PACKAGE!r}:
            return None
        return importlib.util.spec_from_file_location(name, PACKAGE_DIR + "/__init__.py",
                                                      submodule_search_locations=[PACKAGE_DIR])


if EditableFinder not in sys.meta_path:
    sys.meta_path.append(EditableFinder)
'''
    pth = f"__editable__.{distribution_name(table)}-{table['version']}.pth"
    contents = [(pth, f"import {finder}\n".encode()), (f"{finder}.py", source.encode("utf-8"))]
    return _write_wheel(Path(dest), table, contents)


def write_sdist(dest: Path, root: Path = ROOT) -> Path:
    """The source distribution: a reproducible .tar.gz from which the same wheel builds."""
    table = project(root)
    base = f"{distribution_name(table)}-{table['version']}"
    names = sorted({*package_files(root), *(n for n in SDIST_EXTRA if (root / n).is_file())})
    members = [("PKG-INFO", metadata(table).encode("utf-8"))] + [(n, (root / n).read_bytes()) for n in names]
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    path = dest / f"{base}.tar.gz"
    partial = path.with_name(path.name + ".part")
    with open(partial, "wb") as raw, \
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as compressed, \
            tarfile.open(fileobj=compressed, mode="w", format=tarfile.PAX_FORMAT) as archive:
        for name, data in members:
            entry = tarfile.TarInfo(f"{base}/{name}")
            entry.size, entry.mtime, entry.mode = len(data), FIXED_EPOCH, FILE_MODE
            entry.uid = entry.gid = 0
            entry.uname = entry.gname = ""
            archive.addfile(entry, io.BytesIO(data))
    os.replace(partial, path)
    return path


def _write_metadata(metadata_directory: str) -> str:
    table = project()
    info = f"{distribution_name(table)}-{table['version']}.dist-info"
    folder = Path(metadata_directory) / info
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in _dist_info(table).items():
        (folder / name).write_bytes(data)
    return info


# -- PEP 517 / PEP 660 hooks --------------------------------------------------------------------

def get_requires_for_build_wheel(config_settings=None) -> list[str]:
    return []


def get_requires_for_build_sdist(config_settings=None) -> list[str]:
    return []


def get_requires_for_build_editable(config_settings=None) -> list[str]:
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None) -> str:
    return _write_metadata(metadata_directory)


def prepare_metadata_for_build_editable(metadata_directory, config_settings=None) -> str:
    return _write_metadata(metadata_directory)


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None) -> str:
    return write_wheel(Path(wheel_directory)).name


def build_editable(wheel_directory, config_settings=None, metadata_directory=None) -> str:
    return write_editable_wheel(Path(wheel_directory)).name


def build_sdist(sdist_directory, config_settings=None) -> str:
    return write_sdist(Path(sdist_directory)).name
