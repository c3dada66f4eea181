"""Render the media gallery: every scene of examples.media_scenes to docs/gallery/<name>.png.

    python examples/gallery.py [--size 128] [--spp N] [--only NAME ...] [--workers 2] [--out DIR]

Each scene renders on `workers` processes (the second core needs a second process, see
renderer.render) and its time is printed; --spp overrides every scene's default.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Runnable as a script from anywhere: the repository root holds `renderer` and `examples`.
ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from examples.media_scenes import BUILDERS  # noqa: E402
from renderer.imageio import write_png  # noqa: E402
from renderer.render import render_progressive  # noqa: E402

OUT = ROOT / "docs" / "gallery"
# Samples per pixel for each scene: at 128x128 each takes about a minute on two cores
# (the fog's multiple scattering converges slowly, the grids cost more per sample).
DEFAULT_SPP = {
    "fog_isotropic": 512,
    "fog_backward": 512,
    "fog_forward": 512,
    "smoke_ball": 256,
    "yellow_smoke": 256,
    "fire_ball": 256,
    "underwater": 512,
}


def render_one(name: str, size: int, spp: int, workers: int, out: Path = OUT) -> tuple[float, int]:
    """Render gallery entry `name` to out/<name>.png; returns (seconds, spp reached)."""
    scene = BUILDERS[name](size, spp)
    start = time.perf_counter()
    progress = None
    for progress in render_progressive(scene, workers=workers):  # noqa: B007
        pass
    assert progress is not None
    seconds = time.perf_counter() - start
    write_png(out / f"{name}.png", progress.image)
    return seconds, progress.spp


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128, help="image width and height in pixels")
    parser.add_argument("--spp", type=int, default=0, help="samples per pixel (default: per scene)")
    parser.add_argument("--workers", type=int, default=2, help="render processes")
    parser.add_argument("--only", nargs="+", choices=sorted(BUILDERS), help="render only these scenes")
    parser.add_argument("--out", type=Path, default=OUT, help="output folder (default docs/gallery)")
    args = parser.parse_args(argv)
    if args.size < 1 or args.spp < 0 or args.workers < 1:
        parser.error("--size and --workers must be >= 1, --spp >= 0")
    args.out.mkdir(parents=True, exist_ok=True)
    total = 0.0
    for name in args.only or list(BUILDERS):
        spp = args.spp or DEFAULT_SPP[name]
        seconds, reached = render_one(name, args.size, spp, args.workers, args.out)
        total += seconds
        print(f"{name:16s} {args.size}x{args.size} {reached:5d} spp {seconds:7.1f} s", flush=True)
    print(f"{'total':16s} {total:7.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
