"""Which render passes a View Layer asks for, as Blender's pass system names them (no bpy
import: the engine and the session hand in the view layer and scene).

The names, channels and types are Cycles' (cycles/engine.py list_render_passes), so a
scene set up for Cycles gets the same passes in the compositor and in multilayer EXRs.
A pass that is not listed here is never computed: the session asks the renderer for the
AOV columns only when at least one of them is requested (or denoising needs them).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PassSpec:
    name: str
    channels: str  # Blender's channel ids, one letter per channel
    kind: str  # "VALUE", "VECTOR" or "COLOR"


COMBINED = PassSpec("Combined", "RGBA", "COLOR")
DEPTH = PassSpec("Depth", "Z", "VALUE")
MIST = PassSpec("Mist", "Z", "VALUE")
POSITION = PassSpec("Position", "XYZ", "VECTOR")
NORMAL = PassSpec("Normal", "XYZ", "VECTOR")
DENOISING_NORMAL = PassSpec("Denoising Normal", "XYZ", "VECTOR")
DENOISING_ALBEDO = PassSpec("Denoising Albedo", "RGB", "COLOR")
NOISY_IMAGE = PassSpec("Noisy Image", "RGBA", "COLOR")
DIFFUSE_COLOR = PassSpec("Diffuse Color", "RGB", "COLOR")
GLOSSY_COLOR = PassSpec("Glossy Color", "RGB", "COLOR")
EMISSION = PassSpec("Emission", "RGB", "COLOR")
TRANSMISSION_COLOR = PassSpec("Transmission Color", "RGB", "COLOR")
VOLUME_DIRECT = PassSpec("Volume Direct", "RGB", "COLOR")
VOLUME_INDIRECT = PassSpec("Volume Indirect", "RGB", "COLOR")
# renderer film.light_aovs
LIGHT_PASSES = (DIFFUSE_COLOR, GLOSSY_COLOR, TRANSMISSION_COLOR, EMISSION, VOLUME_DIRECT, VOLUME_INDIRECT)

# The View Layer toggles of the passes Haze writes, in Cycles' order (list_render_passes):
# (whose property: "view_layer" or "cycles" = view_layer.cycles, its name, the pass).
# Denoising data and Noisy Image depend on more than one toggle (requested_passes).
TOGGLES = (
    ("view_layer", "use_pass_z", DEPTH),
    ("view_layer", "use_pass_mist", MIST),
    ("view_layer", "use_pass_position", POSITION),
    ("view_layer", "use_pass_normal", NORMAL),
    ("view_layer", "use_pass_diffuse_color", DIFFUSE_COLOR),
    ("view_layer", "use_pass_glossy_color", GLOSSY_COLOR),
    ("view_layer", "use_pass_transmission_color", TRANSMISSION_COLOR),
    ("cycles", "use_pass_volume_direct", VOLUME_DIRECT),
    ("cycles", "use_pass_volume_indirect", VOLUME_INDIRECT),
    ("view_layer", "use_pass_emit", EMISSION),
)


def store_denoising_data(view_layer) -> bool:
    """Cycles' View Layer > Passes > Data > Denoising Data toggle (view_layer.cycles exists
    whenever the Cycles add-on is registered, as it is in Blender and in bpy)."""
    cycles = getattr(view_layer, "cycles", None)
    return bool(getattr(cycles, "denoising_store_passes", False))


def requested_passes(scene, view_layer) -> list[PassSpec]:
    """The passes Haze writes for this view layer, Combined first, then the toggled ones,
    Noisy Image and the denoising data last."""
    owners = {"view_layer": view_layer, "cycles": getattr(view_layer, "cycles", None)}
    passes = [COMBINED] + [spec for owner, name, spec in TOGGLES if getattr(owners[owner], name, False)]
    if denoising_enabled(scene):
        passes.append(NOISY_IMAGE)
    if store_denoising_data(view_layer):
        passes += [DENOISING_NORMAL, DENOISING_ALBEDO]
    return passes


def denoising_enabled(scene) -> bool:
    haze = getattr(scene, "haze", None)
    return bool(getattr(haze, "use_denoising", False))


def needs_aovs(passes: list[PassSpec], denoise: bool) -> bool:
    """True when the renderer must write the AOV columns (any pass beyond the image)."""
    return denoise or any(p not in (COMBINED, NOISY_IMAGE) for p in passes)


def needs_light_aovs(passes: list[PassSpec]) -> bool:
    """True when the renderer must also write the light and colour passes' columns."""
    return any(p in LIGHT_PASSES for p in passes)
