"""Dense voxel arrays from any Blender volume, read through a temporary geometry-node tree.

Blender's Python API has no access to voxels, but geometry nodes do: Get Named Grid takes a
grid of a volume, Sample Grid Index reads it at integer voxel indices (voxel centres sit at
the integer coordinates of the grid's index space), and Store Named Attribute leaves the
values on the vertices of a mesh, whose attributes Python reads with foreach_get. The point
count and index arithmetic of the tree cover a box of the grid's index space, so one
evaluation reads that box exactly (no interpolation: each point is one voxel).

The tree lives on a temporary object in a temporary scene, so the user's scenes, objects and
node groups are never touched; everything the sampler creates is removed when it closes,
also when reading fails. The volume is referenced by an Object Info node in "Original"
space, i.e. its grids are read in the volume object's own space, whatever its transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TEMPORARY_NAME = ".Haze Grid Sampler"  # leading dot: hidden from most of Blender's lists
VALUE_ATTRIBUTE = "haze_voxel_value"
MAX_POINTS_PER_PASS = 1 << 22  # voxels per evaluation: bounds the temporary mesh's memory
GRID_TYPES = {"FLOAT": ("FLOAT", "value", 1), "VECTOR": ("FLOAT_VECTOR", "vector", 3)}


@dataclass
class GridInfo:
    """One grid of an evaluated volume."""

    name: str
    data_type: str  # Blender's VolumeGrid.data_type: "FLOAT", "VECTOR_FLOAT", "DOUBLE", ...
    index_to_object: np.ndarray  # (4, 4) float64: voxel (i, j, k) centre -> object space

    @property
    def node_type(self) -> str | None:
        """The geometry-node socket type that reads this grid, or None if none can."""
        if self.data_type in ("FLOAT", "DOUBLE", "INT", "INT64", "BOOLEAN", "MASK"):
            return "FLOAT"
        if self.data_type.startswith("VECTOR"):
            return "VECTOR"
        return None


@dataclass
class VolumeInfo:
    """The grids of an evaluated volume and its object-space bounding box."""

    grids: dict[str, GridInfo]
    bounds: tuple[np.ndarray, np.ndarray]  # object-space (min, max) corners


def index_box(grid: GridInfo, bounds: tuple[np.ndarray, np.ndarray], margin: int = 1):
    """(start, shape) in (x, y, z) of the index-space box holding `bounds`, plus `margin` voxels
    on every side (voxels there read as the grid's background: the zero border of the box)."""
    low, high = bounds
    corners = np.array([[x, y, z, 1.0] for x in (low[0], high[0]) for y in (low[1], high[1])
                        for z in (low[2], high[2])])
    index = corners @ np.linalg.inv(grid.index_to_object).T
    start = np.floor(index[:, :3].min(axis=0) + 1e-6).astype(np.int64) - margin
    stop = np.ceil(index[:, :3].max(axis=0) - 1e-6).astype(np.int64) + margin
    return start, np.maximum(stop - start + 1, 1)


def _link(tree, output, socket) -> None:
    tree.links.new(output, socket)


def _integer_math(tree, operation: str, a, b):
    node = tree.nodes.new("FunctionNodeIntegerMath")
    node.operation = operation
    for socket, value in zip(node.inputs[:2], (a, b)):
        if isinstance(value, int):
            socket.default_value = value
        else:
            _link(tree, value, socket)
    return node.outputs[0]


def build_sampler_tree(name: str, target, grid_name: str, node_type: str):
    """A node group that reads grid `grid_name` of `target` at the voxels of an index box.

    The box is set on the returned nodes (see `set_box`): point i reads voxel
    (x0 + i % nx, y0 + (i // nx) % ny, z0 + i // (nx ny)), so the values come out x fastest,
    the (nz, ny, nx) order of Haze's grids."""
    import bpy

    attribute_type = GRID_TYPES[node_type][0]
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    info = tree.nodes.new("GeometryNodeObjectInfo")
    info.transform_space = "ORIGINAL"
    info.inputs["Object"].default_value = target
    get = tree.nodes.new("GeometryNodeGetNamedGrid")
    get.data_type = node_type
    get.inputs["Name"].default_value = grid_name
    _link(tree, info.outputs["Geometry"], get.inputs["Volume"])
    points = tree.nodes.new("GeometryNodePoints")
    index = tree.nodes.new("GeometryNodeInputIndex").outputs[0]
    offsets = [tree.nodes.new("FunctionNodeIntegerMath") for _ in range(3)]
    sizes = [tree.nodes.new("FunctionNodeIntegerMath") for _ in range(2)]
    sizes[0].operation = sizes[1].operation = "ADD"  # constants nx and nx * ny, set by set_box
    row = _integer_math(tree, "DIVIDE_FLOOR", index, sizes[0].outputs[0])
    coordinates = [
        _integer_math(tree, "MODULO", index, sizes[0].outputs[0]),
        _integer_math(tree, "MODULO", row, 1),
        _integer_math(tree, "DIVIDE_FLOOR", index, sizes[1].outputs[0]),
    ]
    coordinates[1].node.inputs[1].default_value = 1
    sample = tree.nodes.new("GeometryNodeSampleGridIndex")
    sample.data_type = node_type
    _link(tree, get.outputs["Grid"], sample.inputs["Grid"])
    for axis, offset, coordinate in zip("XYZ", offsets, coordinates):
        offset.operation = "ADD"
        _link(tree, coordinate, offset.inputs[0])
        _link(tree, offset.outputs[0], sample.inputs[axis])
    store = tree.nodes.new("GeometryNodeStoreNamedAttribute")
    store.data_type = attribute_type
    store.domain = "POINT"
    store.inputs["Name"].default_value = VALUE_ATTRIBUTE
    _link(tree, points.outputs[0], store.inputs["Geometry"])
    _link(tree, sample.outputs[0], store.inputs["Value"])
    vertices = tree.nodes.new("GeometryNodePointsToVertices")
    _link(tree, store.outputs[0], vertices.inputs[0])
    output = tree.nodes.new("NodeGroupOutput")
    _link(tree, vertices.outputs[0], output.inputs[0])
    return SamplerNodes(tree, points, offsets, sizes, coordinates[1].node)


@dataclass
class SamplerNodes:
    """The nodes of a sampler tree whose constants select the index box."""

    tree: object
    points: object
    offsets: list
    sizes: list
    row_modulo: object

    def set_box(self, start, shape) -> None:
        nx, ny, nz = (int(v) for v in shape)
        self.points.inputs["Count"].default_value = nx * ny * nz
        for offset, value in zip(self.offsets, start):
            offset.inputs[1].default_value = int(value)
        self.sizes[0].inputs[0].default_value, self.sizes[0].inputs[1].default_value = nx, 0
        self.sizes[1].inputs[0].default_value, self.sizes[1].inputs[1].default_value = nx * ny, 0
        self.row_modulo.inputs[1].default_value = ny


def volume_info(evaluated) -> VolumeInfo:
    """Grids and bounds of an evaluated VOLUME-type object: a Volume object, or the volume
    a mesh object's geometry nodes output (a depsgraph instance whose original is the mesh)."""
    grids: dict[str, GridInfo] = {}
    for grid in evaluated.data.grids:
        grid.load()
        grids[grid.name] = GridInfo(grid.name, grid.data_type, np.array(grid.matrix_object, np.float64))
    corners = np.array([tuple(c) for c in evaluated.bound_box], np.float64)
    return VolumeInfo(grids, (corners.min(axis=0), corners.max(axis=0)))


class GridSampler:
    """Reads grids of volume objects into dense arrays; use as a context manager.

    `frame` is the scene frame to evaluate the volumes at (animated volumes, sequences)."""

    def __init__(self, frame: int = 1, subframe: float = 0.0) -> None:
        import bpy

        self._scene = bpy.data.scenes.new(TEMPORARY_NAME)
        self._scene.frame_set(int(frame), subframe=float(subframe))
        self._mesh = bpy.data.meshes.new(TEMPORARY_NAME)
        self._object = bpy.data.objects.new(TEMPORARY_NAME, self._mesh)
        self._scene.collection.objects.link(self._object)
        self._modifier = self._object.modifiers.new(TEMPORARY_NAME, "NODES")
        self._trees: list = []
        self._volumes: list = []  # temporary Volume datablocks (file volumes)
        self._objects: list = []  # and their objects

    # ------------------------------------------------------------------ lifetime
    def __enter__(self) -> GridSampler:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Remove everything the sampler created (safe to call twice)."""
        import bpy

        for tree in self._trees:
            if tree is not None and tree.name in bpy.data.node_groups:
                bpy.data.node_groups.remove(tree)
        self._trees.clear()
        for collection, items in ((bpy.data.objects, self._objects), (bpy.data.volumes, self._volumes)):
            for item in items:
                if item.name in collection:
                    collection.remove(item)
            items.clear()
        if self._object is not None:
            bpy.data.objects.remove(self._object)
            bpy.data.meshes.remove(self._mesh)
            bpy.data.scenes.remove(self._scene)
            self._object = self._mesh = self._scene = None

    # ------------------------------------------------------------------ reading
    def file_volume(self, filepath: str):
        """A temporary volume object that loads the OpenVDB file `filepath` (removed on close)."""
        import bpy

        volume = bpy.data.volumes.new(TEMPORARY_NAME)
        self._volumes.append(volume)
        volume.filepath = filepath
        obj = bpy.data.objects.new(TEMPORARY_NAME, volume)
        self._objects.append(obj)
        return obj

    def inspect(self, target) -> VolumeInfo:
        """Grids and bounds of `target` (an original volume object) as the sampler evaluates it."""
        self._use_tree(build_sampler_tree(TEMPORARY_NAME, target, "", "FLOAT"))
        evaluated = target.evaluated_get(self._depsgraph())
        if evaluated.type != "VOLUME":
            raise ValueError(f"it is a {evaluated.type.lower()} object making volume geometry; Haze reads "
                             "the grids of Volume objects only")
        return volume_info(evaluated)

    def read(self, target, grid: GridInfo, start, shape) -> np.ndarray:
        """Voxels start .. start + shape - 1 (x, y, z) of `grid`: (nz, ny, nx) float32, or
        (nz, ny, nx, 3) for vector grids. Voxels the grid does not store read as its background."""
        nodes = self.reader(target, grid)
        try:
            return self.read_with(nodes, grid, start, shape)
        finally:
            self._drop(nodes)

    def reader(self, target, grid: GridInfo) -> SamplerNodes:
        """A sampler tree reading `grid` of `target`, for any number of read_with calls (so a
        volume read box by box builds its tree once); removed on close."""
        node_type = grid.node_type
        if node_type is None:
            raise ValueError(f"grids of type {grid.data_type} cannot be read")
        nodes = build_sampler_tree(TEMPORARY_NAME, target, grid.name, node_type)
        self._trees.append(nodes.tree)
        return nodes

    def read_with(self, nodes: SamplerNodes, grid: GridInfo, start, shape) -> np.ndarray:
        """read() through a tree from reader(): at most MAX_POINTS_PER_PASS voxels per
        evaluation, so the temporary mesh stays small whatever the box."""
        node_type = grid.node_type
        width = GRID_TYPES[node_type][2]
        nx, ny, nz = (int(v) for v in shape)
        result = np.empty((nz, ny, nx, width), np.float32)
        self._modifier.node_group = nodes.tree
        slab = max(1, MAX_POINTS_PER_PASS // max(nx * ny, 1))
        for z0 in range(0, nz, slab):
            depth = min(slab, nz - z0)
            nodes.set_box((start[0], start[1], start[2] + z0), (nx, ny, depth))
            result[z0:z0 + depth] = self._evaluate(node_type, nx * ny * depth).reshape(depth, ny, nx, width)
        return result[..., 0] if width == 1 else result

    # ------------------------------------------------------------------ internals
    def _use_tree(self, nodes: SamplerNodes) -> None:
        """Evaluate `nodes` from now on; the previous tree is removed."""
        previous = self._modifier.node_group
        self._modifier.node_group = nodes.tree
        self._trees.append(nodes.tree)
        if previous is not None:
            self._drop_tree(previous)

    def _drop(self, nodes: SamplerNodes) -> None:
        if self._modifier.node_group is nodes.tree:
            self._modifier.node_group = None
        self._drop_tree(nodes.tree)

    def _drop_tree(self, tree) -> None:
        import bpy

        if tree in self._trees:
            self._trees.remove(tree)
        if tree.name in bpy.data.node_groups:
            bpy.data.node_groups.remove(tree)

    def _depsgraph(self):
        view_layer = self._scene.view_layers[0]
        view_layer.update()
        return view_layer.depsgraph

    def _evaluate(self, node_type: str, count: int) -> np.ndarray:
        _, field, width = GRID_TYPES[node_type]
        mesh = self._object.evaluated_get(self._depsgraph()).data
        attribute = mesh.attributes.get(VALUE_ATTRIBUTE)
        if attribute is None or len(attribute.data) != count:
            raise RuntimeError("the geometry-node grid sampler returned no values")
        values = np.empty(count * width, np.float32)
        attribute.data.foreach_get(field, values)
        return values.reshape(count, width)
