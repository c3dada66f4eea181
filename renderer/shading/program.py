"""A shader program: the varying part of a material's node tree as a flat list of
operations over a register file, in the spirit of Cycles' SVM (kernel/svm/svm.h).

Registers are float32 scalars; a vector or colour takes three consecutive registers. The
exporter folds every constant input into the initial register values, so an operation
only names registers. An instruction is one int32 row of INSTR: its opcode, destination
register, up to five source registers (a..e) and three integer parameters (i0..i2, e.g.
which Math operation, or where a table starts in the program's constant data).

Bindings say what the program drives: after it runs, each binding writes registers into
a field of one of the material's lobes (renderer.bsdfs.layout.LOBE), either setting the
field (BIND_SET) or scaling it by one scalar register (BIND_SCALE, Mix Shader factors).
The field "emission" names no lobe (its lobe is -1): its three registers are the surface's
emitted radiance, which then replaces Material.emission (that value only sets the
emitter's share of light sampling; see renderer.integrator.program_stage). The field "normal" names
no lobe either: its three registers are the shading normal of all the material's lobes (the
Normal input of a BSDF).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from renderer.layout import Layout

INSTR = Layout("instr", [("op", 1), ("dst", 1), ("a", 1), ("b", 1), ("c", 1), ("d", 1), ("e", 1),
                         ("i0", 1), ("i1", 1), ("i2", 1)])
I_OP, I_DST = INSTR.offset("op"), INSTR.offset("dst")
I_A, I_B, I_C, I_D, I_E = (INSTR.offset(f) for f in "abcde")
I_P0, I_P1, I_P2 = INSTR.offset("i0"), INSTR.offset("i1"), INSTR.offset("i2")

# Opcodes, by name (the exporter emits OP["..."]).
OPCODES = (
    "attribute",   # dst(3) = corner attribute i0 (i1 components) interpolated at the hit
    "position",    # dst(3) = world-space hit point
    "normal",      # dst(3) = world-space shading normal (front side)
    "math",        # dst = Math node operation i0 of a, b, c; i1 = clamp
    "vector_math",  # dst(3 or 1) = Vector Math operation i0 of a, b, c (vectors), d (scale)
    "mix",         # dst(3) = Mix (colour) blend i0 of b, c by factor a; i1 = clamp factor, i2 = clamp result
    "mix_float",   # dst = mix of b, c by factor a (scalars; the vector Mix uses it per component)
    "mapping",     # dst(3) = Mapping type i0 of vector a, location b, rotation c, scale d
    "checker",     # dst(3) colour, dst+3 factor: Checker of vector a, colours b c, scale d
    "image",       # dst(3) colour, dst+3 alpha: image i0 at vector a; i1 interpolation (INTERPOLATIONS),
                   # i2 extension
    "ramp",        # dst(3) colour, dst+3 alpha: 256-entry RGBA table at data[i0], factor a; i1 interpolate
    "curve",       # dst(i1): RGB/Vector Curves (i1 = 3) or Float Curve (i1 = 1) of b (i1 registers),
                   # factor a, the curves' x range [c, d]; table of 256 x i1 at data[i0]; i2 extrapolate
    "combine",     # dst(3) = (a, b, c)
    "copy",        # dst = a (i0 components)
    "invert",      # dst(3) = mix(colour b, 1 - b, factor a)
    "rgb_to_bw",   # dst = Rec. 709 luminance of a
    "clamp",       # dst = clamp(a, b, c); i0 = 0 min-max, 1 range
    "map_range",   # dst = Map Range (float) of a; b..b+4 = from min, from max, to min, to max, steps;
                   # i0 type (names.MAP_RANGE_TYPES), i1 clamp
    "gradient",    # dst = Gradient texture type i0 of vector a (factor; the colour is the same)
    "gamma",       # dst(3) = colour a ^ gamma b
    "bright_contrast",  # dst(3) = Bright/Contrast of colour a, bright b, contrast c
    "hsv",         # dst(3) = Hue/Saturation/Value of colour a: b..b+3 = hue, saturation, value, factor
    "hsv_convert",  # dst(3) = colour a to HSV (i0 0), HSV to RGB (1), to HSL (2), HSL to RGB (3)
    "fresnel",     # dst = Fresnel of IOR a with normal b (3), the view direction and the face side
    "layer_weight",  # dst = Layer Weight of blend a with normal b: i0 0 Fresnel, 1 Facing
    "normal_map",  # dst(3) = Normal Map of colour a, strength b, tangent c (3), bitangent sign d;
                   # i0 space (names.NORMAL_MAP_SPACES)
    "noise_nd",    # dst factor, dst+1..3 colour: Noise Texture of vector a; b..b+7 = W, scale, detail,
                   # roughness, lacunarity, offset, gain, distortion; i0 dimensions (1-4),
                   # i1 type (fractal.TYPES), i2 flags: NOISE_NORMALIZE, NOISE_NO_COLOR
    "white_noise",  # dst value, dst+1..3 colour: White Noise of vector a and W b; i0 dimensions (1-4)
    "voronoi",     # dst distance, dst+1..3 colour, dst+4..6 position, dst+7 W, dst+8 radius: Voronoi of
                   # vector a; b..b+7 = W, scale, detail, roughness, lacunarity, smoothness, exponent,
                   # randomness; i0 dimensions, i1 feature, i2 metric + 4 normalize (voronoi_cells)
    "wave",        # dst = Wave of vector a; b..b+5 = scale, distortion, detail, detail scale, detail
                   # roughness, phase; i0 type, i1 direction, i2 profile (patterns.py)
    "magic",       # dst(3) colour, dst+3 factor: Magic of vector a; b, b+1 = scale, distortion; i0 depth
    "brick",       # dst(3) colour, dst+3 factor: Brick of vector a; b..b+7 = scale, mortar size, mortar
                   # smooth, bias, brick width, row height, offset, squash; colours c, d, mortar e;
                   # i0 offset frequency, i1 squash frequency
    "bump_eval",   # attribute and position operations that follow read the point moved along
                   # tangent i0 (0: the point itself; shading.bump); i1 the corner-position column
    "bump",        # dst(3) = Bump of normal a; b..b+4 = height at the point, at offsets 1 and 2,
                   # strength, distance; i0 invert, i1 the corner-position column
    "spectrum",    # dst(3) = max(M f(a), 0), M the 3x3 (rows) at b..b+8: f Blackbody of temperature a
                   # (i0 0, linear Rec.709) or Wavelength a nm (i0 1, CIE XYZ)
)
OP = {name: code for code, name in enumerate(OPCODES)}
# noise_nd's i2 bits. NOISE_NO_COLOR: the Color output is unused (not linked), so its two
# extra fractals are skipped and dst+2, dst+3 hold 0 (Cycles computes the colour only for a
# linked output too). Programs without the bit compute it.
NOISE_NORMALIZE, NOISE_NO_COLOR = 1, 2

# Lobe fields a binding may drive, and how.
BIND_FIELDS = ("weight", "color", "roughness", "ior", "tint", "emission", "normal")
BIND = Layout("bind", [("lobe", 1), ("field", 1), ("width", 1), ("reg", 1), ("mode", 1)])
BIND_SET, BIND_SCALE = 0, 1

INTERPOLATIONS = ("closest", "linear", "cubic")
EXTENSIONS = ("repeat", "extend", "clip", "mirror")


@dataclass
class ImageTexture:
    """Pixels of one image as Cycles samples them: straight alpha, row 0 at the bottom
    (v = 0), as Blender stores them; scene-linear, or with `srgb` sRGB-encoded values that
    are decoded after interpolation (Cycles keeps 8-bit sRGB images so: COMPRESS_AS_SRGB)."""

    name: str
    pixels: np.ndarray  # (H, W, 4) float32
    srgb: bool = False


@dataclass
class ShaderProgram:
    """The varying part of one material (see the module docstring).

    code (I, INSTR.size) int32; registers (R,) float32, the initial register file (folded
    constants); data (D,) float32, tables (colour ramps, curves); bindings (B, BIND.size)
    int32; attributes: names of the corner attributes `attribute` operations read (their
    i0 indexes this list: "uv:<map>" UV maps, "generated", "object", "color:<name>");
    images: names of the scene's ImageTextures `image` operations read (their i0 indexes it).
    """

    code: np.ndarray
    registers: np.ndarray
    bindings: np.ndarray
    data: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    attributes: list[str] = field(default_factory=list)
    images: list[str] = field(default_factory=list)
