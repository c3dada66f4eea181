"""The shader program interpreter: runs material m's program (program.py) at one shading
point and leaves its results in the register file `regs`.

`st` is the scene's shading table tuple (table.py): (progs, code, init, data, binds,
corner, texels, images). A point is given by its triangle p, barycentrics (b0, b1, b2),
world position x, shading normal n (facing the side the ray came from, as Cycles' sd->N),
the direction wi toward where the ray came from, and whether the back face was hit;
corner attributes are interpolated with the barycentrics Embree returns
(hit = b0 v0 + b1 v1 + b2 v2).
"""

import numpy as np

from renderer.kernels import helper_kernel, inline_kernel
from renderer.kernels.native_call import native_address

from .bump import bump_normal, bump_point
from .color import fresnel, hsl_to_rgb, hsv_to_rgb, hue_saturation_value, layer_weight, rgb_to_hsl, rgb_to_hsv
from .fractal import noise_texture
from .image import image_lookup
from .math_ops import map_range, math_op, mix_color, vector_op
from .normals import normal_map
from .patterns import brick, magic, wave
from .program import (
    I_A,
    I_B,
    I_C,
    I_D,
    I_DST,
    I_E,
    I_OP,
    I_P0,
    I_P1,
    I_P2,
    NOISE_NO_COLOR,
    NOISE_NORMALIZE,
    OP,
)
from .spectrum import spectrum_node
from .table import P_CODE, P_INIT, P_NCODE, P_NREGS
from .textures import checker, curves, gradient, mapping, ramp_lookup
from .voronoi import voronoi_texture
from .white_noise import white_noise

ATTRIBUTE, POSITION, NORMAL = OP["attribute"], OP["position"], OP["normal"]
MATH, VECTOR_MATH, MIX, MIX_FLOAT = OP["math"], OP["vector_math"], OP["mix"], OP["mix_float"]
MAPPING, CHECKER, IMAGE, RAMP, CURVE = OP["mapping"], OP["checker"], OP["image"], OP["ramp"], OP["curve"]
COMBINE, COPY, INVERT, RGB_TO_BW = OP["combine"], OP["copy"], OP["invert"], OP["rgb_to_bw"]
CLAMP, GRADIENT, GAMMA, BRIGHT_CONTRAST = OP["clamp"], OP["gradient"], OP["gamma"], OP["bright_contrast"]
MAP_RANGE, HSV, HSV_CONVERT = OP["map_range"], OP["hsv"], OP["hsv_convert"]
FRESNEL, LAYER_WEIGHT = OP["fresnel"], OP["layer_weight"]
NORMAL_MAP, BUMP_EVAL, BUMP = OP["normal_map"], OP["bump_eval"], OP["bump"]
NOISE_ND, WHITE_NOISE, VORONOI = OP["noise_nd"], OP["white_noise"], OP["voronoi"]
WAVE, MAGIC, BRICK, SPECTRUM = OP["wave"], OP["magic"], OP["brick"], OP["spectrum"]


@inline_kernel
def _v(regs, r):
    return (float(regs[r]), float(regs[r + 1]), float(regs[r + 2]))


@inline_kernel
def _put3(regs, r, v):
    regs[r] = v[0]
    regs[r + 1] = v[1]
    regs[r + 2] = v[2]


@inline_kernel
def _attribute(corner, p, b0, b1, b2, column, width):
    c = corner[p]
    out0 = b0 * c[0, column] + b1 * c[1, column] + b2 * c[2, column]
    out1 = 0.0
    out2 = 0.0
    if width > 1:
        out1 = b0 * c[0, column + 1] + b1 * c[1, column + 1] + b2 * c[2, column + 1]
    if width > 2:
        out2 = b0 * c[0, column + 2] + b1 * c[1, column + 2] + b2 * c[2, column + 2]
    return (out0, out1, out2)


@helper_kernel
def run_program(st, m, regs, p, b0, b1, b2, x, n, wi, back):  # noqa: C901 - the interpreter's dispatch
    progs, code, init, data, _, corner, texels, images = st
    r0 = progs[m, P_INIT]
    for k in range(progs[m, P_NREGS]):
        regs[k] = init[r0 + k]
    # the point attribute and position operations read (Bump moves it)
    q0, q1, q2, qx = float(b0), float(b1), float(b2), (float(x[0]), float(x[1]), float(x[2]))
    c0 = progs[m, P_CODE]
    for j in range(c0, c0 + progs[m, P_NCODE]):
        ins = code[j]
        op, dst, a, b, c = ins[I_OP], ins[I_DST], ins[I_A], ins[I_B], ins[I_C]
        if op == ATTRIBUTE:
            _put3(regs, dst, _attribute(corner, p, q0, q1, q2, ins[I_P0], ins[I_P1]))
        elif op == POSITION:
            _put3(regs, dst, qx)
        elif op == NORMAL:
            _put3(regs, dst, n)
        elif op == MATH:
            r = math_op(ins[I_P0], float(regs[a]), float(regs[b]), float(regs[c]))
            regs[dst] = min(max(r, 0.0), 1.0) if ins[I_P1] else r
        elif op == VECTOR_MATH:
            v, s = vector_op(ins[I_P0], _v(regs, a), _v(regs, b), _v(regs, c), float(regs[ins[I_D]]))
            if ins[I_P1]:
                regs[dst] = s
            else:
                _put3(regs, dst, v)
        elif op == MIX:
            t = float(regs[a])
            if ins[I_P1]:
                t = min(max(t, 0.0), 1.0)
            v = mix_color(ins[I_P0], t, _v(regs, b), _v(regs, c))
            if ins[I_P2]:
                v = (min(max(v[0], 0.0), 1.0), min(max(v[1], 0.0), 1.0), min(max(v[2], 0.0), 1.0))
            _put3(regs, dst, v)
        elif op == MIX_FLOAT:
            t = float(regs[a])
            if ins[I_P1]:
                t = min(max(t, 0.0), 1.0)
            regs[dst] = (1.0 - t) * regs[b] + t * regs[c]
        elif op == MAPPING:
            _put3(regs, dst, mapping(ins[I_P0], _v(regs, a), _v(regs, b), _v(regs, c), _v(regs, ins[I_D])))
        elif op == CHECKER:
            s = float(regs[ins[I_D]])
            q = _v(regs, a)
            f = checker((q[0] * s, q[1] * s, q[2] * s))
            _put3(regs, dst, _v(regs, b) if f == 1.0 else _v(regs, c))
            regs[dst + 3] = f
        elif op == IMAGE:
            q = _v(regs, a)
            rgba = image_lookup(texels, images, ins[I_P0], q[0], q[1], ins[I_P1], ins[I_P2])
            _put3(regs, dst, (rgba[0], rgba[1], rgba[2]))
            regs[dst + 3] = rgba[3]
        elif op == RAMP:
            f = float(regs[a])
            for ch in range(4):
                regs[dst + ch] = ramp_lookup(data, ins[I_P0], 4, ch, f, ins[I_P1] != 0)
        elif op == CURVE:
            curves(regs, dst, data, ins[I_P0], ins[I_P1], ins[I_P2] != 0, float(regs[a]), b, float(regs[c]),
                   float(regs[ins[I_D]]))
        elif op == COMBINE:
            v = (float(regs[a]), float(regs[b]), float(regs[c]))
            _put3(regs, dst, v)
        elif op == COPY:
            for ch in range(ins[I_P0]):
                regs[dst + ch] = regs[a + ch]
        elif op == INVERT:
            t = float(regs[a])
            col = _v(regs, b)
            for ch in range(3):
                regs[dst + ch] = t * (1.0 - col[ch]) + (1.0 - t) * col[ch]
        elif op == RGB_TO_BW:
            regs[dst] = 0.2126 * regs[a] + 0.7152 * regs[a + 1] + 0.0722 * regs[a + 2]
        elif op == CLAMP:
            lo, hi = float(regs[b]), float(regs[c])
            if ins[I_P0] == 1 and lo > hi:
                lo, hi = hi, lo
            regs[dst] = min(max(float(regs[a]), lo), hi)
        elif op == GRADIENT:
            regs[dst] = gradient(ins[I_P0], _v(regs, a))
        elif op == GAMMA:
            g = float(regs[b])
            for ch in range(3):
                v = float(regs[a + ch])
                regs[dst + ch] = v ** g if v > 0.0 else v
        elif op == BRIGHT_CONTRAST:
            ka = 1.0 + regs[c]
            kb = regs[b] - regs[c] * 0.5
            for ch in range(3):
                regs[dst + ch] = max(ka * regs[a + ch] + kb, 0.0)
        elif op == HSV:
            _put3(regs, dst, hue_saturation_value(_v(regs, a), float(regs[b]), float(regs[b + 1]),
                                                  float(regs[b + 2]), float(regs[b + 3])))
        elif op == HSV_CONVERT:
            _put3(regs, dst, _convert_color(ins[I_P0], _v(regs, a)))
        elif op == FRESNEL:
            nn = _v(regs, b)
            regs[dst] = fresnel(float(regs[a]), wi[0] * nn[0] + wi[1] * nn[1] + wi[2] * nn[2], back)
        elif op == LAYER_WEIGHT:
            nn = _v(regs, b)
            regs[dst] = layer_weight(float(regs[a]), wi[0] * nn[0] + wi[1] * nn[1] + wi[2] * nn[2], back,
                                     ins[I_P0] != 0)
        elif op == NORMAL_MAP:
            _put3(regs, dst, normal_map(_v(regs, a), float(regs[b]), _v(regs, c), float(regs[ins[I_D]]),
                                        ins[I_P0], n, back))
        elif op == NOISE_ND:
            _noise_nd(regs, dst, _v(regs, a), b, ins[I_P0], ins[I_P1], ins[I_P2])
        elif op == WHITE_NOISE:
            q = _v(regs, a)
            value, col = white_noise(ins[I_P0], q[0], q[1], q[2], float(regs[b]))
            regs[dst] = value
            _put3(regs, dst + 1, col)
        elif op == VORONOI:
            _voronoi(regs, dst, _v(regs, a), b, ins[I_P0], ins[I_P1], ins[I_P2])
        elif op == WAVE:
            q = _v(regs, a)
            s = float(regs[b])
            regs[dst] = wave(ins[I_P0], ins[I_P1], ins[I_P2], q[0] * s, q[1] * s, q[2] * s,
                             float(regs[b + 1]), float(regs[b + 2]), float(regs[b + 3]), float(regs[b + 4]),
                             float(regs[b + 5]))
        elif op == MAGIC:
            q = _v(regs, a)
            col = magic(q[0], q[1], q[2], float(regs[b]), ins[I_P0], float(regs[b + 1]))
            _put3(regs, dst, col)
            regs[dst + 3] = (col[0] + col[1] + col[2]) * (1.0 / 3.0)
        elif op == BRICK:
            _brick(regs, dst, _v(regs, a), b, _v(regs, c), _v(regs, ins[I_D]), _v(regs, ins[I_E]), ins[I_P0],
                   ins[I_P1])
        elif op == BUMP_EVAL:
            q0, q1, q2, qx = bump_point(corner, p, ins[I_P1], b0, b1, b2, x, n, ins[I_P0])
        elif op == BUMP:
            _put3(regs, dst, bump_normal(corner, p, ins[I_P1], x, n, _v(regs, a), float(regs[b]),
                                         float(regs[b + 1]), float(regs[b + 2]), float(regs[b + 3]),
                                         float(regs[b + 4]), ins[I_P0] != 0))
        elif op == SPECTRUM:
            spectrum_node(regs, dst, ins[I_P0], float(regs[a]), b)
        elif op == MAP_RANGE:
            regs[dst] = map_range(float(regs[a]), float(regs[b]), float(regs[b + 1]), float(regs[b + 2]),
                                  float(regs[b + 3]), float(regs[b + 4]), ins[I_P0], ins[I_P1] != 0)


def program_entry(st: tuple, regs: np.ndarray) -> int:
    """This process's address of run_program compiled for the shading tuple `st` and the
    register file `regs` (renderer.kernels.native_call): the kernels that run programs
    (integrator.program_stage through shading.apply, media.procedural) call it through this address with
    call_native, so the interpreter is compiled once rather than again inside each of them.
    The arguments after regs have the types those callers pass: int64 m and p, float64
    barycentrics, 3-tuples of float64 for x, n and wi, bool back."""
    v = (0.0, 0.0, 0.0)
    return native_address(run_program, st, np.int64(0), regs, np.int64(0), 0.0, 0.0, 0.0, v, v, v, False)


@inline_kernel
def _noise_nd(regs, dst, q, b, dim, kind, flags):
    """Noise Texture of any dimension and type: (q, W) scaled by regs[b + 1], as
    svm_node_tex_noise; 1D noise reads W alone. flags: program.NOISE_NORMALIZE,
    program.NOISE_NO_COLOR."""
    s = float(regs[b + 1])
    w = float(regs[b]) * s
    x, y, z = q[0] * s, q[1] * s, q[2] * s
    if dim == 1:
        x, y, z, w = w, 0.0, 0.0, 0.0
    elif dim == 2:
        z, w = 0.0, 0.0
    elif dim == 3:
        w = 0.0
    value, col = noise_texture(dim, kind, x, y, z, w, float(regs[b + 2]), float(regs[b + 3]),
                               float(regs[b + 4]), float(regs[b + 5]), float(regs[b + 6]),
                               float(regs[b + 7]), (flags & NOISE_NORMALIZE) != 0,
                               (flags & NOISE_NO_COLOR) == 0)
    regs[dst] = value
    _put3(regs, dst + 1, col)


@inline_kernel
def _voronoi(regs, dst, q, b, dim, feature, flags):
    d, col, pos, radius = voronoi_texture(dim, feature, flags & 3, (flags & 4) != 0, q[0], q[1], q[2],
                                          float(regs[b]), float(regs[b + 1]), float(regs[b + 2]),
                                          float(regs[b + 3]), float(regs[b + 4]), float(regs[b + 5]),
                                          float(regs[b + 6]), float(regs[b + 7]))
    regs[dst] = d
    _put3(regs, dst + 1, col)
    _put3(regs, dst + 4, (pos[0], pos[1], pos[2]))
    regs[dst + 7] = pos[3]
    regs[dst + 8] = radius


@inline_kernel
def _brick(regs, dst, q, b, c1, c2, mortar, offset_frequency, squash_frequency):
    """svm_node_tex_brick: the brick's tint mixes Color1 and Color2, the mortar covers both."""
    s = float(regs[b])
    tint, f = brick(q[0] * s, q[1] * s, float(regs[b + 1]), float(regs[b + 2]), float(regs[b + 3]),
                    float(regs[b + 4]), float(regs[b + 5]), float(regs[b + 6]), offset_frequency,
                    float(regs[b + 7]), squash_frequency)
    for ch in range(3):
        base = (1.0 - tint) * c1[ch] + tint * c2[ch] if f != 1.0 else c1[ch]
        regs[dst + ch] = base * (1.0 - f) + mortar[ch] * f
    regs[dst + 3] = f


@inline_kernel
def _convert_color(kind, c):
    if kind == 0:
        return rgb_to_hsv(c)
    if kind == 1:
        return hsv_to_rgb(c)
    return rgb_to_hsl(c) if kind == 2 else hsl_to_rgb(c)
