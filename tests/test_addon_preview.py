"""Material previews rendered by Haze (bl_use_preview), headless.

Blender renders a material's preview in its own preview scene (preview.blend: the object
carrying the material, a floor, lights and a world) with the scene's render engine, which
sees engine.is_preview. Without a window the UI's preview jobs never run, but
bpy.ops.wm.previews_ensure() renders every material's icon and preview synchronously
through the same code (ED_preview_icon_render): that is what this test calls, for a
material of every kind Haze knows (diffuse, glossy, glass, emission, Principled, a volume
only and a surface with a volume), and it checks that each preview came from Haze (the
session saw is_preview), holds a lit image, and was rendered with the preview's capped
samples. The time each took is printed, not asserted (speed goals belong in benchmarks:
on this shared 2-core machine it varies with the other jobs' load).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.blender import BlenderRun
from helpers.blender_runs import blender_fixture

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

BODY = r'''
import time
import bpy
import bpy_helpers as H
import blender_cornell as C
session = H.addon_module("session")

calls = []
_run = session.RenderSession.run


def counted(self):
    started = time.monotonic()
    _run(self)
    calls.append({"preview": self.preview, "seconds": time.monotonic() - started,
                  "size": [self.width, self.height], "spp": getattr(self.latest, "spp", 0)})


session.RenderSession.run = counted


def shader(name, kind, output="Surface", **inputs):
    material, tree, out = C.node_material(name)
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], out.inputs[output])
    return material


def materials():
    yield C.diffuse_material("Diffuse", (0.8, 0.2, 0.1))
    yield shader("Glossy", "ShaderNodeBsdfGlossy", Roughness=0.2)
    yield shader("Glass", "ShaderNodeBsdfGlass", Roughness=0.0)
    yield shader("Emission", "ShaderNodeEmission", Strength=3.0)
    yield shader("Principled", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.1, 0.4, 0.8, 1.0)})
    yield shader("Smoke", "ShaderNodeVolumePrincipled", output="Volume", Density=2.0)
    glass = shader("Murky", "ShaderNodeBsdfGlass", Roughness=0.0)
    scatter = glass.node_tree.nodes.new("ShaderNodeVolumeScatter")
    glass.node_tree.links.new(scatter.outputs[0], glass.node_tree.nodes["Material Output"].inputs["Volume"])
    yield glass


def main():
    H.enable_addon()
    scene = C.clear_scene()
    scene.render.engine = "HAZE"
    scene.haze.workers = 1
    names = []
    for material in materials():
        material.use_fake_user = True  # previews_ensure skips data-blocks nobody uses
        material.preview_ensure()
        names.append(material.name)
    # The first call compiles what the preview scene needs (and starts the worker); the
    # second is timed warm: every preview is rendered again (previews_ensure re-renders
    # only what changed, so the materials are tagged for it).
    bpy.ops.wm.previews_ensure()
    first = len(calls)
    for name in names:
        bpy.data.materials[name].preview.reload()
    bpy.ops.wm.previews_ensure()
    out = {"cold": calls[:first], "warm": calls[first:], "previews": {}}
    for name in names:
        preview = bpy.data.materials[name].preview
        pixels = list(preview.image_pixels_float)
        w, h = preview.image_size
        rgb = [pixels[i + c] for i in range(0, len(pixels), 4) for c in range(3)]
        out["previews"][name] = {"size": [w, h], "max": max(rgb) if rgb else 0.0,
                                 "lit": sum(1 for v in rgb if v > 0.02) / max(len(rgb), 1)}
    return out
'''


def printed(run: BlenderRun, folder: Path) -> dict:
    print(run.result)
    return run.result


previews = blender_fixture(BODY, "preview", timeout=1800, read=printed)


def test_previews_are_rendered_by_haze(previews):
    assert previews["warm"], "Blender rendered no preview with Haze"
    assert all(call["preview"] for call in previews["cold"] + previews["warm"])


def test_every_material_kind_has_a_lit_preview(previews):
    for name, preview in previews["previews"].items():
        assert preview["size"][0] > 0 and preview["lit"] > 0.2, f"{name}: {preview}"


def test_previews_render_the_capped_samples(previews):
    from addon.session import PREVIEW_SAMPLES, PREVIEW_VOLUME_SAMPLES

    # The volume-only and glass + volume materials take the volume cap, the five others the
    # surface one (an icon and a preview each).
    spp = sorted(call["spp"] for call in previews["warm"])
    assert spp == sorted([PREVIEW_SAMPLES] * 10 + [PREVIEW_VOLUME_SAMPLES] * 4), spp
    for size in (32, 128):
        times = sorted(c["seconds"] for c in previews["warm"] if c["size"][0] == size)
        print(f"warm {size}x{size} previews: {', '.join(f'{t:.2f}' for t in times)} s")
