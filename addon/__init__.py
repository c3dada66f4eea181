"""Haze: a volumetric path tracer as a Blender render engine.

Installed as an extension (the built zip) the renderer and its dependencies come from the
bundled wheels. Enabled from a clone of the repository (this folder linked into Blender's
add-ons folder, or imported with the repository root on sys.path) the renderer is taken
from the checkout next to it.
"""

import sys

from . import bootstrap

bootstrap.make_renderer_importable(__file__)
if "bpy" in sys.modules:  # loaded into Blender (not merely imported by a unit test)
    # Before anything can import numba: the command line's cache folder, not the add-on's.
    bootstrap.configure_numba_cache()

# Used when enabled as a legacy add-on from a clone; extensions read blender_manifest.toml.
bl_info = {
    "name": "Haze",
    "author": "Haze developers",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "category": "Render",
    "description": "Volumetric path tracer (numpy, numba, Embree)",
}

MODULE_NAMES = ("properties", "preferences", "engine", "ui", "operators", "operators_volume",
                "operators_cluster")


def _modules():
    import importlib

    return [importlib.import_module(f".{name}", __name__) for name in MODULE_NAMES]


def register() -> None:
    for module in _modules():
        module.register()
    # Compile the kernels while the user sets up the scene, not after pressing F12.
    from .preferences import start_background_compile

    start_background_compile()


def unregister() -> None:
    from . import background

    background.stop()
    stop_render_workers()
    for module in reversed(_modules()):
        module.unregister()


def stop_render_workers() -> None:
    """Persistent render workers must not outlive the add-on (only if the renderer is loaded)."""
    render = sys.modules.get("renderer.render")
    if render is not None and hasattr(render, "shutdown_workers"):
        render.shutdown_workers()
    cluster = sys.modules.get("renderer.cluster")  # connections and LocalClusters, if any
    if cluster is not None and hasattr(cluster, "shutdown_clusters"):
        cluster.shutdown_clusters()
