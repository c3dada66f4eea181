"""Evaluated Blender geometry to world-space triangle meshes, with numpy only.

Every array is read with foreach_get into a preallocated buffer and transformed with numpy;
there is no Python loop over vertices or faces, so a million triangles export in well under
a second.

Shading normals follow the mesh's normals domain (Blender 4.1+): FACE = flat (no normals),
POINT = one normal per vertex, CORNER = mixed smooth/sharp, exported by giving every face
corner its own vertex with its corner normal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from renderer.scene import CornerAttribute, Mesh

from .messages import Messages, object_subject


@dataclass
class LocalGeometry:
    """Triangles of one evaluated mesh in object space."""

    positions: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) int32 into positions
    normals: np.ndarray | None  # (V, 3) float32, or None for flat shading
    slots: np.ndarray  # (T,) int32 material slot of each triangle
    topology: np.ndarray  # (T, 3) int32 into the mesh's own vertices (for closedness checks)
    # Corner attributes shader programs read, by name (renderer.scene.CornerAttribute): (T, 3, k).
    attributes: dict[str, np.ndarray] = field(default_factory=dict)


def read_array(collection, attribute: str, count: int, width: int, dtype) -> np.ndarray:
    buffer = np.empty(count * width, dtype=dtype)
    if count:
        collection.foreach_get(attribute, buffer)
    return buffer.reshape(count, width) if width > 1 else buffer


def read_attribute(mesh, name: str, width: int, dtype, fallback: int | None = None) -> np.ndarray | None:
    """A generic attribute's values (stored contiguously: far faster than struct collections)."""
    attribute = mesh.attributes.get(name)
    if attribute is None:
        return None
    field = {1: "value", 3: "vector"}[width]
    return read_array(attribute.data, field, len(attribute.data), width, dtype)


def active_render_uv(mesh):
    return next((layer for layer in mesh.uv_layers if layer.active_render), None)


def corner_attribute(mesh, name: str, corners: np.ndarray, positions: np.ndarray, topology: np.ndarray):
    """(T, 3, k) float32 values of attribute `name` at the triangles' corners, or None when
    the mesh lacks it. `positions` are the mesh's vertices, `topology` the triangles' vertex
    indices, `corners` their corner (loop) indices."""
    if name.startswith("uv:"):
        layer = mesh.uv_layers.get(name[3:]) if name[3:] else active_render_uv(mesh)
        if layer is None:
            return None
        return read_array(layer.uv, "vector", len(mesh.loops), 2, np.float32)[corners]
    if name.startswith("attr:"):
        return named_attribute(mesh, name[5:], corners, topology)
    if name.startswith(("tangent:", "tangent_sign:")):
        return tangent_attribute(mesh, name, corners)
    local = positions[topology]
    if name == "object":
        return local
    if name == "generated":
        # Blender's texture space: location +- size maps to [0, 1] (Cycles' Generated).
        location = np.array(mesh.texspace_location, np.float32)
        size = np.array(mesh.texspace_size, np.float32)
        size = np.where(size != 0.0, size, np.float32(1.0))
        return (local - (location - size)) / (2.0 * size)
    return None


def tangent_attribute(mesh, name: str, corners: np.ndarray):
    """MikkTSpace tangents of a UV map ("tangent:<map>", (T, 3, 3), object space) or their
    bitangent signs ("tangent_sign:<map>", (T, 3, 1)), per corner, as Blender computes them
    for Cycles (mesh.calc_tangents); None without the UV map or where Blender cannot compute
    them (the Normal Map node then keeps the mesh's normal, as Cycles does)."""
    uv_name = name.split(":", 1)[1]
    layer = mesh.uv_layers.get(uv_name) if uv_name else active_render_uv(mesh)
    if layer is None:
        return None
    try:
        mesh.calc_tangents(uvmap=layer.name)
    except RuntimeError:
        return None
    try:
        if name.startswith("tangent:"):
            return read_array(mesh.loops, "tangent", len(mesh.loops), 3, np.float32)[corners]
        return read_array(mesh.loops, "bitangent_sign", len(mesh.loops), 1, np.float32)[corners][:, :, None]
    finally:
        mesh.free_tangents()


ATTRIBUTE_FIELDS = {"FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color", 4), "FLOAT_VECTOR": ("vector", 3),
                    "FLOAT2": ("vector", 2), "FLOAT": ("value", 1), "INT": ("value", 1),
                    "BOOLEAN": ("value", 1)}


def named_attribute(mesh, name: str, corners: np.ndarray, topology: np.ndarray):
    """(T, 3, 3) values of a mesh attribute at the triangles' corners (an empty name: the
    render colour attribute), from its domain; colours scene-linear (Blender's `color`),
    scalars repeated over three components as Cycles reads them. None when missing."""
    if not name:
        index = mesh.color_attributes.render_color_index
        attribute = mesh.color_attributes[index] if 0 <= index < len(mesh.color_attributes) else None
    else:
        attribute = mesh.attributes.get(name)
    if attribute is None or attribute.data_type not in ATTRIBUTE_FIELDS or \
            attribute.domain not in ("POINT", "CORNER", "FACE"):
        return None
    field_name, width = ATTRIBUTE_FIELDS[attribute.data_type]
    values = read_array(attribute.data, field_name, len(attribute.data), width, np.float32).reshape(-1, width)
    if attribute.domain == "CORNER":
        per_corner = values[corners]
    elif attribute.domain == "POINT":
        per_corner = values[topology]
    else:
        faces = read_array(mesh.loop_triangle_polygons, "value", len(corners), 1, np.int32)
        per_corner = np.repeat(values[faces][:, None, :], 3, axis=1)
    if width == 1:
        return np.repeat(per_corner, 3, axis=2)
    out = np.zeros(per_corner.shape[:2] + (3,), np.float32)
    out[..., :min(width, 3)] = per_corner[..., :3]
    return out


def read_geometry(mesh, attributes: tuple[str, ...] = ()) -> LocalGeometry:
    """Triangulate `mesh` (Blender's loop triangles) into arrays, normals per its normals domain.

    Only the loop triangles' corner indices are read from a struct collection (the slow kind
    of foreach_get); vertices, corners, materials and normals come from contiguous arrays.
    """
    tri_count = len(mesh.loop_triangles)
    corners = read_array(mesh.loop_triangles, "loops", tri_count, 3, np.int32)
    corner_vertices = read_attribute(mesh, ".corner_vert", 1, np.int32)
    if corner_vertices is None:  # older Blender: no generic corner attribute
        corner_vertices = read_array(mesh.loops, "vertex_index", len(mesh.loops), 1, np.int32)
    topology = corner_vertices[corners]
    positions = read_attribute(mesh, "position", 3, np.float32)
    if positions is None:
        positions = read_array(mesh.vertices, "co", len(mesh.vertices), 3, np.float32)
    slots = triangle_slots(mesh, tri_count)
    values = {name: corner_attribute(mesh, name, corners, positions, topology) for name in attributes}
    values = {name: v.astype(np.float32) for name, v in values.items() if v is not None}
    domain = mesh.normals_domain if tri_count else "FACE"
    if domain == "POINT":
        normals = read_array(mesh.vertex_normals, "vector", len(positions), 3, np.float32)
        return LocalGeometry(positions, topology, normals, slots, topology, values)
    if domain == "CORNER":
        normals = read_array(mesh.corner_normals, "vector", len(corner_vertices), 3, np.float32)
        return LocalGeometry(positions[corner_vertices], corners, normals, slots, topology, values)
    return LocalGeometry(positions, topology, None, slots, topology, values)


def triangle_slots(mesh, tri_count: int) -> np.ndarray:
    """Material slot of each loop triangle, from its face's material_index (0 if unset)."""
    face_slots = read_attribute(mesh, "material_index", 1, np.int32)
    if face_slots is None or tri_count == 0:
        return np.zeros(tri_count, dtype=np.int32)
    faces = read_array(mesh.loop_triangle_polygons, "value", tri_count, 1, np.int32)
    return face_slots[faces]


@dataclass
class WorldGeometry:
    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) int32, counter-clockwise from the front
    normals: np.ndarray | None
    slots: np.ndarray
    topology: np.ndarray
    attributes: dict[str, np.ndarray] = field(default_factory=dict)


def transform(geometry: LocalGeometry, matrix: np.ndarray) -> WorldGeometry:
    """Object to world space. A mirroring matrix reverses the winding so fronts stay outside."""
    linear = matrix[:3, :3]
    # float32 arithmetic: the result is float32 anyway, and it halves the memory traffic.
    vertices = geometry.positions @ linear.T.astype(np.float32)
    vertices += matrix[:3, 3].astype(np.float32)
    normals = None
    if geometry.normals is not None:
        try:
            normal_matrix = np.linalg.inv(linear).T
        except np.linalg.LinAlgError:
            normal_matrix = None  # flat object: no smooth shading possible
        if normal_matrix is not None:
            transformed = geometry.normals @ normal_matrix.T.astype(np.float32)
            lengths = np.sqrt(np.einsum("ij,ij->i", transformed, transformed))[:, None]
            normals = transformed / np.where(lengths > 0.0, lengths, np.float32(1.0))
    mirrored = np.linalg.det(linear) < 0.0
    triangles = geometry.triangles[:, ::-1].copy() if mirrored else geometry.triangles
    topology = geometry.topology[:, ::-1].copy() if mirrored else geometry.topology
    attributes = {k: world_attribute(k, v, linear, mirrored) for k, v in geometry.attributes.items()}
    return WorldGeometry(vertices, triangles, normals, geometry.slots, topology, attributes)


def world_attribute(name: str, values: np.ndarray, linear: np.ndarray, mirrored: bool) -> np.ndarray:
    """A corner attribute in world space: tangents turn with the object, and a mirroring
    matrix flips the bitangent sign (the world-space cross product flips with it)."""
    if name.startswith("tangent:"):
        values = values @ linear.T.astype(np.float32)
    elif name.startswith("tangent_sign:") and mirrored:
        values = -values
    return values[:, ::-1].copy() if mirrored else values


def edge_problems(topology: np.ndarray) -> tuple[int, int]:
    """(edges not shared by exactly two triangles, edges both triangles traverse the same way)."""
    if len(topology) == 0:
        return 0, 0
    starts = topology.reshape(-1)
    ends = np.roll(topology, -1, axis=1).reshape(-1)
    scale = np.int64(int(topology.max()) + 1)
    undirected = np.minimum(starts, ends).astype(np.int64) * scale + np.maximum(starts, ends)
    _, counts = np.unique(undirected, return_counts=True)
    directed = starts.astype(np.int64) * scale + ends
    _, directed_counts = np.unique(directed, return_counts=True)
    return int(np.count_nonzero(counts != 2)), int(np.count_nonzero(directed_counts > 1))


def warn_if_not_closed(name: str, medium: str, topology: np.ndarray, messages: Messages) -> None:
    """A medium needs a closed, consistently oriented boundary, or rays leak in or out."""
    open_edges, flipped_edges = edge_problems(topology)
    if open_edges:
        messages.warn(object_subject(name), f"encloses the volume '{medium}' but is not closed "
                      f"({open_edges} open or non-manifold edges); the volume may leak")
    if flipped_edges:
        messages.warn(object_subject(name), f"encloses the volume '{medium}' but has inconsistent face "
                      f"orientation ({flipped_edges} edges); recalculate normals outside")


def compact(triangles: np.ndarray, vertices: np.ndarray, normals: np.ndarray | None):
    """Keep only the vertices `triangles` uses, renumbered."""
    used, remapped = np.unique(triangles, return_inverse=True)
    kept_normals = normals[used] if normals is not None else None
    return remapped.reshape(-1, 3).astype(np.int32), vertices[used], kept_normals


@dataclass
class MeshPart:
    """One object's (or instance's) triangles with their materials, ready to merge."""

    geometry: WorldGeometry
    material_names: list[str]  # material of each slot; triangle slots index this


def merge_attributes(parts: list[MeshPart]) -> dict[str, np.ndarray]:
    """Each part's corner attributes concatenated; zeros where a part lacks one."""
    names = list(dict.fromkeys(name for part in parts for name in part.geometry.attributes))
    merged = {}
    for name in names:
        width = max(p.geometry.attributes[name].shape[2] for p in parts if name in p.geometry.attributes)
        merged[name] = np.concatenate([
            p.geometry.attributes.get(name, np.zeros((len(p.geometry.triangles), 3, width), np.float32))
            for p in parts])
    return merged


def mesh_attributes(attributes: dict[str, np.ndarray], mask=None) -> list[CornerAttribute]:
    return [CornerAttribute(name, values if mask is None else values[mask])
            for name, values in attributes.items()]


def merge_parts(parts: list[MeshPart]) -> tuple[WorldGeometry, list[str], np.ndarray]:
    """Concatenate parts: (geometry, material names, per-triangle material ids)."""
    names: list[str] = []
    for part in parts:
        names.extend(n for n in part.material_names if n not in names)
    vertices, triangles, normals, ids, topology = [], [], [], [], []
    offset = topology_offset = 0
    for part in parts:
        g = part.geometry
        lookup = np.array([names.index(n) for n in part.material_names], dtype=np.int32)
        ids.append(lookup[np.clip(g.slots, 0, len(lookup) - 1)])
        vertices.append(g.vertices)
        triangles.append(g.triangles + offset)
        topology.append(g.topology + topology_offset)
        normals.append(g.normals)
        offset += len(g.vertices)
        topology_offset += int(g.topology.max()) + 1 if len(g.topology) else 0
    merged_normals = np.concatenate(normals) if all(n is not None for n in normals) else None
    geometry = WorldGeometry(np.concatenate(vertices), np.concatenate(triangles), merged_normals,
                             np.zeros(0, np.int32), np.concatenate(topology), merge_attributes(parts))
    return geometry, names, np.concatenate(ids).astype(np.int32)


def build_meshes(name: str, parts: list[MeshPart], medium_of: dict[str, str | None],
                 messages: Messages) -> list[Mesh]:
    """Haze meshes of one object: one per medium its materials enclose (usually just one)."""
    geometry, names, material_ids = merge_parts(parts)
    if len(material_ids) == 0:
        return []
    media = [medium_of.get(n) for n in names]
    distinct = list(dict.fromkeys(media))
    if len(distinct) == 1:
        if distinct[0] is not None:
            warn_if_not_closed(name, distinct[0], geometry.topology, messages)
        return [Mesh(name, geometry.vertices, geometry.triangles.astype(np.int32), names,
                     material_ids, geometry.normals, distinct[0], mesh_attributes(geometry.attributes))]
    medium_ids = np.array([distinct.index(m) for m in media], dtype=np.int32)[material_ids]
    meshes = []
    for index, medium in enumerate(distinct):
        mask = medium_ids == index
        triangles, vertices, normals = compact(geometry.triangles[mask], geometry.vertices, geometry.normals)
        part_name = name if medium is None else f"{name} [{medium}]"
        if medium is not None:
            warn_if_not_closed(name, medium, geometry.topology[mask], messages)
        meshes.append(Mesh(part_name, vertices, triangles, names, material_ids[mask], normals, medium,
                           mesh_attributes(geometry.attributes, mask)))
    return meshes
