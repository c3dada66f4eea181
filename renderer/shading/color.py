"""Colour nodes with Cycles' semantics: HSV and HSL conversions (util/color.h), Hue/Saturation/Value
(svm/hsv.h), and the view-dependent Fresnel and Layer Weight (svm/fresnel.h)."""

import math

from renderer.kernels import inline_kernel


@inline_kernel
def rgb_to_hsv(c):
    cmax = max(c[0], max(c[1], c[2]))
    cmin = min(c[0], min(c[1], c[2]))
    delta = cmax - cmin
    s = delta / cmax if cmax != 0.0 else 0.0
    h = 0.0
    if s != 0.0:
        cr, cg, cb = (cmax - c[0]) / delta, (cmax - c[1]) / delta, (cmax - c[2]) / delta
        if c[0] == cmax:
            h = cb - cg
        elif c[1] == cmax:
            h = 2.0 + cr - cb
        else:
            h = 4.0 + cg - cr
        h /= 6.0
        if h < 0.0:
            h += 1.0
    return (h, s, cmax)


@inline_kernel
def rgb_to_hsl(c):
    """(h, s, l): h in [0, 1), s >= 0, l <= 1 for any input (Separate Color, HSL)."""
    cmax = max(c[0], max(c[1], c[2]))
    cmin = min(c[0], min(c[1], c[2]))
    lum = min(1.0, (cmax + cmin) / 2.0)
    if cmax == cmin:
        return (0.0, 0.0, lum)
    delta = cmax - cmin
    s = delta / (2.0 - cmax - cmin) if lum > 0.5 else delta / (cmax + cmin)
    if cmax == c[0]:
        h = (c[1] - c[2]) / delta + (6.0 if c[1] < c[2] else 0.0)
    elif cmax == c[1]:
        h = (c[2] - c[0]) / delta + 2.0
    else:
        h = (c[0] - c[1]) / delta + 4.0
    return (h / 6.0, s, lum)


@inline_kernel
def hsl_to_rgb(c):
    h, s, lum = c
    nr = min(max(abs(h * 6.0 - 3.0) - 1.0, 0.0), 1.0)
    ng = min(max(2.0 - abs(h * 6.0 - 2.0), 0.0), 1.0)
    nb = min(max(2.0 - abs(h * 6.0 - 4.0), 0.0), 1.0)
    chroma = (1.0 - abs(2.0 * lum - 1.0)) * s
    return ((nr - 0.5) * chroma + lum, (ng - 0.5) * chroma + lum, (nb - 0.5) * chroma + lum)


@inline_kernel
def hsv_to_rgb(c):
    h, s, v = c
    if s == 0.0:
        return (v, v, v)
    if h == 1.0:
        h = 0.0
    h *= 6.0
    i = math.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    if i == 0.0:
        return (v, t, p)
    if i == 1.0:
        return (q, v, p)
    if i == 2.0:
        return (p, v, t)
    if i == 3.0:
        return (p, q, v)
    if i == 4.0:
        return (t, p, v)
    return (v, p, q)


@inline_kernel
def hue_saturation_value(color, hue, sat, val, fac):
    h, s, v = rgb_to_hsv(color)
    h = h + hue + 0.5
    h = h - math.floor(h)
    s = min(max(s * sat, 0.0), 1.0)
    r = hsv_to_rgb((h, s, v * val))
    return (max(fac * r[0] + (1.0 - fac) * color[0], 0.0), max(fac * r[1] + (1.0 - fac) * color[1], 0.0),
            max(fac * r[2] + (1.0 - fac) * color[2], 0.0))


@inline_kernel
def fresnel_dielectric_cos(cosi, eta):
    c = abs(cosi)
    g = eta * eta - 1.0 + c * c
    if g > 0.0:
        g = math.sqrt(g)
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        return 0.5 * a * a * (1.0 + b * b)
    return 1.0


@inline_kernel
def fresnel(ior, cosi, back):
    eta = max(ior, 1e-5)
    return fresnel_dielectric_cos(cosi, 1.0 / eta if back else eta)


@inline_kernel
def layer_weight(blend, cosi, back, facing):
    """Layer Weight's Fresnel output (facing False) or Facing output (True)."""
    if not facing:
        eta = max(1.0 - blend, 1e-5)
        return fresnel_dielectric_cos(cosi, eta if back else 1.0 / eta)
    f = abs(cosi)
    if blend != 0.5:
        blend = min(max(blend, 0.0), 1.0 - 1e-5)
        blend = 2.0 * blend if blend < 0.5 else 0.5 / (1.0 - blend)
        f = f ** blend
    return 1.0 - f
