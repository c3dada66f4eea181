"""The Principled BSDF's last departures from Cycles, closed (issue 14, item 6): Multiscatter
GGX energy compensation (renderer/bsdfs/multiscatter.py), the specular tint of the
dielectric layer (plastic) and the untinted reflection of Principled transmission
(dielectric's separate reflection tint). Against Cycles in a render: tests/test_addon_cycles.py
("principled_ms").
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_bsdfs import PLAIN, WHITE, direction, lobe_quadrature

from renderer.bsdfs import FRESNEL_CONSTANT, PLASTIC, ROUGH_CONDUCTOR
from renderer.bsdfs.lobe import lobe_eval, lobe_sample
from renderer.bsdfs.multiscatter import GGX_E, energy_factor, ggx_albedo
from renderer.bsdfs.plastic import layer_albedo
from renderer.bsdfs.spec_albedo import f0_from_eta

# The tables' own accuracy: Cycles' E (read from its binary) and ours differ by up to 1.5e-3
# at the nodes, and linear interpolation between nodes adds up to a few 1e-3 at grazing.
TABLE_ACCURACY = 5e-3


@pytest.mark.parametrize("rough, theta", [(0.3, 20.0), (0.6, 50.0), (1.0, 10.0), (1.0, 70.0), (0.8, 80.0)])
def test_multiscatter_white_conductor_keeps_its_energy(rough, theta):
    """A white GGX mirror with Multiscatter GGX reflects E(mu) x (1 + (1 - E) / E) = 1: its
    albedo is the quadrature's E times the compensation, exactly, and 1 within the table's
    accuracy (the single-scattering lobe loses up to a third of the light)."""
    wo = direction(theta)
    plain = (ROUGH_CONDUCTOR, WHITE, rough, 1.5, FRESNEL_CONSTANT, WHITE)
    _, albedo, _, err = lobe_quadrature(*plain, True, wo)
    _, single, _, err1 = lobe_quadrature(*plain, False, wo)
    factor = np.array(energy_factor(WHITE, rough, wo[2]))
    bound = float(err.max() + err1.max() * factor.max()) + 1e-9
    np.testing.assert_allclose(albedo, single * factor, rtol=0, atol=bound)
    exact = ggx_albedo(rough, wo[2], 512)
    assert abs(single[0] - exact) <= err1[0] + 1e-4, (single, exact)  # the two quadratures' accuracy
    assert np.all(np.abs(albedo - 1.0) <= TABLE_ACCURACY + err), albedo


def test_multiscatter_table_nodes_are_the_quadrature():
    for x, y in [(0, 0), (10, 31), (31, 31), (31, 3), (20, 12)]:
        rough, mu = max(x / 31, 1e-4), max(y / 31, 1e-4)
        assert GGX_E[y, x] == pytest.approx(ggx_albedo(rough, mu, 256), abs=1e-9)


def test_coloured_fresnel_is_saturated_by_its_bounces():
    """Cycles' Fms: a coloured Fresnel gains less than a white one (1 + Fms (1 - E) / E with
    Fms < 1), and a black one nothing."""
    white = energy_factor(WHITE, 0.8, 0.5)
    coloured = energy_factor((0.9, 0.5, 0.0), 0.8, 0.5)
    assert white[0] > coloured[0] > coloured[1] > coloured[2] == 1.0


def test_specular_tint_scales_f0_of_the_layer():
    """Smooth layer, normal incidence: the layer's reflection is F0 x Specular Tint per channel
    (Cycles' generalized Schlick mix(F0 tint, 1, s) with s = 0 there)."""
    ior, tint = 1.5, (0.2, 0.6, 1.0)
    wo = (0.0, 0.0, 1.0)
    wi, w, pdf, delta = lobe_sample(PLASTIC, (0.5, 0.5, 0.5), 0.0, ior, FRESNEL_CONSTANT, tint, False, wo,
                                    0.5, 0.5, 0.0)  # u3 = 0: the layer
    assert delta
    np.testing.assert_allclose(np.array(w) * pdf, f0_from_eta(ior) * np.array(tint), rtol=1e-12)


@pytest.mark.parametrize("rough, ms", [(0.0, False), (0.4, False), (0.4, True)])
def test_tinted_layer_leaves_the_base_one_minus_its_largest_channel(rough, ms):
    """Cycles' closure_layering_weight: the base is weighted by 1 - max over channels of the
    layer's albedo estimate (F0 tint + (1 - F0 tint) s per channel)."""
    ior, tint, color = 1.5, (0.1, 1.0, 0.4), (0.6, 0.3, 0.1)
    f0 = f0_from_eta(ior)
    for wo in (direction(10), direction(60, 30)):
        s = (layer_albedo(wo[2], rough, ior) - f0) / (1.0 - f0)
        albedo = np.array([f0 * t + (1.0 - f0 * t) * s for t in tint])
        if ms:
            factor = np.array(energy_factor(tuple(f0 * t + (1.0 - f0 * t) * _s_avg(ior) for t in tint),
                                            rough, wo[2]))
            albedo *= factor * _table_e(rough, wo[2])
        kd = (1.0 - albedo.max()) / math.pi
        wi = direction(45, 100)
        f = np.array(lobe_eval(PLASTIC, color, rough, ior, FRESNEL_CONSTANT, tint, ms, wo, wi)[0])
        black = (0.0, 0.0, 0.0)
        layer = np.array(lobe_eval(PLASTIC, black, rough, ior, FRESNEL_CONSTANT, tint, ms, wo, wi)[0])
        np.testing.assert_allclose(f - layer, np.array(color) * kd, rtol=1e-9, atol=1e-15)


def _s_avg(ior: float) -> float:
    f0 = f0_from_eta(ior)
    fss = (ior - 1.0) / (4.08567 + 1.00071 * ior)  # Cycles' fresnel_dielectric_Fss
    return min(max((fss - f0) / (1.0 - f0), 0.0), 1.0)


def _table_e(rough: float, mu: float) -> float:
    """E from the table with Cycles' bilinear read, as multiscatter.ggx_energy."""
    x, y = rough * 31, mu * 31
    i, j = min(int(x), 30), min(int(y), 30)
    tx, ty = x - i, y - j
    e = GGX_E
    return ((1 - ty) * ((1 - tx) * e[j, i] + tx * e[j, i + 1])
            + ty * ((1 - tx) * e[j + 1, i] + tx * e[j + 1, i + 1]))


def test_plain_lobes_are_unchanged():
    """Without multiscatter and with a white tint the plastic is exactly the old lobe: the
    layer's Fresnel is the exact dielectric one."""
    wo, wi = direction(30), direction(40, 180)
    f = lobe_eval(PLASTIC, (0.5, 0.4, 0.3), 0.3, 1.5, *PLAIN, wo, wi)[0]
    assert f[0] > f[1] > f[2] > 0.0
