"""Render passes from a film's AOV sums (integrator.aovs writes them), with Cycles' names
and values (kernel/film/read.h):

  Depth             camera-space depth of sample 0's first hit (distance from the camera
                    for panoramic cameras); 1e10 where it saw the world
  Position          sample 0's first hit in world space; 0 where it saw the world
  Mist              1 - mean of (1 - mist) x throughput at the first hit (world: 1)
  Normal            mean world-space shading normal of the first hit, facing the camera
                    (misses count as 0)
  Denoising Normal  mean normal of the first diffuse-like hit, in Cycles' camera space
                    (x right, y up, z forward: Blender's camera space with z flipped);
                    (0, 0, -1) for a scatter in a medium
  Denoising Albedo  mean albedo of the first diffuse-like hit x the specular albedos passed
  Emission          mean emission the camera path found before scattering (film.light_aovs)
  Diffuse Color     mean throughput x diffuse albedo over the hits before scattering
  Glossy Color      the same for the glossy lobes' albedo
  Transmission Color  the same for the glass lobes' refraction albedo
  Volume Direct     mean light the camera path brought back through a first scattering
                    event in a volume, by that vertex's next-event ray or the emission
                    found right after it (Cycles' PASS_VOLUME_DIRECT)
  Volume Indirect   the rest of what came back through a first scatter in a volume

Every image is (H, W, C) float32, row 0 at the top, like Film.image.
"""

from __future__ import annotations

import numpy as np

from .film import Film
from .integrator.paths import (
    AOV_COUNT,
    AOV_DALBEDO,
    AOV_DIFFUSE_COLOR,
    AOV_DNORMAL,
    AOV_DNORMAL_VOLUME,
    AOV_EMISSION,
    AOV_FIRST,
    AOV_GLOSSY_COLOR,
    AOV_HIT0,
    AOV_MIST,
    AOV_NORMAL,
    AOV_POSITION,
    AOV_TRANSMISSION_COLOR,
    AOV_VOLUME_DIRECT,
    AOV_VOLUME_INDIRECT,
    LIGHT_AOV_FIRST,
)
from .scene import Camera

DATA_PASSES = ("Depth", "Position", "Normal", "Mist")
DENOISING_PASSES = ("Denoising Normal", "Denoising Albedo")
LIGHT_COLUMNS = {"Emission": AOV_EMISSION, "Diffuse Color": AOV_DIFFUSE_COLOR,
                 "Glossy Color": AOV_GLOSSY_COLOR, "Transmission Color": AOV_TRANSMISSION_COLOR,
                 "Volume Direct": AOV_VOLUME_DIRECT,
                 "Volume Indirect": AOV_VOLUME_INDIRECT}
LIGHT_PASSES = tuple(LIGHT_COLUMNS)  # need film.light_aovs
MISS_DEPTH = 1e10  # Cycles' Depth where the camera saw the world
PANORAMIC = ("equirectangular", "fisheye_equidistant", "fisheye_equisolid", "mirrorball")


def _column(film: Film, first: int, count: int) -> np.ndarray:
    assert film.aov is not None, "the film holds no passes: render with scene.film.aovs on"
    c = first - AOV_FIRST if first < LIGHT_AOV_FIRST else AOV_COUNT + first - LIGHT_AOV_FIRST
    assert c + count <= film.aov.shape[1], "the film holds no light passes: render with film.light_aovs on"
    return film.aov[:, c:c + count]


def _mean(film: Film, first: int, count: int) -> np.ndarray:
    return _column(film, first, count) / np.maximum(film.n, 1)[:, None]


def _image(film: Film, values: np.ndarray) -> np.ndarray:
    return values.reshape(film.height, film.width, -1).astype(np.float32)


def depth_values(film: Film, camera: Camera) -> np.ndarray:
    """(P,) Depth: view-axis depth z = -(world-to-camera P).z (Blender's camera looks down
    -Z), or |P - camera| for panoramic cameras; MISS_DEPTH where sample 0 missed."""
    hit = _column(film, AOV_HIT0, 1)[:, 0] > 0.0
    p = _column(film, AOV_POSITION, 3)
    to_world = np.asarray(camera.to_world, np.float64)
    if camera.projection in PANORAMIC:
        depth = np.linalg.norm(p - to_world[:3, 3], axis=1)
    else:
        local = (p - to_world[:3, 3]) @ np.linalg.inv(to_world[:3, :3]).T
        depth = -local[:, 2]
    return np.where(hit, depth, MISS_DEPTH)


def camera_space(camera: Camera, directions: np.ndarray) -> np.ndarray:
    """World directions (P, 3) in Cycles' camera space: Blender's camera space with z
    negated, so z points forward (Cycles' sync scales the camera matrix by (1, 1, -1))."""
    local = directions @ np.linalg.inv(np.asarray(camera.to_world, np.float64)[:3, :3]).T
    return local * np.array([1.0, 1.0, -1.0])


def film_passes(film: Film, camera: Camera, names: tuple[str, ...] = DATA_PASSES + DENOISING_PASSES
                ) -> dict[str, np.ndarray]:
    """The named passes of the film as (H, W, C) float32 images, row 0 at the top."""
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name == "Depth":
            values = depth_values(film, camera)[:, None]
        elif name == "Position":
            values = _column(film, AOV_POSITION, 3)  # only sample 0 added to it
        elif name == "Normal":
            values = _mean(film, AOV_NORMAL, 3)
        elif name == "Mist":
            values = np.clip(1.0 - _mean(film, AOV_MIST, 1), 0.0, 1.0)  # Cycles' film_get_pass_pixel_mist
        elif name == "Denoising Normal":
            # Surfaces give world normals; a scatter in a medium gives (0, 0, -1) in camera space.
            volume = _mean(film, AOV_DNORMAL_VOLUME, 1) * np.array([0.0, 0.0, -1.0])
            values = camera_space(camera, _mean(film, AOV_DNORMAL, 3)) + volume
        elif name == "Denoising Albedo":
            values = _mean(film, AOV_DALBEDO, 3)
        elif name in LIGHT_COLUMNS:
            values = _mean(film, LIGHT_COLUMNS[name], 3)
        else:
            raise KeyError(f"Haze renders no pass named {name!r}")
        out[name] = _image(film, values)
    return out
