"""The renderer as a pip package: the wheel tools/wheel_backend.py builds (what `pip install .`
installs and what the Blender extension bundles), its metadata against pyproject.toml, and,
slow, a fresh virtual environment that pip-installs it with the `cluster` extra and renders
the same bits locally and on a `dask scheduler` + `dask worker` of its own.
"""

from __future__ import annotations

import ast
import base64
import configparser
import csv
import email.parser
import hashlib
import importlib.metadata
import importlib.util
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
import tomllib
import zipfile
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
MANIFEST = tomllib.loads((REPO / "blender_manifest.toml").read_text())
DIST_INFO = f"haze_renderer-{PROJECT['version']}.dist-info"
DIST_INFO_FILES = ("METADATA", "WHEEL", "entry_points.txt", "top_level.txt", "RECORD")


def load_by_path(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


backend = load_by_path("wheel_backend", REPO / "tools" / "wheel_backend.py")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel, built through the PEP 517 hook as pip calls it."""
    folder = tmp_path_factory.mktemp("wheel")
    return folder / backend.build_wheel(str(folder))


def package_files() -> list[str]:
    """renderer/**.py and the .npz tables it loads, without caches."""
    return sorted(p.relative_to(REPO).as_posix() for suffix in ("*.py", "*.npz")
                  for p in (REPO / "renderer").rglob(suffix) if "__pycache__" not in p.parts)


def read_metadata(wheel: Path):
    with zipfile.ZipFile(wheel) as archive:
        return email.parser.BytesParser().parsebytes(archive.read(f"{DIST_INFO}/METADATA"))


def test_wheel_holds_the_renderer_package_and_its_dist_info_only(wheel):
    assert wheel.name == f"haze_renderer-{PROJECT['version']}-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
    assert len(names) == len(set(names))
    assert sorted(names) == sorted(package_files() + [f"{DIST_INFO}/{n}" for n in DIST_INFO_FILES])
    assert "renderer/bsdfs/ggx_energy.npz" in names  # data the BSDFs load at import
    tracked = subprocess.run(["git", "ls-files", "renderer"], cwd=REPO, capture_output=True, text=True)
    if tracked.returncode == 0:  # every file of the package in git is in the wheel
        assert set(tracked.stdout.split()) <= set(names)


def test_metadata_matches_pyproject(wheel):
    meta = read_metadata(wheel)
    assert meta["Metadata-Version"] == "2.1"
    assert meta["Name"] == PROJECT["name"] == "haze-renderer"
    assert meta["Version"] == PROJECT["version"]
    assert meta["Requires-Python"] == PROJECT["requires-python"] == ">=3.11"
    assert meta["Summary"] == PROJECT["description"]
    assert meta.get_all("Provides-Extra") == ["cluster"] == list(PROJECT["optional-dependencies"])
    requires = [Requirement(r) for r in meta.get_all("Requires-Dist")]
    always = [str(r) for r in requires if r.marker is None]
    cluster = [r for r in requires if r.marker is not None]
    assert always == [str(Requirement(r)) for r in PROJECT["dependencies"]]
    assert all(r.marker.evaluate({"extra": "cluster"}) and not r.marker.evaluate({"extra": ""})
               for r in cluster)
    assert [f"{r.name}{r.specifier}" for r in cluster] == PROJECT["optional-dependencies"]["cluster"]
    names = {canonicalize_name(r.name) for r in requires}
    assert names == {"numpy", "numba", "llvmlite", "embreex", "openexr", "dask", "distributed"}


def test_dependencies_admit_the_tested_versions():
    """requirements.txt pins what is tested; the package's ranges must allow those versions
    (numpy, numba, ... as installed here) and the cluster extra pins the same dask."""
    pins = {}
    for line in (REPO / "requirements.txt").read_text().splitlines():
        if "==" in line and not line.lstrip().startswith("#"):
            name, version = line.split("#")[0].strip().split("==")
            pins[canonicalize_name(name)] = version
    for text in PROJECT["dependencies"] + PROJECT["optional-dependencies"]["cluster"]:
        requirement = Requirement(text)
        name = canonicalize_name(requirement.name)
        assert requirement.specifier.contains(pins[name]), (text, pins[name])
        assert requirement.specifier.contains(importlib.metadata.version(requirement.name)), text
    assert PROJECT["optional-dependencies"]["cluster"] == \
        [f"dask=={pins['dask']}", f"distributed=={pins['distributed']}"]


def imported_modules() -> tuple[set[str], set[str]]:
    """Top-level modules renderer/ imports from outside itself and the standard library:
    (at module level, i.e. whenever the module is imported; only inside functions or
    `if TYPE_CHECKING:`)."""
    eager, lazy = set(), set()

    def visit(node, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            names = []
            if isinstance(child, ast.Import):
                names = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom) and child.level == 0:
                names = [child.module]
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in ("renderer", "__future__"):
                    (lazy if in_function else eager).add(top)
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                visit(ast.Module(body=child.body, type_ignores=[]), True)  # never run
                visit(ast.Module(body=child.orelse, type_ignores=[]), in_function)
                continue
            function = isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            visit(child, in_function or function)

    for path in (REPO / "renderer").rglob("*.py"):
        visit(ast.parse(path.read_text(), str(path)), False)
    return eager, lazy - eager


def test_dependencies_are_what_the_renderer_imports():
    """Every required dependency is imported by the renderer whenever it loads (OpenEXR:
    renderer.imageio, which writes every image); the cluster's only inside functions."""
    eager, lazy = imported_modules()
    known = importlib.metadata.packages_distributions()  # Python 3.11 infers it from .py files only

    def distribution(module: str) -> str:
        if module in known:
            return canonicalize_name(known[module][0])
        origin = Path(importlib.util.find_spec(module).origin).resolve()  # e.g. OpenEXR, a .so
        for dist in importlib.metadata.distributions():
            if any(Path(dist.locate_file(f)).resolve() == origin for f in dist.files or ()):
                return canonicalize_name(dist.metadata["Name"])
        raise AssertionError(f"no installed distribution provides {module} ({origin})")

    def names(modules: set[str]) -> set[str]:
        return {distribution(m) for m in modules}

    required = {canonicalize_name(Requirement(r).name) for r in PROJECT["dependencies"]}
    cluster = {canonicalize_name(Requirement(r).name) for r in PROJECT["optional-dependencies"]["cluster"]}
    assert names(eager) == required
    assert names(lazy) <= cluster and "distributed" in names(lazy)


def test_version_is_the_extension_version(wheel):
    assert PROJECT["version"] == MANIFEST["version"]
    assert f"./wheels/{wheel.name}" in MANIFEST["wheels"]


def test_wheel_tag_and_entry_point(wheel):
    with zipfile.ZipFile(wheel) as archive:
        tags = email.parser.BytesParser().parsebytes(archive.read(f"{DIST_INFO}/WHEEL"))
        points = configparser.ConfigParser()
        points.read_string(archive.read(f"{DIST_INFO}/entry_points.txt").decode())
    assert tags["Wheel-Version"] == "1.0" and tags["Root-Is-Purelib"] == "true"
    assert tags.get_all("Tag") == ["py3-none-any"]
    assert dict(points["console_scripts"]) == {"haze": "renderer.cli:main"} == PROJECT["scripts"]
    from renderer.cli import main

    assert callable(main)


def test_record_hashes_every_file(wheel):
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        rows = list(csv.reader(io.StringIO(archive.read(f"{DIST_INFO}/RECORD").decode())))
        assert sorted(r[0] for r in rows) == sorted(names)
        for path, digest, size in rows:
            if path == f"{DIST_INFO}/RECORD":
                assert digest == size == ""
                continue
            data = archive.read(path)
            expected = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            assert digest == f"sha256={expected}" and int(size) == len(data), path


def test_builds_are_reproducible_and_the_extension_bundles_the_same_wheel(wheel, tmp_path):
    again = tmp_path / "again"
    assert backend.build_wheel(str(again)) == wheel.name
    assert (again / wheel.name).read_bytes() == wheel.read_bytes()
    extension = load_by_path("build_extension", REPO / "tools" / "build_extension.py")
    bundled = extension.renderer_wheel(MANIFEST["version"], tmp_path / "extension")
    assert bundled.name == wheel.name and bundled.read_bytes() == wheel.read_bytes()
    assert extension.RENDERER_DIST == "haze_renderer"


def test_sdist_is_reproducible_and_builds_the_same_wheel(wheel, tmp_path):
    first = tmp_path / backend.build_sdist(str(tmp_path))
    second = tmp_path / "2" / backend.build_sdist(str(tmp_path / "2"))
    assert first.name == f"haze_renderer-{PROJECT['version']}.tar.gz"
    assert first.read_bytes() == second.read_bytes()
    with tarfile.open(first) as archive:
        base = f"haze_renderer-{PROJECT['version']}"
        names = sorted(m.name.removeprefix(base + "/") for m in archive.getmembers())
        assert all(m.name.startswith(base + "/") and m.isfile() for m in archive.getmembers())
        archive.extractall(tmp_path / "unpacked", filter="data")
    assert "PKG-INFO" in names and "pyproject.toml" in names and "tools/wheel_backend.py" in names
    assert not [n for n in names if n.split("/")[0] in ("addon", "tests", "bench", "examples")]
    # The unpacked sdist's own backend (its root: the unpacked folder) builds the same wheel.
    unpacked = load_by_path("sdist_backend", tmp_path / "unpacked" / base / "tools" / "wheel_backend.py")
    assert unpacked.ROOT == (tmp_path / "unpacked" / base).resolve()
    rebuilt = tmp_path / "from-sdist" / unpacked.build_wheel(str(tmp_path / "from-sdist"))
    assert rebuilt.read_bytes() == wheel.read_bytes()


def test_editable_wheel_imports_the_checkout_package_only(tmp_path):
    editable = tmp_path / backend.build_editable(str(tmp_path))
    with zipfile.ZipFile(editable) as archive:
        archive.extractall(tmp_path / "site")
        names = set(archive.namelist())
    pth = [n for n in names if n.endswith(".pth")]
    assert len(pth) == 1 and f"{DIST_INFO}/entry_points.txt" in names and f"{DIST_INFO}/METADATA" in names
    import_line = (tmp_path / "site" / pth[0]).read_text().strip()
    assert import_line.startswith("import ")
    # -I: no PYTHONPATH, no user site, no current folder on sys.path.
    code = (f"import sys; sys.path.insert(0, {str(tmp_path / 'site')!r}); {import_line}; "
            "import renderer.cli; print(renderer.cli.__file__); "
            "import importlib.util; print(importlib.util.find_spec('tools'))")
    run = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    cli_file, tools_spec = run.stdout.split()
    assert Path(cli_file) == REPO / "renderer" / "cli.py" and tools_spec == "None"


# -- slow: a fresh virtual environment -------------------------------------------------------

TIMEOUT = 900  # s, for every command: a hang fails the test rather than blocking CI


def run(command: list, **options) -> subprocess.CompletedProcess:
    done = subprocess.run([str(c) for c in command], capture_output=True, text=True, timeout=TIMEOUT,
                          **options)
    assert done.returncode == 0, \
        f"{command}: exit {done.returncode}\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
    return done


def stop(process: subprocess.Popen) -> None:
    """End `process` and what it started (its own session: a worker's nanny and worker)."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=30)
            return
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(process.pid, signal.SIGKILL)  # leftovers of the group, or a process that ignored TERM
    except ProcessLookupError:
        pass
    process.wait(timeout=30)


def tail(path: Path) -> str:
    return path.read_text(errors="replace")[-3000:] if path.is_file() else ""


@pytest.mark.slow
def test_a_fresh_venv_installs_and_renders_on_a_cluster(tmp_path):
    """`pip install "<repo>[cluster]"` into a new venv of this Python; from a folder outside the
    repository, without PYTHONPATH: `haze --help`, then a render with `--workers 1` and one on a
    `dask scheduler` + `dask worker` of that venv, bit for bit the same. The versions are those
    of requirements.txt (as a constraints file), so only the package itself is under test."""
    from examples.scenes import cornell_box
    from renderer.imageio import read_exr
    from renderer.scenefile import save_scene

    venv, work = tmp_path / "venv", tmp_path / "work"
    work.mkdir()
    bin_dir = venv / "bin"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update(HAZE_CACHE_DIR=str(tmp_path / "kernel-cache"), PIP_DISABLE_PIP_VERSION_CHECK="1")
    env.pop("NUMBA_CACHE_DIR", None)
    env["PATH"] = os.pathsep.join([str(bin_dir), env.get("PATH", "")])
    started = time.monotonic()
    run([sys.executable, "-m", "venv", venv], env=env, cwd=work)
    install = [bin_dir / "python", "-m", "pip", "install", "--constraint", REPO / "requirements.txt",
               f"{REPO}[cluster]"]
    if (REPO / "build" / "wheels").is_dir():  # the third-party wheels the extension build downloaded
        install += ["--find-links", REPO / "build" / "wheels"]
    run(install, env=env, cwd=work)
    installed = time.monotonic()

    where = run([bin_dir / "python", "-c", "import renderer; print(renderer.__file__)"], env=env, cwd=work)
    assert Path(where.stdout.strip()).is_relative_to(venv), where.stdout
    usage = run([bin_dir / "haze", "--help"], env=env, cwd=work)
    assert "render" in usage.stdout

    scene = work / "scene"
    save_scene(cornell_box(size=32, spp=4), scene)
    common = ["--spp", "4", "--no-png"]
    run([bin_dir / "haze", "render", scene, "-o", work / "b.exr", "--workers", "1", *common],
        env=env, cwd=work)
    local = time.monotonic()

    scheduler_file = work / "scheduler.json"
    processes = []
    logs = {name: work / f"{name}.log" for name in ("scheduler", "worker")}
    try:
        with open(logs["scheduler"], "w") as log:
            processes.append(subprocess.Popen(
                [str(bin_dir / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                 "--scheduler-file", str(scheduler_file)],
                cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        deadline = time.monotonic() + 120
        address = None
        while address is None:
            assert processes[0].poll() is None, f"the scheduler ended:\n{tail(logs['scheduler'])}"
            assert time.monotonic() < deadline, f"no scheduler file after 120 s:\n{tail(logs['scheduler'])}"
            try:
                address = json.loads(scheduler_file.read_text())["address"]
            except (FileNotFoundError, ValueError, KeyError):
                time.sleep(0.2)
        assert address.startswith("tcp://127.0.0.1:"), address
        with open(logs["worker"], "w") as log:
            processes.append(subprocess.Popen(
                [str(bin_dir / "dask"), "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                 "--nworkers", "1", "--no-dashboard"],
                cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        wait = ("import sys; from distributed import Client; c = Client(sys.argv[1], timeout=60); "
                "c.wait_for_workers(1, timeout=300); c.close()")
        try:
            run([bin_dir / "python", "-c", wait, address], env=env, cwd=work)
        except AssertionError as error:
            raise AssertionError(f"{error}\nworker log:\n{tail(logs['worker'])}") from None
        try:
            run([bin_dir / "haze", "render", scene, "-o", work / "a.exr", "--cluster", address, *common],
                env=env, cwd=work)
        except AssertionError as error:
            raise AssertionError(f"{error}\nworker log:\n{tail(logs['worker'])}") from None
    finally:
        for process in reversed(processes):
            stop(process)
    done = time.monotonic()
    print(f"fresh venv: install {installed - started:.0f} s, local render {local - installed:.0f} s, "
          f"cluster render {done - local:.0f} s")

    a, b = read_exr(work / "a.exr"), read_exr(work / "b.exr")
    assert a.shape == b.shape == (32, 32, 3) and a.dtype == b.dtype
    assert a.tobytes() == b.tobytes(), "the cluster render differs from the local one"
    assert a.mean() > 0.0
    shutil.rmtree(venv, ignore_errors=True)  # ~1 GB of numba, llvmlite, ...
