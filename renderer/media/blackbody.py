"""Blackbody colour and Cycles' Principled Volume blackbody emission.

blackbody_rgb(T) is the linear Rec.709 colour of a blackbody at T kelvin normalised to
luminance 1, which is Cycles' normalisation (its fitted curve in svm/math_util.h has
Rec.709 luminance 1 at every temperature and is held constant below 800 K and above
12000 K, as is this one). Here the colour is computed from first principles instead of a
fit: Planck's law summed against the CIE 1931 2-degree colour matching functions (the
standard's 5 nm table, cie1931.py) gives XYZ, converted to linear Rec.709 (D65) and
divided by Y; this reproduces Cycles' curve to ~1e-3. It is tabulated once at import,
uniformly in 1/T (colour varies smoothly in mireds), and interpolated linearly.
Below ~2000 K the colour leaves the Rec.709 gamut and blue (below 800 K also green) turns
slightly negative (-0.09 against red 4.6 at 1000 K). Cycles' Principled Volume keeps
those values (only its Blackbody node clamps), and so does this: the emission estimate
stays that of Cycles, negative blue included.

Principled Volume adds, where blackbody intensity b > 0 (svm/closure.h):

    emission = sigma_SB / pi * 1e-6 * mix(1, T^4, b) * blackbody_rgb(T)
             = 5.670373e-8 / pi * 1e-6 * ((1 - b) + b T^4) * blackbody_rgb(T)

(Stefan-Boltzmann radiance scaled by Cycles' 1e-6; the blackbody tint is 1).

A grid medium evaluates this per voxel (blackbody_emission_voxels) and interpolates the
resulting emission, not the temperature: Cycles samples volume grids stochastically (one
voxel picked with the trilinear weights, util/texture_3d.h), so the emission it renders
is, in expectation, the trilinear mix of the voxels' emission. Interpolating the
temperature instead loses light wherever it varies, since T^4 is convex (a hot voxel next
to an empty one: 0.2 instead of 0.5 of its emission over the half voxel between them).
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel
from renderer.media.cie1931 import CIE_1931_XYZ, CIE_LAMBDA_MIN, CIE_LAMBDA_STEP
from renderer.scene import LUMINANCE

T_MIN = 800.0
T_MAX = 12000.0
TABLE_SIZE = 1024
STEFAN_BOLTZMANN_OVER_PI = 5.670373e-8 * 1e-6 / math.pi


XYZ_TO_REC709 = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def blackbody_rgb_reference(temperature: float) -> np.ndarray:
    """Linear Rec.709 blackbody colour of luminance 1 (numpy, builds the table)."""
    t = min(max(temperature, T_MIN), T_MAX)
    lam = CIE_LAMBDA_MIN + CIE_LAMBDA_STEP * np.arange(CIE_1931_XYZ.shape[0])  # nm
    c2 = 1.4387769e7  # second radiation constant h c / k, in nm K
    # Planck's spectral radiance up to a constant factor (it cancels in the normalisation).
    planck = 1.0 / (lam**5 * np.expm1(c2 / (lam * t)))
    xyz = CIE_1931_XYZ.T @ planck  # the standard's 5 nm summation
    rgb = XYZ_TO_REC709 @ (xyz / xyz[1])
    return rgb / (LUMINANCE[0] * rgb[0] + LUMINANCE[1] * rgb[1] + LUMINANCE[2] * rgb[2])


def _table() -> np.ndarray:
    inv_t = np.linspace(1.0 / T_MIN, 1.0 / T_MAX, TABLE_SIZE)
    return np.ascontiguousarray([blackbody_rgb_reference(1.0 / x) for x in inv_t])


BLACKBODY_TABLE = _table()  # (TABLE_SIZE, 3), row i at 1/T = 1/T_MIN + i (1/T_MAX - 1/T_MIN)/(N-1)


@inline_kernel
def blackbody_rgb(temperature):
    """Linear Rec.709 colour of a blackbody at `temperature` kelvin, luminance 1."""
    t = min(max(temperature, T_MIN), T_MAX)
    x = (1.0 / t - 1.0 / T_MIN) / (1.0 / T_MAX - 1.0 / T_MIN) * (TABLE_SIZE - 1)
    i = min(int(x), TABLE_SIZE - 2)
    f = x - i
    a = BLACKBODY_TABLE[i]
    b = BLACKBODY_TABLE[i + 1]
    return (a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f)


@kernel
def blackbody_emission(temperature, intensity):
    """Cycles' Principled Volume blackbody term (see the module docstring); 0 when b <= 0."""
    if intensity <= 0.0:
        return (0.0, 0.0, 0.0)
    t = max(temperature, 0.0)
    t2 = t * t
    scale = STEFAN_BOLTZMANN_OVER_PI * ((1.0 - intensity) + intensity * t2 * t2)
    if scale <= 0.0:  # Cycles adds nothing unless the intensity is positive (b > 1, T < 1 K)
        return (0.0, 0.0, 0.0)
    c = blackbody_rgb(t)
    return (scale * c[0], scale * c[1], scale * c[2])


def blackbody_emission_voxels(temperature, intensity: float) -> np.ndarray:
    """blackbody_emission of every voxel of a temperature grid: (..., 3) float64, the same
    table and interpolation as the kernel's (numpy, for compiling grid media)."""
    t = np.asarray(temperature, np.float64)
    out = np.zeros(t.shape + (3,))
    if intensity <= 0.0:
        return out
    t = np.maximum(t, 0.0)
    scale = STEFAN_BOLTZMANN_OVER_PI * ((1.0 - intensity) + intensity * (t * t) * (t * t))
    clamped = np.clip(t, T_MIN, T_MAX)
    x = (1.0 / clamped - 1.0 / T_MIN) / (1.0 / T_MAX - 1.0 / T_MIN) * (TABLE_SIZE - 1)
    i = np.minimum(x.astype(np.int64), TABLE_SIZE - 2)
    f = (x - i)[..., None]
    colour = BLACKBODY_TABLE[i] + (BLACKBODY_TABLE[i + 1] - BLACKBODY_TABLE[i]) * f
    return np.where((scale > 0.0)[..., None], scale[..., None] * colour, 0.0)
