"""A whole evaluated Blender scene (depsgraph) to a Haze Scene.

Everything comes from the evaluated dependency graph: modifiers are applied, instances
(particles, geometry nodes, collection instances) are included, and objects hidden from the
render are excluded. Instances of one object under one instancer are merged into one Haze
mesh, so thousands of instances do not become thousands of meshes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from renderer.cores import usable_cores
from renderer.scene import Film, IntegratorSettings, Scene

from .camera import export_camera, film_size, render_region
from .lights import area_light, point_light, spot_light, sun_light
from .materials import MaterialLibrary
from .mesh import LocalGeometry, MeshPart, build_meshes, read_geometry, transform
from .messages import Messages, object_subject
from .object_info import add_object_info
from .procedural_volume import object_medium
from .volumes import VolumeExporter, is_smoke_domain
from .world import world_environment

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
RAY_VISIBILITY = ("camera", "diffuse", "glossy", "transmission", "volume_scatter", "shadow")
UNSUPPORTED_TYPES = {"CURVES": "hair curves", "POINTCLOUD": "point clouds", "GREASEPENCIL": "Grease Pencil"}


@dataclass
class ExportResult:
    scene: Scene
    warnings: list[str] = field(default_factory=list)
    light_names: list[str] = field(default_factory=list)  # Blender object of each scene.lights entry
    volume_stats: list[str] = field(default_factory=list)  # size and memory of each volume grid


def integrator_settings(haze_settings) -> IntegratorSettings:
    """IntegratorSettings from the scene's Haze properties (scene.haze)."""
    return IntegratorSettings(
        spp=int(haze_settings.samples),
        max_bounces=int(haze_settings.max_bounces),
        seed=int(haze_settings.seed),
        sampling=haze_settings.sampling,
        transmittance=haze_settings.transmittance,
        distance_sampling=haze_settings.distance_sampling,
        equiangular=bool(haze_settings.equiangular),
        majorant_grid=bool(haze_settings.majorant_grid),
        time_limit=float(haze_settings.time_limit),
    )


def worker_count(haze_settings, render=None) -> int:
    """Haze's Workers setting, or when it is 0 (automatic) Blender's Threads (Render >
    Performance, or `blender -t N`, which Blender reports as render.threads) capped by the
    cores this process may use (its CPU affinity and quota, renderer.cores)."""
    if int(haze_settings.workers) > 0:
        return int(haze_settings.workers)
    cores = usable_cores()
    if render is None:
        return cores
    threads = max(1, int(render.threads))
    return threads if render.threads_mode == "FIXED" else min(threads, cores)


def instance_group(instance) -> str:
    """Name of the Haze mesh an object instance goes into."""
    name = instance.object.name
    if instance.is_instance and instance.parent is not None:
        return f"{instance.parent.name}/{name}"
    return name


def is_rendered(instance, render_depsgraph: bool) -> bool:
    if instance.is_instance:
        return True
    if not instance.show_self:
        return False  # e.g. a particle emitter whose own mesh is hidden
    # A viewport depsgraph (the export operator) still contains render-disabled objects.
    original = instance.object.original
    return render_depsgraph or original is None or not original.hide_render


def warn_hair_particles(obj, messages: Messages) -> None:
    """Hair particle systems drawn as strands: Cycles renders them as curves, Haze not yet."""
    for system in getattr(obj, "particle_systems", ()):
        settings = system.settings
        if settings.type == "HAIR" and settings.render_type == "PATH":
            messages.warn(object_subject(obj.name), f"hair particle system '{system.name}' is not rendered "
                          "(Haze does not render hair yet)")


def used_images(images: list, materials: list) -> list:
    """The images some exported material's program reads (each once)."""
    read = {name for m in materials if m.program is not None for name in m.program.images}
    return [image for image in images if image.name in read]


class MeshCollector:
    """Reads geometry once per evaluated mesh and groups instances into Haze meshes."""

    def __init__(self, library: MaterialLibrary, messages: Messages) -> None:
        self.library = library
        self.messages = messages
        self.groups: dict[str, list[MeshPart]] = {}
        self._geometry_cache: dict[tuple, LocalGeometry | None] = {}
        # group -> material name -> that instance's procedural Medium (procedural_volume.py)
        self.procedural: dict[str, dict[str, object]] = {}

    def add(self, instance) -> None:
        obj = instance.object
        self._warn_ignored_visibility(obj)
        materials = [self.library.get(m).material for m in self._slot_materials(obj)]
        # Only the corner attributes some program of this object reads are exported.
        needed = tuple(dict.fromkeys(a for m in materials if m.program for a in m.program.attributes))
        geometry = self._local_geometry(obj, needed)
        if geometry is None or len(geometry.triangles) == 0:
            return
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        world = transform(geometry, matrix)
        random_id = instance.random_id if instance.is_instance else None
        add_object_info(world.attributes, needed, len(world.triangles), obj, matrix, random_id)
        names = [m.name for m in materials]
        group = instance_group(instance)
        templates = self._procedural_media(obj)
        if templates:  # one medium per instance: its coordinates and box are the instance's
            group = f"{group} #{len(self.procedural)}" if group in self.groups else group
            texspace = (getattr(obj.data, "texspace_location", (0.0, 0.0, 0.0)),
                        getattr(obj.data, "texspace_size", (1.0, 1.0, 1.0)))
            self.procedural[group] = {
                material: object_medium(template, f"{template.name} [{group}]", matrix, geometry.positions,
                                        *texspace)
                for material, template in templates.items()}
        self.groups.setdefault(group, []).append(MeshPart(world, names))

    def _procedural_media(self, obj) -> dict:
        """Procedural media (material name -> template Medium) of the object's materials."""
        exports = [self.library.get(m) for m in self._slot_materials(obj)]
        return {e.material.name: e.medium for e in exports
                if e.medium is not None and e.medium.program is not None}

    def _warn_ignored_visibility(self, obj) -> None:
        hidden = [name for name in RAY_VISIBILITY if not getattr(obj, f"visible_{name}", True)]
        if hidden or getattr(obj, "is_holdout", False):
            self.messages.warn(object_subject(obj.name), "ray visibility and holdout settings are ignored; "
                               "the object is rendered like any other")

    def _slot_materials(self, obj) -> list:
        materials = [slot.material for slot in obj.material_slots]
        if not materials and obj.data is not None and hasattr(obj.data, "materials"):
            materials = list(obj.data.materials)  # e.g. geometry-nodes output without object slots
        return materials or [None]

    def _local_geometry(self, obj, attributes: tuple[str, ...]) -> LocalGeometry | None:
        data = obj.data
        key = (obj.name, data.name if data is not None else "", data.as_pointer() if data is not None else 0,
               attributes)
        if key not in self._geometry_cache:
            self._geometry_cache[key] = self._read(obj, attributes)
        return self._geometry_cache[key]

    def _read(self, obj, attributes: tuple[str, ...]) -> LocalGeometry | None:
        if obj.type == "MESH":
            return read_geometry(obj.data, attributes)
        mesh = obj.to_mesh()  # curves, text, surfaces, metaballs: their evaluated mesh
        try:
            return read_geometry(mesh, attributes) if mesh is not None else None
        finally:
            obj.to_mesh_clear()

    def meshes(self) -> list:
        medium_of = self.library.medium_by_material()
        result = []
        for name, parts in self.groups.items():
            own = {material: medium.name for material, medium in self.procedural.get(name, {}).items()}
            result.extend(build_meshes(name, parts, {**medium_of, **own}, self.messages))
        return result

    def procedural_media(self) -> list:
        return [medium for media in self.procedural.values() for medium in media.values()]


def add_light(instance, library: MaterialLibrary, lights: list, light_names: list[str], emitters: list,
              messages: Messages) -> None:
    obj = instance.object
    count = len(lights)
    light = obj.data
    matrix = np.array(instance.matrix_world, dtype=np.float64)
    subject = object_subject(obj.name)
    if light.type == "POINT":
        lights.append(point_light(light, matrix, subject, messages))
    elif light.type == "SPOT":
        lights.append(spot_light(light, matrix, subject, messages))
    elif light.type == "SUN":
        lights.append(sun_light(light, matrix))
    elif light.type == "AREA":
        emitter = area_light(light, matrix, instance_group(instance), messages)
        if emitter is not None:
            mesh, material = emitter
            library.add(material)
            emitters.append(mesh)
    if len(lights) > count:
        light_names.append(instance_group(instance))


MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}  # Cycles' exponents


def _export_mist(world, film: Film) -> None:
    """World > Mist Pass settings (start, depth, falloff) for the Mist pass."""
    mist = getattr(world, "mist_settings", None)
    if mist is None:
        return
    film.mist_start = float(mist.start)
    film.mist_depth = float(mist.depth)
    film.mist_falloff = MIST_FALLOFF.get(mist.falloff, 2.0)


def export_scene(depsgraph, film: Film | None = None, render_depsgraph: bool = True) -> ExportResult:
    """Haze Scene of an evaluated depsgraph; `film` overrides the output size (e.g. the engine's)."""
    messages = Messages()
    scene = depsgraph.scene_eval
    film = film or Film(*film_size(scene.render))
    film.region = render_region(scene.render, film.width, film.height)
    film.transparent = bool(scene.render.film_transparent)
    _export_mist(scene.world, film)
    camera_object = scene.camera.evaluated_get(depsgraph) if scene.camera is not None else None
    camera = export_camera(camera_object, film, scene.render, scene.name, messages)
    library = MaterialLibrary(messages)
    collector = MeshCollector(library, messages)
    lights: list = []
    light_names: list[str] = []
    emitters: list = []
    volumes = VolumeExporter(library, messages, scene.frame_current, scene.frame_subframe)
    for instance in depsgraph.object_instances:
        if not instance.is_instance and instance.object.type == "MESH" and (
                render_depsgraph or not getattr(instance.object.original, "hide_render", False)):
            warn_hair_particles(instance.object, messages)  # even where the emitter itself is hidden
        if not is_rendered(instance, render_depsgraph):
            continue
        kind = instance.object.type
        if kind == "VOLUME" or (kind == "MESH" and is_smoke_domain(instance.object)):
            volumes.add(instance, instance_group(instance))
        elif kind in GEOMETRY_TYPES:
            collector.add(instance)
        elif kind == "LIGHT":
            add_light(instance, library, lights, light_names, emitters, messages)
        elif kind in UNSUPPORTED_TYPES:
            messages.warn(object_subject(instance.object.name),
                          f"{UNSUPPORTED_TYPES[kind]} are not supported by Haze and are not rendered")
    environment, world_medium = world_environment(scene.world, messages)
    volume_meshes, volume_media = volumes.export()
    meshes = collector.meshes() + emitters + volume_meshes
    used_materials = {name for mesh in meshes for name in mesh.materials}
    used_media = {mesh.medium for mesh in meshes if mesh.medium is not None}
    procedural = [m for m in collector.procedural_media() if m.name in used_media]
    media = (library.media(used_media) + procedural + volume_media
             + ([world_medium] if world_medium is not None else []))
    result = Scene(
        camera=camera,
        film=film,
        integrator=integrator_settings(scene.haze),
        materials=library.materials(used_materials),
        images=used_images(library.images.list(), library.materials(used_materials)),
        meshes=meshes,
        lights=lights,
        media=media,
        environment=environment,
        medium=world_medium.name if world_medium is not None else None,
    )
    return ExportResult(result, messages.warnings, light_names, volumes.stats)
