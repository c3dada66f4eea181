"""Haze's render settings, stored per scene as `scene.haze`."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

SAMPLING_ITEMS = [
    ("mis", "MIS", "Combine light sampling and BSDF/phase sampling (multiple importance sampling)"),
    ("nee", "Light", "Light sampling only (next-event estimation)"),
    ("bsdf", "BSDF", "BSDF and phase-function sampling only; lights are found by chance"),
]

TRANSMITTANCE_ITEMS = [
    ("ratio", "Ratio Tracking", "Unbiased transmittance of shadow rays in grid media, low variance"),
    ("delta", "Delta Tracking", "Binary transmittance estimate; cheaper per ray, noisier"),
]

DISTANCE_SAMPLING_ITEMS = [
    ("spectral_mis", "Spectral MIS", "Sample distances in coloured media by combining all channels"),
    ("uniform", "Uniform", "Sample distances with the mean extinction"),
]


class HazeRenderSettings(bpy.types.PropertyGroup):
    """Settings of the Haze path tracer for one scene."""

    samples: IntProperty(
        name="Samples",
        description="Samples per pixel to render",
        default=64,
        min=1,
        max=1 << 24,  # renderer.validate.scene.MAX_SPP
        soft_max=4096,
    )
    time_limit: FloatProperty(
        name="Time Limit",
        description="Stop the render after this time, keeping the samples done so far (0 = no limit)",
        default=0.0,
        min=0.0,
        subtype="TIME_ABSOLUTE",
        unit="TIME_ABSOLUTE",
    )
    target_error: FloatProperty(
        name="Noise Threshold",
        description=(
            "Stop early once the estimated relative mean squared error of the image falls below "
            "this value (0 = render all samples)"
        ),
        default=0.0,
        min=0.0,
        soft_max=0.1,
        precision=4,
    )
    max_bounces: IntProperty(
        name="Max Bounces",
        description="Maximum number of scattering events (surface or volume) of a path, as in Cycles; "
        "0 = direct light only",
        default=8,
        min=0,
        max=1024,  # renderer.validate.scene.MAX_BOUNCES, Cycles' own limit
        soft_max=64,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random number sequences; the same seed renders the same image",
        default=0,
        min=0,
    )
    sampling: EnumProperty(
        name="Sampling",
        description="How paths find light",
        items=SAMPLING_ITEMS,
        default="mis",
    )
    transmittance: EnumProperty(
        name="Transmittance",
        description="Estimator of shadow-ray transmittance in heterogeneous media",
        items=TRANSMITTANCE_ITEMS,
        default="ratio",
    )
    distance_sampling: EnumProperty(
        name="Distance Sampling",
        description="How free-flight distances are sampled in media whose extinction depends on colour",
        items=DISTANCE_SAMPLING_ITEMS,
        default="spectral_mis",
    )
    equiangular: BoolProperty(
        name="Equiangular Sampling",
        description="Also sample scattering points near lights in homogeneous media (combined by MIS)",
        default=True,
    )
    majorant_grid: BoolProperty(
        name="Majorant Grid",
        description="Track rays through grid media with a coarse grid of local density bounds "
        "instead of one global bound",
        default=True,
    )
    use_denoising: BoolProperty(
        name="Denoise",
        description="Denoise the final image with Open Image Denoise (the one in Blender), guided by "
        "the Denoising Albedo and Normal passes; the raw image is kept as the Noisy Image pass",
        default=False,
    )
    workers: IntProperty(
        name="Workers",
        description="Worker processes rendering in parallel (0 = automatic: Blender's Threads setting, "
        "at most the cores this process may use)",
        default=0,
        min=0,
        soft_max=64,
    )
    cluster: StringProperty(
        name="Cluster",
        description="Render on a Dask cluster: a scheduler address such as tcp://HOST:8786 (its "
        "workers need the same Haze installed), or 'local' for a Dask cluster of Workers processes "
        "on this machine. Empty: this machine's own worker processes. Same image either way",
        default="",
    )


def register() -> None:
    bpy.utils.register_class(HazeRenderSettings)
    bpy.types.Scene.haze = PointerProperty(type=HazeRenderSettings, name="Haze Render Settings")


def unregister() -> None:
    del bpy.types.Scene.haze
    bpy.utils.unregister_class(HazeRenderSettings)
