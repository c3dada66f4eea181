"""Bake cases of the procedural texture nodes (Noise in every dimension and type, ...) for
tests/test_shader_programs.py: each case name maps to a builder that adds the node to a
material tree inside Blender and returns the output socket to bake.

Textures read Object coordinates (x, y in [-1, 1] on the bake plane, z = 0); a W input,
where one is used, is a varying value too (x / 2 + y), so that 1D and 4D noise vary over
the plane along W.
"""

from __future__ import annotations

# name: (dimensions, type, detail, distortion, normalize, output). Inputs are quantized
# (multiples of 1/16 both sides hold exactly) unless the name ends in "_smooth": these pin
# the algorithm to TIGHT; smooth inputs differ by Cycles' own coordinate round-off, which
# high octaves amplify (3D Hetero Terrain, detail 4.5: 3e-4 smooth, 4e-6 quantized).
NOISE = {
    "tex_noise_1d_fbm": ("1D", "FBM", 3.5, 0.0, True, "Fac"),
    "tex_noise_1d_color": ("1D", "FBM", 2.0, 0.6, True, "Color"),
    "tex_noise_1d_hetero": ("1D", "HETERO_TERRAIN", 2.5, 0.0, True, "Fac"),
    "tex_noise_2d_fbm_smooth": ("2D", "FBM", 3.5, 0.0, True, "Fac"),
    "tex_noise_2d_color": ("2D", "FBM", 2.0, 0.6, False, "Color"),
    "tex_noise_2d_raw": ("2D", "FBM", 2.0, 0.0, False, "Color"),
    "tex_noise_2d_ridged": ("2D", "RIDGED_MULTIFRACTAL", 3.0, 0.0, True, "Fac"),
    "tex_noise_2d_multi": ("2D", "MULTIFRACTAL", 2.5, 0.0, True, "Fac"),
    "tex_noise_3d_distortion": ("3D", "FBM", 2.0, 0.6, True, "Fac"),
    "tex_noise_3d_multi": ("3D", "MULTIFRACTAL", 4.5, 0.3, True, "Fac"),
    "tex_noise_3d_hybrid": ("3D", "HYBRID_MULTIFRACTAL", 4.5, 0.3, True, "Fac"),
    "tex_noise_3d_ridged": ("3D", "RIDGED_MULTIFRACTAL", 4.0, 0.3, True, "Fac"),
    "tex_noise_3d_hetero": ("3D", "HETERO_TERRAIN", 4.5, 0.3, True, "Color"),
    "tex_noise_4d_fbm_smooth": ("4D", "FBM", 3.5, 0.0, True, "Fac"),
    "tex_noise_4d_color": ("4D", "FBM", 2.0, 0.6, True, "Color"),
    "tex_noise_4d_hybrid": ("4D", "HYBRID_MULTIFRACTAL", 2.5, 0.0, True, "Fac"),
}
TIGHT = 1e-5

# White Noise hashes its input's float32 bits, so it is baked at lattice points that both
# sides compute exactly: floor(4 Object + 0.5) (integers), W = 8 x + y of those.
WHITE_NOISE = {f"tex_white_{d}_{out.lower()}": (d, out) for d in ("1D", "2D", "3D", "4D")
               for out in ("Value", "Color")}

# name: (dimensions, feature, metric, output, detail, normalize); on quantized inputs, as
# noise (a point near a cell border would otherwise pick its cell by round-off).
_V = [("F1", "EUCLIDEAN", "Distance", 0.0, False), ("F1", "EUCLIDEAN", "Color", 0.0, False),
      ("F1", "MANHATTAN", "Position", 0.0, False), ("F2", "CHEBYCHEV", "Distance", 0.0, False),
      ("F2", "EUCLIDEAN", "Color", 0.0, False), ("SMOOTH_F1", "EUCLIDEAN", "Distance", 0.0, False),
      ("SMOOTH_F1", "MANHATTAN", "Color", 0.0, False),
      ("DISTANCE_TO_EDGE", "EUCLIDEAN", "Distance", 0.0, False),
      ("N_SPHERE_RADIUS", "EUCLIDEAN", "Radius", 0.0, False)]
VORONOI = {f"tex_voronoi_{d.lower()}_{f.lower()}_{m.lower()}_{o.lower()}": (d, f, m, o, detail, normalize)
           for d in ("1D", "2D", "3D", "4D") for f, m, o, detail, normalize in _V
           if not (d == "1D" and o == "Position")}  # 1D has W only
VORONOI.update({
    "tex_voronoi_3d_f1_minkowski_distance": ("3D", "F1", "MINKOWSKI", "Distance", 0.0, False),
    "tex_voronoi_3d_smooth_f1_euclidean_position": ("3D", "SMOOTH_F1", "EUCLIDEAN", "Position", 0.0, False),
    "tex_voronoi_3d_fractal_f1_distance": ("3D", "F1", "EUCLIDEAN", "Distance", 2.5, True),
    "tex_voronoi_3d_fractal_f2_color": ("3D", "F2", "EUCLIDEAN", "Color", 2.5, True),
    "tex_voronoi_2d_fractal_smooth_position": ("2D", "SMOOTH_F1", "EUCLIDEAN", "Position", 1.5, False),
    "tex_voronoi_3d_fractal_edge": ("3D", "DISTANCE_TO_EDGE", "EUCLIDEAN", "Distance", 1.5, True),
    "tex_voronoi_4d_f1_euclidean_w": ("4D", "F1", "EUCLIDEAN", "W", 0.0, False),
    "tex_voronoi_1d_fractal_f1_w": ("1D", "F1", "EUCLIDEAN", "W", 2.5, True),
})

# Wave: (type, direction, profile, distortion); Magic: depth; Brick: (offset frequency,
# squash frequency, mortar smooth, output). Quantized inputs, as noise.
WAVE = {f"tex_wave_{t.lower()}_{d.lower()}_{p.lower()}": (t, d, p, dist)
        for t, d, p, dist in [("BANDS", "X", "SIN", 0.0), ("BANDS", "Y", "SAW", 0.0),
                              ("BANDS", "Z", "TRI", 0.0), ("BANDS", "DIAGONAL", "SIN", 1.5),
                              ("RINGS", "X", "SAW", 0.0), ("RINGS", "Y", "TRI", 0.0),
                              ("RINGS", "Z", "SIN", 0.0), ("RINGS", "SPHERICAL", "TRI", 2.0)]}
MAGIC = {f"tex_magic_{depth}": depth for depth in (0, 2, 5, 10)}
BRICK = {"tex_brick_color": (2, 1, 0.0, "Color"), "tex_brick_fac": (2, 1, 0.3, "Fac"),
         "tex_brick_squash": (3, 2, 0.3, "Color")}

# Separate Color (HSL) per output, and Combine Color (HSL) of the separated values.
HSL = {"tex_hsl_separate_h": 0, "tex_hsl_separate_s": 1, "tex_hsl_separate_l": 2, "tex_hsl_combine": None}

CASES = list(NOISE) + list(WHITE_NOISE) + list(VORONOI) + list(WAVE) + list(MAGIC) + list(BRICK) + list(HSL)
# Per-case tolerance (relative, as the test's); the others use the test's own.
# Distorted Color: green and blue are the fractal at the distorted point plus a seed offset
# near 150, where a float32 step is 1.5e-5, so the distortion itself must round exactly as
# Cycles' (renderer/shading/perlin32.py): in float64 it was off by up to 5.7e-5 (2D) and
# 2.1e-5 (4D) here; bit-exact, they match as the rest, to ~1e-6.
TOLERANCES = {**{name: TIGHT for name in NOISE if not name.endswith("_smooth")},
              **{name: 1e-6 for name in WHITE_NOISE},
              **{name: TIGHT for name in list(VORONOI) + list(WAVE) + list(MAGIC) + list(BRICK) + list(HSL)}}


def by_id(node, identifier):
    return next(s for s in node.inputs if s.identifier == identifier)


def _object_coordinates(tree):
    return tree.nodes.new("ShaderNodeTexCoord").outputs["Object"]


def _varying_w(tree, vector):
    """x / 2 + y of `vector`, as a float socket (exact for multiples of 1/16)."""
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(vector, sep.inputs["Vector"])
    w = tree.nodes.new("ShaderNodeMath")
    w.operation = "MULTIPLY_ADD"
    w.inputs[1].default_value = 0.5
    tree.links.new(sep.outputs["X"], w.inputs[0])
    tree.links.new(sep.outputs["Y"], w.inputs[2])
    return w.outputs["Value"]


def _noise(tree, name):
    dims, kind, detail, distortion, normalize, output = NOISE[name]
    node = tree.nodes.new("ShaderNodeTexNoise")
    node.noise_dimensions = dims
    node.noise_type = kind
    node.normalize = normalize
    values = {"Scale": 3.7, "Detail": detail, "Roughness": 0.6, "Lacunarity": 2.3, "Offset": 0.8,
              "Gain": 1.3, "Distortion": distortion}
    for identifier, value in values.items():  # by identifier: a type's unused inputs are hidden
        by_id(node, identifier).default_value = value
    vector = _object_coordinates(tree) if name.endswith("_smooth") else _quantized(tree)
    if dims != "1D":
        tree.links.new(vector, node.inputs["Vector"])
    if dims in ("1D", "4D"):
        tree.links.new(_varying_w(tree, vector), by_id(node, "W"))
    return node.outputs[output]


def _lattice(tree):
    """(floor(4 Object + 0.5) as a vector socket, 8 x + y of it as a float socket)."""
    scaled = tree.nodes.new("ShaderNodeVectorMath")
    scaled.operation = "MULTIPLY_ADD"
    scaled.inputs[1].default_value = (4.0, 4.0, 4.0)
    scaled.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(_object_coordinates(tree), scaled.inputs[0])
    floor = tree.nodes.new("ShaderNodeVectorMath")
    floor.operation = "FLOOR"
    tree.links.new(scaled.outputs["Vector"], floor.inputs[0])
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(floor.outputs["Vector"], sep.inputs["Vector"])
    w = tree.nodes.new("ShaderNodeMath")
    w.operation = "MULTIPLY_ADD"
    w.inputs[1].default_value = 8.0
    tree.links.new(sep.outputs["X"], w.inputs[0])
    tree.links.new(sep.outputs["Y"], w.inputs[2])
    return floor.outputs["Vector"], w.outputs["Value"]


def _quantized(tree):
    """floor(16 Object + 0.5) / 16: coordinates both sides hold exactly (multiples of 1/16)."""
    scaled = tree.nodes.new("ShaderNodeVectorMath")
    scaled.operation = "MULTIPLY_ADD"
    scaled.inputs[1].default_value = (16.0, 16.0, 16.0)
    scaled.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(_object_coordinates(tree), scaled.inputs[0])
    floor = tree.nodes.new("ShaderNodeVectorMath")
    floor.operation = "FLOOR"
    tree.links.new(scaled.outputs["Vector"], floor.inputs[0])
    back = tree.nodes.new("ShaderNodeVectorMath")
    back.operation = "SCALE"
    back.inputs["Scale"].default_value = 1.0 / 16.0
    tree.links.new(floor.outputs["Vector"], back.inputs[0])
    return back.outputs["Vector"]


def _white_noise(tree, name):
    dims, output = WHITE_NOISE[name]
    node = tree.nodes.new("ShaderNodeTexWhiteNoise")
    node.noise_dimensions = dims
    vector, w = _lattice(tree)
    if dims != "1D":
        tree.links.new(vector, node.inputs["Vector"])
    if dims in ("1D", "4D"):
        tree.links.new(w, by_id(node, "W"))
    return node.outputs[output]


def _voronoi(tree, name):
    dims, feature, metric, output, detail, normalize = VORONOI[name]
    node = tree.nodes.new("ShaderNodeTexVoronoi")
    node.voronoi_dimensions = dims
    node.feature = feature
    node.distance = metric
    node.normalize = normalize
    values = {"Scale": 3.7, "Detail": detail, "Roughness": 0.6, "Lacunarity": 2.1, "Smoothness": 0.6,
              "Exponent": 1.5, "Randomness": 0.9}
    for identifier, value in values.items():
        socket = next((s for s in node.inputs if s.identifier == identifier), None)
        if socket is not None:
            socket.default_value = value
    vector = _quantized(tree)
    if dims != "1D":
        tree.links.new(vector, node.inputs["Vector"])
    if dims in ("1D", "4D"):
        tree.links.new(_varying_w(tree, vector), by_id(node, "W"))
    return next(s for s in node.outputs if s.identifier == output)


def _pattern(tree, name):
    if name in WAVE:
        kind, direction, profile, distortion = WAVE[name]
        node = tree.nodes.new("ShaderNodeTexWave")
        node.wave_type = kind
        if kind == "BANDS":
            node.bands_direction = direction
        else:
            node.rings_direction = direction
        node.wave_profile = profile
        values = {"Scale": 1.3, "Distortion": distortion, "Detail": 2.5, "Detail Scale": 1.7,
                  "Detail Roughness": 0.6, "Phase Offset": 0.4}
        output = "Fac"
    elif name in MAGIC:
        node = tree.nodes.new("ShaderNodeTexMagic")
        node.turbulence_depth = MAGIC[name]
        values = {"Scale": 2.3, "Distortion": 1.7}
        output = "Color"
    else:
        offset_frequency, squash_frequency, smooth, output = BRICK[name]
        node = tree.nodes.new("ShaderNodeTexBrick")
        node.offset, node.offset_frequency = 0.4, offset_frequency
        node.squash, node.squash_frequency = 0.7, squash_frequency
        values = {"Scale": 3.1, "Mortar Size": 0.04, "Mortar Smooth": smooth, "Bias": 0.2,
                  "Brick Width": 0.55, "Row Height": 0.27, "Color1": (0.9, 0.3, 0.2, 1),
                  "Color2": (0.2, 0.5, 0.7, 1), "Mortar": (0.1, 0.1, 0.1, 1)}
    for identifier, value in values.items():
        by_id(node, identifier).default_value = value
    # Shifted off the origin: z = 0 would put every Object point on a wave's or brick's edge.
    shift = tree.nodes.new("ShaderNodeVectorMath")
    shift.inputs[1].default_value = (0.3125, 0.1875, 0.4375)  # multiples of 1/16: exact
    tree.links.new(_quantized(tree), shift.inputs[0])
    tree.links.new(shift.outputs["Vector"], node.inputs["Vector"])
    return node.outputs[output]


def _hsl(tree, name):
    """A colour varying over the plane (UV mixed with a pink, some channels above 0.5 and
    below), separated into HSL; combined back for tex_hsl_combine."""
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["UV"], by_id(mix, "A_Color"))
    by_id(mix, "B_Color").default_value = (0.9, 0.3, 0.6, 1)
    by_id(mix, "Factor_Float").default_value = 0.4
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    sep.mode = "HSL"
    tree.links.new(next(s for s in mix.outputs if s.identifier == "Result_Color"), sep.inputs["Color"])
    if HSL[name] is not None:
        return sep.outputs[HSL[name]]
    comb = tree.nodes.new("ShaderNodeCombineColor")
    comb.mode = "HSL"
    for k in range(3):
        tree.links.new(sep.outputs[k], comb.inputs[k])
    return comb.outputs["Color"]


def case_nodes(tree, name):
    """(output socket to bake) of texture case `name`."""
    if name in NOISE:
        return _noise(tree, name)
    if name in WHITE_NOISE:
        return _white_noise(tree, name)
    if name in VORONOI:
        return _voronoi(tree, name)
    if name in WAVE or name in MAGIC or name in BRICK:
        return _pattern(tree, name)
    if name in HSL:
        return _hsl(tree, name)
    raise ValueError(name)
