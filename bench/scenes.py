"""The convergence benchmark's scenes: each a builder (image size -> renderer Scene), the
estimator settings to compare on it (IntegratorSettings overrides by label) and a line of
description. The builders use examples/, so this lives outside the shipped renderer."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from renderer.scene import Medium, Mesh, Scene


@dataclass
class BenchScene:
    name: str
    build: Callable[[int], Scene]
    # label -> IntegratorSettings overrides; "default" = ratio tracking, spectral MIS,
    # majorant grid, equiangular: the renderer's defaults
    settings: dict[str, dict[str, object]]
    description: str
    # For a scene built in Blender (bench/blend_scenes.py): size -> its .blend, which Cycles
    # renders as it is; None: Cycles renders the Haze scene rebuilt by bench/cycles_reference.py.
    blend: Callable[[int], Path] | None = None


def _cornell(size: int) -> Scene:
    from examples.scenes import cornell_box

    return cornell_box(size, 1, max_bounces=3)


def _fog(g: float) -> Callable[[int], Scene]:
    def build(size: int) -> Scene:
        from examples.scenes import cornell_fog

        return cornell_fog(size, 1, g=g, max_bounces=3)

    return build


def _smoke_ball(size: int) -> Scene:
    from examples.media_scenes import smoke_ball

    return smoke_ball(size, 1)


CHROMATIC_SIGMA_T = (30.0, 3.0, 0.3)  # per unit: 100x between red and blue
CHROMATIC_ALBEDO = 0.9


def _chromatic(size: int) -> Scene:
    """A homogeneous box of a strongly chromatic medium on the Cornell box floor: optically
    thick in red (27 across), thin in blue (0.27)."""
    from examples.media_scenes import INTERFACE, MEDIA_MAX_BOUNCES, interface_material
    from examples.scenes import box, cornell_box

    scene = cornell_box(size, 1, max_bounces=MEDIA_MAX_BOUNCES, boxes=False)
    sigma_s = tuple(CHROMATIC_ALBEDO * s for s in CHROMATIC_SIGMA_T)
    sigma_a = tuple((1.0 - CHROMATIC_ALBEDO) * s for s in CHROMATIC_SIGMA_T)
    scene.media.append(Medium("chromatic", sigma_a=sigma_a, sigma_s=sigma_s))
    scene.materials.append(interface_material())
    scene.meshes.append(Mesh("chromatic_box", *box((0.0, -0.55, 0.0), (0.45, 0.45, 0.45), 25), [INTERFACE],
                             medium="chromatic"))
    return scene


BLEND_BOUNCES = 3
MEDIA_BOUNCES = 16  # examples/blender_gallery's depth for its media scenes


def _built_in_blender(name: str, description: str, bounces: int = BLEND_BOUNCES,
                      gallery: str | None = None) -> BenchScene:
    """examples/blender_gallery's scene `gallery` (default `name`): Haze renders its export,
    Cycles the .blend."""
    from .blend_scenes import blend_file, blend_scene

    source = gallery or name
    return BenchScene(name, lambda size: blend_scene(source, size, bounces), {"default": {}},
                      f"{description}, max_bounces {bounces}",
                      blend=lambda size: blend_file(source, size, bounces))


NO_EQUIANGULAR = {"equiangular": False}
UNIFORM = {"distance_sampling": "uniform"}
SCENES: dict[str, BenchScene] = {s.name: s for s in (
    BenchScene("cornell", _cornell, {"default": {}}, "Cornell box, surfaces only, max_bounces 3"),
    BenchScene("fog_g0", _fog(0.0), {"default": {}, "no-equiangular": NO_EQUIANGULAR, "uniform": UNIFORM},
               "Cornell box in the Fig. 1 fog, g = 0, max_bounces 3"),
    BenchScene("fog_g0.9", _fog(0.9), {"default": {}, "no-equiangular": NO_EQUIANGULAR},
               "Cornell box in the Fig. 1 fog, g = 0.9, max_bounces 3"),
    BenchScene("smoke_ball", _smoke_ball, {"default": {}, "delta": {"transmittance": "delta"},
                                           "no-majorant-grid": {"majorant_grid": False}},
               "Fig. 3 smoke ball (11^3 grid, sigma_a 90, sigma_s 10) in the Cornell box, max_bounces 16"),
    BenchScene("chromatic", _chromatic, {"default": {}, "uniform": UNIFORM, "no-equiangular": NO_EQUIANGULAR},
               f"box of sigma_t {CHROMATIC_SIGMA_T}, albedo {CHROMATIC_ALBEDO} in the Cornell box, "
               "max_bounces 16"),
    _built_in_blender("textured_box", "Cornell box built in Blender: checker/noise Principled floor, image "
                      "wall, noise-marbled cube"),
    _built_in_blender("hdri", "floor, diffuse and rough metal balls under an HDRI with a 2x2-pixel sun, "
                      "built in Blender"),
    # Issue 18's figure: the gallery's Volume objects as a user builds them (Principled Volume
    # reading the grid), at the gallery's depth.
    _built_in_blender("smoke_ball_blender", "Fig. 3 smoke ball as a Blender Volume object (Principled "
                      "Volume, sigma_a 90, sigma_s 10) in the Cornell box", MEDIA_BOUNCES, "smoke_ball"),
    _built_in_blender("fire_ball_blender", "Fig. 7 fire ball as a Blender Volume object (blackbody "
                      "temperature and smoke grids) around a rough metal bust", MEDIA_BOUNCES, "fire_ball"),
    _built_in_blender("procedural_cloud", "procedural cloud built in Blender: Noise -> Map Range -> "
                      "Principled Volume Density in a cube, sun and sky"),
)}
SETTING_NOTES = {
    "default": "ratio tracking, spectral MIS, majorant grid, equiangular (the defaults)",
    "no-equiangular": "free-flight distance sampling only",
    "uniform": "distance sampling in one uniformly chosen channel (no spectral MIS)",
    "delta": "delta-tracking shadow transmittance",
    "no-majorant-grid": "one global majorant",
}
