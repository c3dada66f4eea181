"""Add > Volume: the paper's smoke ball, gaussian-random smoke, and density grids from files.

Each operator computes a density array, writes it exactly into an OpenVDB file and adds a
Volume object that loads that file, with a volume material reading its "density" grid. The
file lives next to the saved .blend (//haze_volumes/), or, for an unsaved .blend, in Haze's
folder of Blender's user data files (the report says where), so nothing is lost on closing.
Volume files are what Blender, Cycles and Haze all read; the redo panel (Adjust Last
Operation) changes the generator's settings afterwards. Clipping is set to 0 on the new
volumes: every voxel of the array is rendered, which keeps Haze's export equal to it.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import bpy
import numpy as np
from bpy.props import FloatProperty, FloatVectorProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from .volume_grids import (
    GridFileError,
    box_index_to_object,
    gaussian_smoke_density,
    read_npy,
    read_pbrt,
    smoke_ball_density,
    write_vdb,
)

VOLUME_FOLDER = "haze_volumes"
PBRT_SIGMA_A = np.array([0.0011, 0.0024, 0.014])  # pbrt-v3's defaults for a named medium
PBRT_SIGMA_S = np.array([2.55, 3.21, 3.77])


def volume_folder() -> tuple[Path, bool]:
    """(folder for new volume files, whether it is relative to the saved .blend)."""
    if bpy.data.filepath:
        return Path(bpy.path.abspath("//")) / VOLUME_FOLDER, True
    return Path(bpy.utils.user_resource("DATAFILES", path=VOLUME_FOLDER, create=True)), False


def grid_file(name: str, grids: dict[str, np.ndarray], p0, p1, folder: Path | None = None) -> str:
    """Write `grids` (all of one shape) filling p0..p1 to a file named after `name` and the data
    (equal grids share a file), in `folder` or the default one; returns the path as Blender
    should store it (relative to the .blend where it can be)."""
    relative = folder is None and bool(bpy.data.filepath)
    folder = volume_folder()[0] if folder is None else Path(folder)
    digest = hashlib.sha1(np.float64([*p0, *p1]).tobytes())
    for key, values in sorted(grids.items()):
        digest.update(key.encode() + np.ascontiguousarray(values, np.float32).tobytes())
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_") or "grid"
    path = folder / f"{stem}-{digest.hexdigest()[:12]}.vdb"
    if not path.is_file():
        shape = next(iter(grids.values())).shape
        write_vdb(path, grids, box_index_to_object(p0, p1, shape))
    return f"//{VOLUME_FOLDER}/{path.name}" if relative else str(path)


def new_node_material(name: str):
    """(material, its empty node tree, a Material Output node in it)."""
    material = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        material.use_nodes = True  # Blender 5.0 always uses nodes and deprecates the switch
    tree = material.node_tree
    tree.nodes.clear()
    return material, tree, tree.nodes.new("ShaderNodeOutputMaterial")


def principled_volume_material(name: str, color, density: float, anisotropy: float = 0.0):
    """Principled Volume reading the "density" grid: scattering Color x Density x grid value,
    absorption (1 - Color) x Density x grid value (black Absorption Color)."""
    material, tree, output = new_node_material(name)
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.location = (-300, 0)
    volume.inputs["Color"].default_value = (*color, 1.0)
    volume.inputs["Density"].default_value = density
    volume.inputs["Anisotropy"].default_value = anisotropy
    volume.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    tree.links.new(volume.outputs["Volume"], output.inputs["Volume"])
    return material


def coefficient_material(name: str, sigma_a, sigma_s, anisotropy: float = 0.0):
    """Volume Scatter + Volume Absorption whose Density is the "density" grid (Attribute node)
    times constants: sigma_s = Color_s x max(sigma_s) x grid and
    sigma_a = (1 - Color_a) x max(sigma_a) x grid."""
    material, tree, output = new_node_material(name)
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "density"
    attribute.location = (-700, 0)
    add = tree.nodes.new("ShaderNodeAddShader")
    add.location = (-150, 0)
    tree.links.new(add.outputs[0], output.inputs["Volume"])
    for index, (kind, sigma) in enumerate((("ShaderNodeVolumeScatter", sigma_s),
                                          ("ShaderNodeVolumeAbsorption", sigma_a))):
        peak = max(float(max(sigma)), 0.0)
        node = tree.nodes.new(kind)
        node.location = (-350, 150 - 300 * index)
        scaled = np.asarray(sigma, np.float64) / peak if peak > 0.0 else np.zeros(3)
        color = scaled if kind == "ShaderNodeVolumeScatter" else 1.0 - scaled
        node.inputs["Color"].default_value = (*color, 1.0)
        if kind == "ShaderNodeVolumeScatter":
            node.inputs["Anisotropy"].default_value = anisotropy
        multiply = tree.nodes.new("ShaderNodeMath")
        multiply.operation = "MULTIPLY"
        multiply.location = (-520, 150 - 300 * index)
        multiply.inputs[1].default_value = peak
        tree.links.new(attribute.outputs["Fac"], multiply.inputs[0])
        tree.links.new(multiply.outputs[0], node.inputs["Density"])
        tree.links.new(node.outputs[0], add.inputs[index])
    return material


def add_volume_object(context, name: str, values: np.ndarray | dict[str, np.ndarray], p0, p1, material,
                      folder: Path | None = None):
    """A new Volume object at the 3D cursor loading `values` (filling p0..p1 in object space):
    one array (the "density" grid) or a dict of grids of one shape."""
    grids = values if isinstance(values, dict) else {"density": values}
    stored = grid_file(name, grids, p0, p1, folder)
    volume = bpy.data.volumes.new(name)
    volume.filepath = stored
    volume.render.clipping = 0.0
    volume.materials.append(material)
    obj = bpy.data.objects.new(name, volume)
    context.collection.objects.link(obj)
    obj.location = context.scene.cursor.location
    for other in context.selected_objects:
        other.select_set(False)
    obj.select_set(True)
    if context.view_layer is not None:
        context.view_layer.objects.active = obj
    return obj


def centred_box(shape, size: float) -> tuple[np.ndarray, np.ndarray]:
    """A box of cubic voxels around the origin whose longest side is `size`."""
    extent = np.array(shape[::-1], np.float64) / max(shape) * size
    return -extent / 2.0, extent / 2.0


class VolumeAdder:
    """Shared reporting of the add operators: file errors become messages, not tracebacks."""

    def add(self, context, name: str, values: np.ndarray, p0, p1, material) -> set[str]:
        try:
            add_volume_object(context, name, values, p0, p1, material)
        except (RuntimeError, OSError) as error:
            bpy.data.materials.remove(material)
            self.report({"ERROR"}, f"{name}: {error}")
            return {"CANCELLED"}
        if not bpy.data.filepath:
            self.report({"INFO"}, f"The .blend is not saved: the grid file is kept in {volume_folder()[0]}")
        return {"FINISHED"}


class HAZE_OT_add_smoke_ball(VolumeAdder, bpy.types.Operator):
    """Add the paper's smoke ball (Fig. 3): density falloff^-(d + 2) at d voxels from the centre"""

    bl_idname = "object.haze_add_smoke_ball"
    bl_label = "Smoke Ball (Haze)"
    bl_options = {"REGISTER", "UNDO"}

    resolution: IntProperty(name="Resolution", description="Voxels along each side", default=11, min=3,
                            max=256)
    radius: FloatProperty(name="Radius", description="Ball radius in voxels (0: (resolution - 2) / 2)",
                          default=0.0, min=0.0, max=256.0)
    falloff: FloatProperty(name="Falloff", description="Density divides by this per voxel from the centre",
                           default=2.0, min=1.0, max=100.0)
    size: FloatProperty(name="Size", description="Edge length of the grid box", default=1.2, min=1e-4,
                        unit="LENGTH", subtype="DISTANCE")
    density: FloatProperty(name="Density", description="Extinction per unit length at grid value 1",
                           default=100.0, min=0.0)

    def execute(self, context):
        values = smoke_ball_density(self.resolution, self.radius or None, self.falloff)
        p0, p1 = centred_box(values.shape, self.size)
        # Fig. 5's coefficients: sigma_s 10 and sigma_a 90 per unit density for Density 100.
        material = principled_volume_material("Smoke Ball", (0.1, 0.1, 0.1), self.density)
        return self.add(context, "Smoke Ball", values, p0, p1, material)


class HAZE_OT_add_gaussian_smoke(VolumeAdder, bpy.types.Operator):
    """Add seeded gaussian-random smoke (the paper's Fig. 6 yellow smoke)"""

    bl_idname = "object.haze_add_gaussian_smoke"
    bl_label = "Gaussian Smoke (Haze)"
    bl_options = {"REGISTER", "UNDO"}

    resolution: IntProperty(name="Resolution", default=32, min=4, max=256)
    seed: IntProperty(name="Seed", default=6, min=0)
    blobs: IntProperty(name="Puffs", description="Number of gaussian puffs", default=24, min=1, max=1000)
    size: FloatProperty(name="Size", default=1.3, min=1e-4, unit="LENGTH", subtype="DISTANCE")
    density: FloatProperty(name="Density", description="Extinction per unit length at the densest voxel",
                           default=4.8, min=0.0)
    color: FloatVectorProperty(name="Color", subtype="COLOR", size=3, min=0.0, max=1.0,
                               default=(0.7, 0.4375, 0.1))
    anisotropy: FloatProperty(name="Anisotropy", default=-0.7, min=-1.0, max=1.0)

    def execute(self, context):
        values = gaussian_smoke_density(self.resolution, self.seed, self.blobs)
        p0, p1 = centred_box(values.shape, self.size)
        # Defaults are Fig. 6's sigma_a [2.4, 4.5, 7.2], sigma_s [5.6, 3.5, 0.8] (extinction 8)
        # scaled by the gallery's peak density 0.6.
        material = principled_volume_material("Gaussian Smoke", tuple(self.color), self.density,
                                              self.anisotropy)
        return self.add(context, "Gaussian Smoke", values, p0, p1, material)


class HAZE_OT_import_density_grid(VolumeAdder, bpy.types.Operator, ImportHelper):
    """Add a volume from a density array: a .npy file (nz, ny, nx), or a pbrt-v3 'heterogeneous' medium"""

    bl_idname = "object.haze_import_density_grid"
    bl_label = "Density Grid (.npy, pbrt)"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".npy"
    filter_glob: StringProperty(default="*.npy;*.pbrt", options={"HIDDEN"})
    size: FloatProperty(name="Size", description="Longest side of the grid box for .npy files (pbrt "
                        "files give their own p0, p1)", default=2.0, min=1e-4, unit="LENGTH",
                        subtype="DISTANCE")
    density: FloatProperty(name="Density", description="Extinction per unit length at grid value 1 (.npy)",
                           default=1.0, min=0.0)

    def execute(self, context):
        path = Path(bpy.path.abspath(self.filepath))
        try:
            if path.suffix.lower() == ".npy":
                values = read_npy(path)
                p0, p1 = centred_box(values.shape, self.size)
                material = principled_volume_material(path.stem, (0.8, 0.8, 0.8), self.density)
            else:
                values, p0, p1 = read_pbrt(path)
                sigma_a, sigma_s, g = pbrt_coefficients(path)
                material = coefficient_material(path.stem, sigma_a, sigma_s, g)
        except GridFileError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        return self.add(context, path.stem, values, p0, p1, material)


def pbrt_coefficients(path: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """sigma_a, sigma_s (times "scale") and g of a pbrt heterogeneous medium (pbrt's defaults)."""
    from .volume_grids import pbrt_numbers, pbrt_parameters

    parameters = pbrt_parameters(path.read_text(errors="replace"))
    scale = float(pbrt_numbers(parameters, "scale", 1)[0]) if "scale" in parameters else 1.0
    sigma_a = pbrt_numbers(parameters, "sigma_a", 3) if "sigma_a" in parameters else PBRT_SIGMA_A
    sigma_s = pbrt_numbers(parameters, "sigma_s", 3) if "sigma_s" in parameters else PBRT_SIGMA_S
    g = float(pbrt_numbers(parameters, "g", 1)[0]) if "g" in parameters else 0.0
    return sigma_a * scale, sigma_s * scale, g


CLASSES = (HAZE_OT_add_smoke_ball, HAZE_OT_add_gaussian_smoke, HAZE_OT_import_density_grid)


def menu_add_volume(self, context) -> None:
    layout = self.layout
    layout.separator()
    layout.operator(HAZE_OT_add_smoke_ball.bl_idname, icon="VOLUME_DATA")
    layout.operator(HAZE_OT_add_gaussian_smoke.bl_idname, icon="VOLUME_DATA")
    layout.operator(HAZE_OT_import_density_grid.bl_idname, icon="FILE_VOLUME")


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.VIEW3D_MT_volume_add.append(menu_add_volume)


def unregister() -> None:
    bpy.types.VIEW3D_MT_volume_add.remove(menu_add_volume)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
