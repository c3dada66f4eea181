"""Where numba's compile time goes: seconds per kernel for one scene, on a cold cache.

Renders one pass of a benchmark scene in a fresh numba cache folder (so every kernel the
scene needs compiles) and lists each compiled function with its own time (its total less
the functions compiled inside it) and its total, from numba's event API; also the time of
LLVM's passes on the finished modules when numba reports them.

    .venv/bin/python tools/compile_profile.py [surface|fog|fog_g0.9|smoke_ball] [--top 25]

The cache folder is a temporary one unless NUMBA_CACHE_DIR is set (then a warm cache shows
what loading costs).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

if not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="haze-compile-profile-")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from numba.core import event  # noqa: E402

from examples import media_scenes as ms  # noqa: E402
from examples import scenes as sc  # noqa: E402
from renderer.compile import compile_scene  # noqa: E402
from renderer.film import Film  # noqa: E402
from renderer.integrator.wavefront import Tracer  # noqa: E402

SCENES = {
    "surface": lambda: sc.cornell_box(16, 1),
    "fog": lambda: sc.cornell_fog(16, 1, 0.0),
    "fog_g0.9": lambda: sc.cornell_fog(16, 1, 0.9),
    "smoke_ball": lambda: ms.smoke_ball(16, 1),
}


def _name(ev) -> str:
    disp = ev.data.get("dispatcher")
    func = getattr(disp, "py_func", None)
    if func is None:
        return str(disp)
    return f"{func.__module__}.{func.__qualname__}"


def profile(records) -> list[tuple[str, float, float]]:
    """(name, own seconds, total seconds) per compiled function, from nested start/end events."""
    stack: list[list] = []  # [name, start, child seconds]
    out: list[tuple[str, float, float]] = []
    for t, ev in records:
        if ev.is_start:
            stack.append([_name(ev), t, 0.0])
        elif stack:
            name, start, child = stack.pop()
            total = t - start
            out.append((name, total - child, total))
            if stack:
                stack[-1][2] += total
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?", default="fog", choices=sorted(SCENES))
    ap.add_argument("--top", type=int, default=25)
    args = ap.parse_args(argv)
    scene = SCENES[args.scene]()
    t0 = time.perf_counter()
    with event.install_recorder("numba:compile") as rec:
        cs = compile_scene(scene)
        Tracer(cs, scene.integrator).trace(Film(cs.width, cs.height), 0, 1, 0)
    wall = time.perf_counter() - t0
    rows = profile(rec.buffer)
    own: dict[str, list[float]] = {}
    for name, s, _ in rows:
        own.setdefault(name, []).append(s)
    top = sorted(own.items(), key=lambda kv: -sum(kv[1]))
    print(f"{args.scene}: {wall:.1f} s to the first pass (cache {os.environ['NUMBA_CACHE_DIR']}), "
          f"{len(rows)} compilations of {len(own)} functions")
    print(f"{'own s':>8} {'count':>5}  function")
    for name, seconds in top[:args.top]:
        print(f"{sum(seconds):8.2f} {len(seconds):5d}  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
