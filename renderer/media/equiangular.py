"""Equiangular distance sampling toward a point light (Kulla & Fajardo 2012).

For a ray o + t d (d unit) and a light at c, let delta = dot(c - o, d) be the parameter of
the point of the ray nearest the light and D the light's distance to the ray line. The pdf

    pdf(t) = D / ((theta_b - theta_a) (D^2 + (t - delta)^2))   on [0, tmax)

with theta_a = atan2(-delta, D), theta_b = atan2(tmax - delta, D) cancels the 1/r^2 falloff
of the light; it is sampled by t = delta + D tan(theta_a + u (theta_b - theta_a)). With
phi = u (theta_b - theta_a), tan(theta_a) = -delta / D and the tangent addition formula this is

    t = (delta^2 + D^2) sin(phi) / (D cos(phi) + delta sin(phi)),

one sincos and no atan2 or tan (the denominator is r cos(theta_a + phi) > 0 in exact maths).

Robustness: a light on the ray line (D = 0) would make the pdf non-integrable, so D is
floored at a tiny fraction of the light's distance (the same floor in sample and pdf keeps
them consistent, so the estimator stays unbiased); tmax may be huge (theta_b -> pi/2); when
the angle range is too small to invert accurately both fall back to uniform on [0, tmax).

Each function has a branch-free twin (*_simd) for the SIMD batch of homogeneous segments
(renderer.integrator.nee_batch): the same maths with every case computed and one kept by a
select, and simdmath's atan2 and sincos (no libm fallback), so that a loop calling it
vectorises across paths. tests/test_nee_batch.py holds the two forms to 1e-11.
"""

import math

from renderer.kernels import fastmath as fm
from renderer.kernels import inline_kernel
from renderer.kernels import simdmath as sm
from renderer.kernels.vecmath import dot, length, madd, sub

MIN_THETA = 1e-9
D_FLOOR = 1e-7  # relative to |delta|
D_MIN = 1e-12  # world units


@inline_kernel
def equiangular_frame(o, d, light_p, tmax):
    """(delta, D, theta_d) of the segment [0, tmax) toward light_p.

    theta_d = theta_b - theta_a comes from one atan2: with a = -delta / D and
    b = (tmax - delta) / D, tan(theta_b - theta_a) = (b - a) / (1 + a b), and the difference
    lies in (0, pi) because D > 0, so theta_d = atan2(D tmax, D^2 - delta (tmax - delta)).
    (atan2 dominated the medium kernel's maths before: four calls per vertex, now one.)
    """
    to_light = sub(light_p, o)
    delta = dot(to_light, d)
    big_d = length(madd(to_light, d, -delta))
    big_d = max(big_d, D_FLOOR * abs(delta), D_MIN)
    theta_d = fm.atan2(big_d * tmax, big_d * big_d - delta * (tmax - delta))
    return delta, big_d, theta_d


@inline_kernel
def frame_pdf(frame, tmax, t):
    """Equiangular pdf of t for a frame from equiangular_frame."""
    delta, big_d, theta_d = frame
    if theta_d < MIN_THETA:
        return 1.0 / tmax
    x = t - delta
    return big_d / (theta_d * (big_d * big_d + x * x))


@inline_kernel
def frame_sample(frame, tmax, u):
    """t in [0, tmax) drawn from the frame's equiangular pdf."""
    delta, big_d, theta_d = frame
    if theta_d < MIN_THETA:
        return u * tmax
    sin_phi, cos_phi = fm.sincos(u * theta_d)
    denom = big_d * cos_phi + delta * sin_phi
    if denom <= 0.0:  # theta_a + phi rounded up to pi/2: t is the far end
        return tmax
    # Clamp only rounding errors: t lands in [0, tmax] in exact maths.
    return min(max((delta * delta + big_d * big_d) * sin_phi / denom, 0.0), tmax)


@inline_kernel
def equiangular_pdf(o, d, light_p, tmax, t):
    return frame_pdf(equiangular_frame(o, d, light_p, tmax), tmax, t)


@inline_kernel
def equiangular_sample(o, d, light_p, tmax, u):
    """(t, pdf) with t in [0, tmax)."""
    frame = equiangular_frame(o, d, light_p, tmax)
    t = frame_sample(frame, tmax, u)
    return t, frame_pdf(frame, tmax, t)


# ------------------------------------------------------------------------- branch-free forms


@inline_kernel
def equiangular_frame_simd(o, d, light_p, tmax):
    """equiangular_frame without branches or calls."""
    ox, oy, oz = o
    dx, dy, dz = d
    lx, ly, lz = light_p[0] - ox, light_p[1] - oy, light_p[2] - oz
    delta = lx * dx + ly * dy + lz * dz
    px, py, pz = lx - delta * dx, ly - delta * dy, lz - delta * dz
    big_d = max(math.sqrt(px * px + py * py + pz * pz), D_FLOOR * abs(delta), D_MIN)
    theta_d = sm.atan2(big_d * tmax, big_d * big_d - delta * (tmax - delta))
    return delta, big_d, theta_d


@inline_kernel
def frame_sample_simd(frame, tmax, u):
    """frame_sample without branches (and with simdmath's sincos)."""
    delta, big_d, theta_d = frame
    degenerate = not theta_d >= MIN_THETA
    sin_phi, cos_phi = sm.sincos(u * theta_d)
    denom = big_d * cos_phi + delta * sin_phi
    t = min(max((delta * delta + big_d * big_d) * sin_phi / denom, 0.0), tmax)
    t = tmax if denom <= 0.0 else t
    return u * tmax if degenerate else t


@inline_kernel
def frame_pdf_simd(frame, tmax, t):
    """frame_pdf without branches."""
    delta, big_d, theta_d = frame
    degenerate = not theta_d >= MIN_THETA
    x = t - delta
    return 1.0 / tmax if degenerate else big_d / (theta_d * (big_d * big_d + x * x))
