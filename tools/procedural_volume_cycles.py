"""Haze against Cycles on the two node-authored volumes of tests/test_addon_procedural_volume.py.

    .venv/bin/python tools/procedural_volume_cycles.py [--runs 4] [--samples 64] [--size 32]

The procedural cloud (Noise -> Map Range -> Principled Volume Density in a rotated, scaled
cube, a procedural medium in Haze) and the mesh whose geometry nodes output a Volume Cube of
noise density, each rendered `runs` times with independent seeds by Cycles and by Haze (the
add-on of this checkout) in one Blender process, then compared as the suite compares
renders (tests/bpy_helpers.compare_images / assert_agree): image means per channel with
their noise sigma, block z-scores, chi-square. Prints the figures and the verdict per scene.

The suite runs the same comparison at these settings (test_addon_procedural_volume's slow
tests); this tool prints the figures and takes other run counts, sample counts and sizes.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO, REPO / "tests"):
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

import bpy_helpers as H  # noqa: E402
import test_addon_procedural_volume as T  # noqa: E402

from renderer.imageio import read_exr  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=T.RUNS)
    parser.add_argument("--samples", type=int, default=T.HAZE_SAMPLES, help="per render, both renderers")
    parser.add_argument("--size", type=int, default=T.SIZE)
    args = parser.parse_args()
    body = T.scene_body(args.size, args.runs, args.samples, args.samples)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        run = H.run_blender(body, Path(folder), timeout=7200, numba_cache=H.shared_numba_cache(),
                            env={"HAZE_TEST_RENDER": "1"})
        if run.returncode != 0 or not run.result:
            print(run.describe())
            return 1
        print(f"{args.runs} x {args.samples} spp per renderer, {args.size}x{args.size}: "
              f"{time.perf_counter() - start:.0f} s in all")
        failed = False
        for name, case in (("procedural cloud", run.result), ("volume cube (geometry nodes)",
                                                               run.result["volume_cube"])):
            paths = case["renders"]
            haze = np.stack([read_exr(p) for p in paths["haze"]])
            cycles = np.stack([read_exr(p) for p in paths["cycles"]])
            comparison = H.compare_images(haze, cycles)
            print(f"{name}: media {case['media']}, warnings {case['warnings']}")
            print("  " + comparison.summary())
            try:
                H.assert_agree(comparison)
                print("  agrees with Cycles within noise")
            except AssertionError as error:
                failed = True
                print(f"  DISAGREES: {error}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
