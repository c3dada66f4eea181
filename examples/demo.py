"""`make demo`: render the main example, the paper's Cornell box in fog (Fig. 1, g = 0).

Writes the scene folder to out/cornell_fog/ (renderable again with
`python -m renderer render out/cornell_fog -o out/again.exr`), and the image to
out/cornell_fog.exr with a PNG preview beside it.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from examples.scenes import cornell_fog  # noqa: E402
from renderer.imageio import write_exr, write_png  # noqa: E402
from renderer.render import render_progressive  # noqa: E402
from renderer.scenefile import save_scene  # noqa: E402


def main() -> int:
    out = Path("out")
    scene = cornell_fog(size=256, spp=256, g=0.0, max_bounces=3)
    save_scene(scene, out / "cornell_fog")
    t0 = time.perf_counter()
    last = None
    for last in render_progressive(scene, workers=os.cpu_count() or 1):
        print(f"\r{last.spp}/{last.spp_target} spp  {last.elapsed:5.1f} s  relMSE~{last.error_estimate:.1e}",
              end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    assert last is not None
    write_exr(out / "cornell_fog.exr", last.image)
    write_png(out / "cornell_fog.png", last.image)
    seconds = time.perf_counter() - t0
    print(f"wrote {out / 'cornell_fog.exr'} and {out / 'cornell_fog.png'} "
          f"({last.spp} spp, {seconds:.1f} s, scene folder {out / 'cornell_fog'})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
