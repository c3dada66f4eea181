"""Output settings Haze renders without are warned about, naming the scene (no bpy needed:
addon.export.camera.render_warnings reads plain attributes)."""

from __future__ import annotations

from types import SimpleNamespace

from addon.export.camera import render_warnings
from addon.export.messages import Messages


def warnings_for(**settings) -> list[str]:
    render = SimpleNamespace(pixel_aspect_x=1.0, pixel_aspect_y=1.0, use_motion_blur=False)
    for name, value in settings.items():
        setattr(render, name, value)
    messages = Messages()
    render_warnings(render, "Scene", messages)
    return messages.warnings


def test_default_output_settings_give_no_warning():
    assert warnings_for() == []


def test_motion_blur_is_warned_about_once_naming_the_scene():
    messages = warnings_for(use_motion_blur=True)
    assert messages == ["Scene 'Scene': motion blur is not supported: the scene renders as it is "
                        "at the current frame"]


def test_non_square_pixels_are_warned_about():
    assert warnings_for(pixel_aspect_x=2.0) == ["Scene 'Scene': non-square pixel aspect is ignored"]


def test_hair_particle_systems_are_warned_about_by_name():
    from addon.export.scene import warn_hair_particles

    def system(name, kind, render_type):
        return SimpleNamespace(name=name, settings=SimpleNamespace(type=kind, render_type=render_type))

    obj = SimpleNamespace(name="Head", particle_systems=[system("Fur", "HAIR", "PATH"),
                                                         system("Sparks", "EMITTER", "OBJECT"),
                                                         system("Pebbles", "HAIR", "COLLECTION")])
    messages = Messages()
    warn_hair_particles(obj, messages)
    assert messages.warnings == ["Object 'Head': hair particle system 'Fur' is not rendered "
                                 "(Haze does not render hair yet)"]
