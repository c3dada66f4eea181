"""A material's BSDF: the weighted sum of its lobes on the side that was hit.

The material table `mt` (renderer.bsdfs.table.build_material_table) is one tuple
    (mat_lobe_start i32 (M,), mat_lobe_count i32 (M,), lobe_kind i32 (L,),
     lobe_weight f32 (L, 3), lobe_color f32 (L, 3), lobe_rough f32 (L,),
     lobe_ior f32 (L,), lobe_sides i32 (L,) bitmask 1 = front, 2 = back).

Sampling picks one lobe with probability proportional to its selection weight
luminance(weight * color) (luminance(weight) for dielectric and plastic, whose coat reflects
regardless of colour), over the lobes present on the hit side. A non-delta sample is then
re-weighted with the whole material (f_total |cos| / pdf_total, pdf_total = the mixture pdf
sum_j P_j pdf_j), which is what MIS with light sampling needs.

Events of bsdf_sample:
    0 ABSORB        no valid sample; stop the path
    1 SCATTER       non-delta scatter, pdf = mixture pdf for MIS
    2 DELTA         delta scatter, weight = lobe weight * value / P_lobe, pdf = 0 (no MIS)
    3 PASS_THROUGH  transparent lobe chosen or no lobes on this side: wi = -wo, not a bounce
"""

from numba import njit

from renderer.bsdfs import DIELECTRIC, PLASTIC, SIDE_BACK, SIDE_FRONT, TRANSPARENT
from renderer.bsdfs.lobe import lobe_eval, lobe_sample
from renderer.kernels.vecmath import luminance, mul, scale

EVENT_ABSORB = 0
EVENT_SCATTER = 1
EVENT_DELTA = 2
EVENT_PASS_THROUGH = 3

_ZERO3 = (0.0, 0.0, 0.0)


@njit(cache=True, inline="always")
def _present(sides, front):
    return (sides & (SIDE_FRONT if front else SIDE_BACK)) != 0


@njit(cache=True, inline="always")
def _row3(a, j):
    return (float(a[j, 0]), float(a[j, 1]), float(a[j, 2]))


@njit(cache=True)
def _selection_weight(kind, weight, color):
    if kind == DIELECTRIC or kind == PLASTIC:
        return max(luminance(weight), 0.0)
    return max(luminance(mul(weight, color)), 0.0)


@njit(cache=True)
def bsdf_has_lobes(mt, m, front):
    start = mt[0][m]
    for j in range(start, start + mt[1][m]):
        if _present(mt[7][j], front):
            return True
    return False


@njit(cache=True)
def bsdf_eval(mt, m, front, wo, wi):
    """(f, pdf): f = sum_j weight_j f_j, pdf = sum_j P_j pdf_j over the lobes on this side."""
    lobe_kind, lobe_weight, lobe_color, lobe_rough, lobe_ior, lobe_sides = mt[2:]
    start = mt[0][m]
    f = _ZERO3
    pdf = 0.0
    total = 0.0
    for j in range(start, start + mt[1][m]):
        if not _present(lobe_sides[j], front):
            continue
        kind = lobe_kind[j]
        weight = _row3(lobe_weight, j)
        color = _row3(lobe_color, j)
        sel = _selection_weight(kind, weight, color)
        total += sel
        fj, pj = lobe_eval(kind, color, float(lobe_rough[j]), float(lobe_ior[j]), wo, wi)
        f = (f[0] + weight[0] * fj[0], f[1] + weight[1] * fj[1], f[2] + weight[2] * fj[2])
        pdf += sel * pj
    return f, (pdf / total if total > 0.0 else 0.0)


@njit(cache=True)
def bsdf_sample(mt, m, front, wo, u_sel, u1, u2, u3):
    """(wi, weight, pdf, event); see the module docstring for the events."""
    lobe_kind, lobe_weight, lobe_color, lobe_rough, lobe_ior, lobe_sides = mt[2:]
    start = mt[0][m]
    end = start + mt[1][m]
    through = (-wo[0], -wo[1], -wo[2])
    total = 0.0
    n_present = 0
    for j in range(start, end):
        if _present(lobe_sides[j], front):
            n_present += 1
            total += _selection_weight(lobe_kind[j], _row3(lobe_weight, j), _row3(lobe_color, j))
    if n_present == 0:
        return through, (1.0, 1.0, 1.0), 0.0, EVENT_PASS_THROUGH
    if total <= 0.0:
        return through, _ZERO3, 0.0, EVENT_ABSORB

    # Pick lobe `chosen` with probability sel / total (the last one absorbs round-off).
    target = u_sel * total
    acc = 0.0
    chosen = -1
    sel = 0.0
    for j in range(start, end):
        if not _present(lobe_sides[j], front):
            continue
        s = _selection_weight(lobe_kind[j], _row3(lobe_weight, j), _row3(lobe_color, j))
        if s <= 0.0:
            continue
        chosen = j
        sel = s
        acc += s
        if target < acc:
            break
    p_lobe = sel / total

    kind = lobe_kind[chosen]
    weight = _row3(lobe_weight, chosen)
    color = _row3(lobe_color, chosen)
    wi, w, pdf, delta = lobe_sample(
        kind, color, float(lobe_rough[chosen]), float(lobe_ior[chosen]), wo, u1, u2, u3
    )
    if w[0] == 0.0 and w[1] == 0.0 and w[2] == 0.0:
        return wi, _ZERO3, 0.0, EVENT_ABSORB
    if kind == TRANSPARENT:
        return wi, scale(mul(weight, w), 1.0 / p_lobe), 0.0, EVENT_PASS_THROUGH
    if delta:
        return wi, scale(mul(weight, w), 1.0 / p_lobe), 0.0, EVENT_DELTA

    f, pdf_total = bsdf_eval(mt, m, front, wo, wi)
    if pdf_total <= 0.0:
        return wi, _ZERO3, 0.0, EVENT_ABSORB
    return wi, scale(f, abs(wi[2]) / pdf_total), pdf_total, EVENT_SCATTER
