"""Image Texture lookups as Cycles' CPU image sampler does them: texel centres at
half-integers, Closest, bilinear (Linear) or the uniform cubic B-spline over 4x4 texels
(Cubic, and Smart, which Cycles' CPU sampler renders as Cubic), and the four extension
modes. Images are rows of one texel table `texels` (P, 4) float32 RGBA;
`images` (N, 4) int32 gives each image's first texel, width, height (row-major, row 0
at v = 0) and whether its texels are sRGB-encoded (decoded after interpolation, as
Cycles' COMPRESS_AS_SRGB 8-bit images)."""

import math

from renderer.kernels import inline_kernel

EXT_REPEAT, EXT_EXTEND, EXT_CLIP, EXT_MIRROR = 0, 1, 2, 3
_ZERO4 = (0.0, 0.0, 0.0, 0.0)


@inline_kernel
def _split(x):
    """(integer part rounded down, fraction) as Cycles' frac()."""
    i = int(math.floor(x))
    return i, x - i


@inline_kernel
def _wrap(i, n, ext):
    """Texel index i on an axis of n texels, or -1 outside a Clip image."""
    if ext == EXT_REPEAT:
        i = i % n
        return i + n if i < 0 else i
    if ext == EXT_MIRROR:
        m = abs(i + (1 if i < 0 else 0)) % (2 * n)
        return 2 * n - m - 1 if m >= n else m
    if ext == EXT_CLIP:
        return i if 0 <= i < n else -1
    return min(max(i, 0), n - 1)


@inline_kernel
def _texel(texels, first, width, ix, iy):
    if ix < 0 or iy < 0:
        return _ZERO4
    k = first + iy * width + ix
    return (float(texels[k, 0]), float(texels[k, 1]), float(texels[k, 2]), float(texels[k, 3]))


@inline_kernel
def _srgb_to_linear(c):
    if c < 0.04045:
        return 0.0 if c < 0.0 else c * (1.0 / 12.92)
    return ((c + 0.055) * (1.0 / 1.055)) ** 2.4


@inline_kernel
def image_lookup(texels, images, index, u, v, interpolation, ext):
    """RGBA of image `index` at texture coordinates (u, v), scene-linear; interpolation
    0 Closest, 1 Linear, 2 Cubic (program.INTERPOLATIONS)."""
    if interpolation == 2:
        c = _cubic(texels, images, index, u, v, ext)
    else:
        c = _interpolate(texels, images, index, u, v, interpolation == 1, ext)
    if images[index, 3] == 0:
        return c
    return (_srgb_to_linear(c[0]), _srgb_to_linear(c[1]), _srgb_to_linear(c[2]), c[3])


@inline_kernel
def _interpolate(texels, images, index, u, v, linear, ext):
    first, width, height = images[index, 0], images[index, 1], images[index, 2]
    if ext == EXT_CLIP and (u < 0.0 or v < 0.0 or u > 1.0 or v > 1.0):
        return _ZERO4
    if not linear:
        ix, _ = _split(u * width)
        iy, _ = _split(v * height)
        return _texel(texels, first, width, _wrap(ix, width, ext), _wrap(iy, height, ext))
    ix, tx = _split(u * width - 0.5)
    iy, ty = _split(v * height - 0.5)
    x0, x1 = _wrap(ix, width, ext), _wrap(ix + 1, width, ext)
    y0, y1 = _wrap(iy, height, ext), _wrap(iy + 1, height, ext)
    a = _texel(texels, first, width, x0, y0)
    b = _texel(texels, first, width, x1, y0)
    c = _texel(texels, first, width, x0, y1)
    d = _texel(texels, first, width, x1, y1)
    w00, w10, w01, w11 = (1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty
    return (w00 * a[0] + w10 * b[0] + w01 * c[0] + w11 * d[0],
            w00 * a[1] + w10 * b[1] + w01 * c[1] + w11 * d[1],
            w00 * a[2] + w10 * b[2] + w01 * c[2] + w11 * d[2],
            w00 * a[3] + w10 * b[3] + w01 * c[3] + w11 * d[3])


@inline_kernel
def _bspline(t):
    """The uniform cubic B-spline's four weights at fraction t (Cycles' SET_CUBIC_SPLINE_WEIGHTS)."""
    return ((((-1.0 / 6.0) * t + 0.5) * t - 0.5) * t + 1.0 / 6.0, ((0.5 * t - 1.0) * t) * t + 2.0 / 3.0,
            ((-0.5 * t + 0.5) * t + 0.5) * t + 1.0 / 6.0, (1.0 / 6.0) * t * t * t)


@inline_kernel
def _cubic(texels, images, index, u, v, ext):
    """Cycles' CPU interp_cubic: 4x4 texels around the point, B-spline weighted; a Clip image
    reads zeros outside (every texel is clipped on its own)."""
    first, width, height = images[index, 0], images[index, 1], images[index, 2]
    ix, tx = _split(u * width - 0.5)
    iy, ty = _split(v * height - 0.5)
    if ext == EXT_CLIP and (ix < -2 or ix > width or iy < -2 or iy > height):
        return _ZERO4
    wx, wy = _bspline(tx), _bspline(ty)
    r, g, b, a = 0.0, 0.0, 0.0, 0.0
    for j in range(4):
        y = _wrap(iy - 1 + j, height, ext)
        for i in range(4):
            w = wx[i] * wy[j]
            c = _texel(texels, first, width, _wrap(ix - 1 + i, width, ext), y)
            r += w * c[0]
            g += w * c[1]
            b += w * c[2]
            a += w * c[3]
    return (r, g, b, a)
