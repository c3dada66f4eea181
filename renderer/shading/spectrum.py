"""Blackbody and Wavelength nodes as Cycles computes them (svm/math_util.h
svm_math_blackbody_color_rec709 and svm_math_wavelength_color_xyz, tables in kernel/tables.h):
float32 coefficients, evaluated in double here (Cycles' float32 arithmetic differs by round-off).

Blackbody gives a linear Rec.709 colour (negative components where the colour is outside the
gamut; the node clamps them after converting to the scene's working space). Wavelength gives
CIE XYZ (D65), which the node converts to the working space, scales by 1/2.52 and clamps.
`blackbody_rec709` and `wavelength_xyz` are numba kernels; BLACKBODY_* and CIE_XYZ are the
tables as numpy arrays, shared with the exporter's constant folding (node_values)."""

import numpy as np

from renderer.kernels import inline_kernel

# Ranges of temperature (K) where each row of coefficients applies (lower bounds).
BLACKBODY_BOUNDS = np.array([800.0, 965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0], np.float64)
_F = np.float32
BLACKBODY_R = np.array([[1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
                        [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
                        [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
                        [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
                        [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
                        [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
                        [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]], _F).astype(np.float64)
BLACKBODY_G = np.array([[-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
                        [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
                        [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
                        [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
                        [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
                        [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
                        [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]], _F).astype(np.float64)
BLACKBODY_B = np.array([[5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
                        [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
                        [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
                        [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
                        [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
                        [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
                        [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]],
                       _F).astype(np.float64)
BLACKBODY_HOT = tuple(float(_F(v)) for v in (0.8262954810464208, 0.9945080501520986, 1.566307710274283))
BLACKBODY_COLD = tuple(float(_F(v)) for v in (5.413294490189271, -0.20319390035873933, -0.0822535242887164))

# CIE 1931 colour matching functions, 380..780 nm every 5 nm (81 rows of X, Y, Z).
CIE_XYZ = np.array([
    0.0014, 0.0000, 0.0065, 0.0022, 0.0001, 0.0105, 0.0042, 0.0001, 0.0201, 0.0076, 0.0002, 0.0362,
    0.0143, 0.0004, 0.0679, 0.0232, 0.0006, 0.1102, 0.0435, 0.0012, 0.2074, 0.0776, 0.0022, 0.3713,
    0.1344, 0.0040, 0.6456, 0.2148, 0.0073, 1.0391, 0.2839, 0.0116, 1.3856, 0.3285, 0.0168, 1.6230,
    0.3483, 0.0230, 1.7471, 0.3481, 0.0298, 1.7826, 0.3362, 0.0380, 1.7721, 0.3187, 0.0480, 1.7441,
    0.2908, 0.0600, 1.6692, 0.2511, 0.0739, 1.5281, 0.1954, 0.0910, 1.2876, 0.1421, 0.1126, 1.0419,
    0.0956, 0.1390, 0.8130, 0.0580, 0.1693, 0.6162, 0.0320, 0.2080, 0.4652, 0.0147, 0.2586, 0.3533,
    0.0049, 0.3230, 0.2720, 0.0024, 0.4073, 0.2123, 0.0093, 0.5030, 0.1582, 0.0291, 0.6082, 0.1117,
    0.0633, 0.7100, 0.0782, 0.1096, 0.7932, 0.0573, 0.1655, 0.8620, 0.0422, 0.2257, 0.9149, 0.0298,
    0.2904, 0.9540, 0.0203, 0.3597, 0.9803, 0.0134, 0.4334, 0.9950, 0.0087, 0.5121, 1.0000, 0.0057,
    0.5945, 0.9950, 0.0039, 0.6784, 0.9786, 0.0027, 0.7621, 0.9520, 0.0021, 0.8425, 0.9154, 0.0018,
    0.9163, 0.8700, 0.0017, 0.9786, 0.8163, 0.0014, 1.0263, 0.7570, 0.0011, 1.0567, 0.6949, 0.0010,
    1.0622, 0.6310, 0.0008, 1.0456, 0.5668, 0.0006, 1.0026, 0.5030, 0.0003, 0.9384, 0.4412, 0.0002,
    0.8544, 0.3810, 0.0002, 0.7514, 0.3210, 0.0001, 0.6424, 0.2650, 0.0000, 0.5419, 0.2170, 0.0000,
    0.4479, 0.1750, 0.0000, 0.3608, 0.1382, 0.0000, 0.2835, 0.1070, 0.0000, 0.2187, 0.0816, 0.0000,
    0.1649, 0.0610, 0.0000, 0.1212, 0.0446, 0.0000, 0.0874, 0.0320, 0.0000, 0.0636, 0.0232, 0.0000,
    0.0468, 0.0170, 0.0000, 0.0329, 0.0119, 0.0000, 0.0227, 0.0082, 0.0000, 0.0158, 0.0057, 0.0000,
    0.0114, 0.0041, 0.0000, 0.0081, 0.0029, 0.0000, 0.0058, 0.0021, 0.0000, 0.0041, 0.0015, 0.0000,
    0.0029, 0.0010, 0.0000, 0.0020, 0.0007, 0.0000, 0.0014, 0.0005, 0.0000, 0.0010, 0.0004, 0.0000,
    0.0007, 0.0002, 0.0000, 0.0005, 0.0002, 0.0000, 0.0003, 0.0001, 0.0000, 0.0002, 0.0001, 0.0000,
    0.0002, 0.0001, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000,
    0.0000, 0.0000, 0.0000], _F).astype(np.float64).reshape(81, 3)
WAVELENGTH_SCALE = 1.0 / 2.52  # Cycles' empirical scale keeping every component <= 1


@inline_kernel
def blackbody_rec709(t):
    if t >= 12000.0:
        return BLACKBODY_HOT
    if t < 800.0:
        return BLACKBODY_COLD
    i = 0
    for k in range(1, 7):
        if t >= BLACKBODY_BOUNDS[k]:
            i = k
    r, g, b = BLACKBODY_R[i], BLACKBODY_G[i], BLACKBODY_B[i]
    inv = 1.0 / t
    return (r[0] * inv + r[1] * t + r[2], g[0] * inv + g[1] * t + g[2],
            ((b[0] * t + b[1]) * t + b[2]) * t + b[3])


@inline_kernel
def wavelength_xyz(nm):
    f = (nm - 380.0) * 0.2
    if not (-1.0 < f < 80.0):  # NaN too
        return (0.0, 0.0, 0.0)
    i = int(f)  # truncation toward zero, as Cycles' float_to_int: (-1, 0) extrapolates row 0
    t = f - i
    s = 1.0 - t
    return (s * CIE_XYZ[i, 0] + t * CIE_XYZ[i + 1, 0], s * CIE_XYZ[i, 1] + t * CIE_XYZ[i + 1, 1],
            s * CIE_XYZ[i, 2] + t * CIE_XYZ[i + 1, 2])


def blackbody_numpy(t: np.ndarray) -> np.ndarray:
    """(..., 3) blackbody_rec709 of temperatures t (...,), for constant folding."""
    t = np.asarray(t, np.float64)
    i = np.clip(np.searchsorted(BLACKBODY_BOUNDS, t, side="right") - 1, 0, 6)
    inv = 1.0 / np.maximum(t, 1.0)
    r, g, b = BLACKBODY_R[i], BLACKBODY_G[i], BLACKBODY_B[i]
    out = np.stack([r[..., 0] * inv + r[..., 1] * t + r[..., 2], g[..., 0] * inv + g[..., 1] * t + g[..., 2],
                    ((b[..., 0] * t + b[..., 1]) * t + b[..., 2]) * t + b[..., 3]], axis=-1)
    out = np.where((t >= 12000.0)[..., None], BLACKBODY_HOT, out)
    return np.where((t < 800.0)[..., None], BLACKBODY_COLD, out)


def wavelength_numpy(nm: np.ndarray) -> np.ndarray:
    """(..., 3) wavelength_xyz of wavelengths nm (...,), for constant folding."""
    f = np.nan_to_num((np.asarray(nm, np.float64) - 380.0) * 0.2, nan=-1.0)
    i = np.trunc(f).astype(np.int64)
    inside = (i >= 0) & (i < 80)
    i = np.clip(i, 0, 79)
    t = (f - i)[..., None]
    out = (1.0 - t) * CIE_XYZ[i] + t * CIE_XYZ[i + 1]
    return np.where(inside[..., None], out, 0.0)



@inline_kernel
def spectrum_node(regs, dst, kind, x, m):
    """Blackbody (kind 0, temperature x) or Wavelength (1, x in nm): the colour times the 3x3
    matrix in registers m..m+8 (rows; to the working space, Wavelength's scale folded in),
    clamped at 0 (svm_node_blackbody, svm_node_wavelength)."""
    c = blackbody_rec709(x) if kind == 0 else wavelength_xyz(x)
    for row in range(3):
        k = m + 3 * row
        v = float(regs[k]) * c[0] + float(regs[k + 1]) * c[1] + float(regs[k + 2]) * c[2]
        regs[dst + row] = max(v, 0.0)
