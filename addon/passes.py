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
LIGHT_PASSES = (DIFFUSE_COLOR, GLOSSY_COLOR, EMISSION)  # renderer film.light_aovs


def store_denoising_data(view_layer) -> bool:
    """Cycles' View Layer > Passes > Data > Denoising Data toggle (view_layer.cycles exists
    whenever the Cycles add-on is registered, as it is in Blender and in bpy)."""
    cycles = getattr(view_layer, "cycles", None)
    return bool(getattr(cycles, "denoising_store_passes", False))


def requested_passes(scene, view_layer) -> list[PassSpec]:
    """The passes Haze writes for this view layer, Combined first."""
    passes = [COMBINED]
    if getattr(view_layer, "use_pass_z", False):
        passes.append(DEPTH)
    if getattr(view_layer, "use_pass_mist", False):
        passes.append(MIST)
    if getattr(view_layer, "use_pass_position", False):
        passes.append(POSITION)
    if getattr(view_layer, "use_pass_normal", False):
        passes.append(NORMAL)
    if denoising_enabled(scene):
        passes.append(NOISY_IMAGE)
    if store_denoising_data(view_layer):
        passes += [DENOISING_NORMAL, DENOISING_ALBEDO]
    if getattr(view_layer, "use_pass_diffuse_color", False):
        passes.append(DIFFUSE_COLOR)
    if getattr(view_layer, "use_pass_glossy_color", False):
        passes.append(GLOSSY_COLOR)
    if getattr(view_layer, "use_pass_emit", False):
        passes.append(EMISSION)
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
