"""The shared kernel cache: one folder per build, one compile per machine, nothing stale."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from numba.core import event

from examples import media_scenes as ms
from examples import scenes as sc
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator import stages
from renderer.integrator.wavefront import Tracer
from renderer.kernels import cache

REPO = Path(__file__).resolve().parents[1]


def test_build_key_follows_the_sources_not_their_place(tmp_path):
    a, b = tmp_path / "a" / "renderer", tmp_path / "b" / "renderer"
    for root in (a, b):
        (root / "kernels").mkdir(parents=True)
        (root / "scene.py").write_text("X = 1\n")
        (root / "kernels" / "rng.py").write_text("Y = 2\n")
    assert cache.build_key(a) == cache.build_key(b)  # same sources elsewhere: the same cache
    (b / "kernels" / "rng.py").write_text("Y = 3\n")
    assert cache.build_key(a) != cache.build_key(b)  # a kernel's source changed: a new cache
    (b / "kernels" / "rng.py").write_text("Y = 2\n")
    (b / "kernels" / "extra.py").write_text("")
    assert cache.build_key(a) != cache.build_key(b)


def test_another_numba_gets_another_cache(monkeypatch):
    key = cache.build_key()
    monkeypatch.setattr(numba, "__version__", "0.0.1")
    assert cache.build_key() != key


def test_cache_root_takes_the_users_choice(monkeypatch, tmp_path):
    monkeypatch.setenv("HAZE_CACHE_DIR", str(tmp_path / "haze"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert cache.cache_root() == tmp_path / "haze"
    monkeypatch.delenv("HAZE_CACHE_DIR")
    assert cache.cache_root() == tmp_path / "numba"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert cache.cache_root() == tmp_path / "xdg" / "haze"


def test_kernels_are_cached_under_the_build_key():
    from renderer.kernels.rng import path_key

    path_key(1, 2, 3)
    folder = Path(path_key.stats.cache_path)
    assert folder == cache.kernel_cache_dir() / "kernels"
    assert list(folder.glob("rng.path_key-*.nbi"))


SCENES = {
    "surface": lambda: sc.cornell_box(8, 1),
    "fog": lambda: sc.cornell_fog(8, 1, 0.3),
    "grid with interfaces": lambda: ms.smoke_ball(8, 1),
    "sunlit slab": lambda: ms.add_slab(ms.sunlit_plane(8, 1), None, 0.5, 1.0),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SCENES))
def test_after_warm_up_a_render_compiles_nothing(name):
    """The tracer's list of kernel calls (what warm_up compiles) matches the calls and
    argument types of a real render, so no kernel is compiled later outside the lock."""
    scene = SCENES[name]()
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    with event.install_recorder("numba:compile") as rec:
        tracer.trace(Film(cs.width, cs.height), 0, 2, 0)
    compiled = {ev.data["dispatcher"].py_func.__name__ for _, ev in rec.buffer if ev.is_start}
    assert not compiled & set(stages.__all__), compiled


WORKER = """
import json, sys, time
from numba.core import event
sys.path.insert(0, {repo!r})
from examples.scenes import cornell_fog
from renderer.compile import compile_scene
from renderer.integrator.wavefront import Tracer
scene = cornell_fog(8, 1, 0.0)
cs = compile_scene(scene)
said = []
with event.install_recorder("numba:compile") as rec:
    tracer = Tracer(cs, scene.integrator, said.append)
compiled = [[ev.data["dispatcher"].py_func.__module__ + "." + ev.data["dispatcher"].py_func.__qualname__,
             str(ev.data["args"])] for _, ev in rec.buffer if ev.is_start]
subtrees = [k.py_func.__module__ + "." + k.py_func.__qualname__ for k, _ in tracer.subtree_calls()]
print(json.dumps({{"compiled": compiled, "said": said, "seconds": tracer.compile_seconds,
                  "subtrees": subtrees}}))
"""


@pytest.mark.slow
def test_two_processes_on_a_cold_cache_never_compile_the_same_function(tmp_path):
    """Started together on an empty cache, two processes share the compiling: each function
    signature is compiled by one of them (under its lock) and loaded by the other; a third
    process later finds everything cached and says nothing."""
    env = {**os.environ, "HAZE_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("NUMBA_CACHE_DIR", None)
    code = WORKER.format(repo=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True)
             for _ in range(2)]
    results = [json.loads(p.communicate(timeout=1800)[0].strip().splitlines()[-1]) for p in procs]
    assert all(p.returncode == 0 for p in procs)
    first, second = ({tuple(c) for c in r["compiled"]} for r in results)
    assert first and not first & second, sorted(first & second)  # nothing compiled twice
    # The stage kernels are all compiled, each once, between the two.
    stages_compiled = [name for name, _ in first | second if name.split(".")[-1] in stages.__all__]
    assert len(stages_compiled) == len(set(stages_compiled)) >= 4, stages_compiled
    # The helpers listed ahead of the stages were compiled for the stages' own argument
    # types: one signature each (a second one would be the stage compiling it again).
    helpers = [name for name, _ in first | second if name in results[0]["subtrees"]]
    assert sorted(helpers) == sorted(set(results[0]["subtrees"])), sorted(first | second)
    # Whoever compiled said so first, naming the kernels.
    for r in results:
        if r["compiled"]:
            assert r["said"] and r["said"][0], results
    third = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    result = json.loads(third.stdout.strip().splitlines()[-1])
    assert result["compiled"] == [] and result["said"] == [] and result["seconds"] == 0.0
    shutil.rmtree(tmp_path / "cache", ignore_errors=True)
