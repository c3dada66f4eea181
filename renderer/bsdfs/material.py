"""A material's BSDF: the weighted sum of its lobes on the side that was hit.

The material table `mt` (renderer.bsdfs.table.build_material_table) is the pair (mats,
lobes) laid out in renderer.bsdfs.layout: per material its first lobe and lobe count, per
lobe its kind, weight, color, roughness, ior, sides bitmask, Fresnel mode, tint and
multiscatter flag.

Sampling picks one lobe with probability proportional to its selection weight
luminance(weight * color) (luminance(weight) for dielectric and plastic, whose coat reflects
regardless of colour; for an F82 conductor `color` is F0 and the mean reflectance over the
hemisphere, mix(F0, 1, 1/21), is used instead, which is > 0 even for a black F0), over the
lobes present on the hit side. A non-delta sample is then re-weighted with the whole
material (f_total |cos| / pdf_total, pdf_total = the mixture pdf sum_j P_j pdf_j), which is
what MIS with light sampling needs.

Events of bsdf_sample:
    0 ABSORB        no valid sample; stop the path
    1 SCATTER       non-delta scatter, pdf = mixture pdf for MIS
    2 DELTA         delta scatter, weight = lobe weight * value / P_lobe, pdf = 0 (no MIS)
    3 PASS_THROUGH  transparent lobe chosen or no lobes on this side: wi = -wo, not a bounce

bsdf_eval_bumped and bsdf_sample_bumped are the same on a bumped surface, whose lobes have
their own normals (renderer.bsdfs.closure_normals).
"""

from renderer.bsdfs import DIELECTRIC, FRESNEL_F82, PLASTIC, SIDE_BACK, SIDE_FRONT, TRANSPARENT
from renderer.bsdfs.layout import (
    L_COLOR,
    L_FRESNEL,
    L_IOR,
    L_KIND,
    L_MS,
    L_ROUGH,
    L_SIDES,
    L_TINT,
    L_WEIGHT,
    M_COUNT,
    M_FIRST,
)
from renderer.bsdfs.lobe import lobe_eval, lobe_eval_bumped, lobe_sample, lobe_sample_bumped
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import add, luminance, max3, mul, neg, scale

EVENT_ABSORB = 0
EVENT_SCATTER = 1
EVENT_DELTA = 2
EVENT_PASS_THROUGH = 3

_ZERO3 = (0.0, 0.0, 0.0)
_NO_LOBES = -1  # _pick_lobe's answers when it picks none
_NOTHING = -2


@inline_kernel
def _present(sides, front):
    return (int(sides) & (SIDE_FRONT if front else SIDE_BACK)) != 0


@inline_kernel
def _row3(a, j, c):
    return (float(a[j, c]), float(a[j, c + 1]), float(a[j, c + 2]))


@inline_kernel
def _selection_weight(kind, weight, color, fresnel):
    if kind == DIELECTRIC or kind == PLASTIC:
        return max(luminance(weight), 0.0)
    if fresnel == FRESNEL_F82:
        k = 1.0 / 21.0
        color = (color[0] + k * (1.0 - color[0]), color[1] + k * (1.0 - color[1]),
                 color[2] + k * (1.0 - color[2]))
    return max(luminance(mul(weight, color)), 0.0)


@inline_kernel
def _lobe_selection(lobes, j):
    return _selection_weight(int(lobes[j, L_KIND]), _row3(lobes, j, L_WEIGHT), _row3(lobes, j, L_COLOR),
                             int(lobes[j, L_FRESNEL]))


@inline_kernel
def _pick_lobe(lobes, start, end, front, u_sel):
    """(lobe, P_lobe): lobe j picked with probability sel_j / total over the lobes on this side
    (the last one absorbs round-off); lobe _NO_LOBES when none is on this side, _NOTHING when
    none can be picked."""
    total = 0.0
    n_present = 0
    for j in range(start, end):
        if _present(lobes[j, L_SIDES], front):
            n_present += 1
            total += _lobe_selection(lobes, j)
    if n_present == 0:
        return _NO_LOBES, 0.0
    if total <= 0.0:
        return _NOTHING, 0.0
    target = u_sel * total
    acc = 0.0
    chosen = -1
    sel = 0.0
    for j in range(start, end):
        if not _present(lobes[j, L_SIDES], front):
            continue
        s = _lobe_selection(lobes, j)
        if s <= 0.0:
            continue
        chosen = j
        sel = s
        acc += s
        if target < acc:
            break
    return chosen, sel / total


@inline_kernel
def bsdf_has_lobes(mt, m, front):
    mats, lobes = mt
    start = mats[m, M_FIRST]
    for j in range(start, start + mats[m, M_COUNT]):
        if _present(lobes[j, L_SIDES], front):
            return True
    return False


@inline_kernel
def bsdf_eval(mt, m, front, wo, wi):
    """(f, pdf): f = sum_j weight_j f_j, pdf = sum_j P_j pdf_j over the lobes on this side."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    f = _ZERO3
    pdf = 0.0
    total = 0.0
    for j in range(start, start + mats[m, M_COUNT]):
        if not _present(lobes[j, L_SIDES], front):
            continue
        kind = int(lobes[j, L_KIND])
        weight = _row3(lobes, j, L_WEIGHT)
        color = _row3(lobes, j, L_COLOR)
        fresnel = int(lobes[j, L_FRESNEL])
        sel = _selection_weight(kind, weight, color, fresnel)
        total += sel
        fj, pj = lobe_eval(kind, color, float(lobes[j, L_ROUGH]), float(lobes[j, L_IOR]), fresnel,
                           _row3(lobes, j, L_TINT), lobes[j, L_MS] != 0.0, wo, wi)
        f = (f[0] + weight[0] * fj[0], f[1] + weight[1] * fj[1], f[2] + weight[2] * fj[2])
        pdf += sel * pj
    return f, (pdf / total if total > 0.0 else 0.0)


@inline_kernel
def bsdf_sample(mt, m, front, wo, u_sel, u1, u2, u3):
    """(wi, weight, pdf, event); see the module docstring for the events."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    end = start + mats[m, M_COUNT]
    through = (-wo[0], -wo[1], -wo[2])
    chosen, p_lobe = _pick_lobe(lobes, start, end, front, u_sel)
    if chosen == _NO_LOBES:
        return through, (1.0, 1.0, 1.0), 0.0, EVENT_PASS_THROUGH
    if chosen < 0:
        return through, _ZERO3, 0.0, EVENT_ABSORB

    kind = int(lobes[chosen, L_KIND])
    weight = _row3(lobes, chosen, L_WEIGHT)
    color = _row3(lobes, chosen, L_COLOR)
    wi, w, pdf, delta = lobe_sample(
        kind, color, float(lobes[chosen, L_ROUGH]), float(lobes[chosen, L_IOR]),
        int(lobes[chosen, L_FRESNEL]), _row3(lobes, chosen, L_TINT), lobes[chosen, L_MS] != 0.0, wo, u1, u2,
        u3
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


@inline_kernel
def _lobe(lobes, j):
    """Lobe j's (kind, weight, color, roughness, ior, fresnel, tint, multiscatter)."""
    return (int(lobes[j, L_KIND]), _row3(lobes, j, L_WEIGHT), _row3(lobes, j, L_COLOR),
            float(lobes[j, L_ROUGH]), float(lobes[j, L_IOR]), int(lobes[j, L_FRESNEL]),
            _row3(lobes, j, L_TINT), lobes[j, L_MS] != 0.0)


@kernel
def bsdf_eval_bumped(mt, m, front, bump, wo, wi):
    """bsdf_eval on a bumped surface, each lobe on its own normal (lobe_eval_bumped; bump as
    renderer.bsdfs.closure_normals): (f cos, pdf), f cos = sum_j weight_j f_j |cos_j| with each
    lobe's own cosine and bump factor, pdf = sum_j P_j pdf_j as bsdf_eval's."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    f = _ZERO3
    pdf = 0.0
    total = 0.0
    for j in range(start, start + mats[m, M_COUNT]):
        if not _present(lobes[j, L_SIDES], front):
            continue
        kind, weight, color, rough, ior, fresnel, tint, ms = _lobe(lobes, j)
        sel = _selection_weight(kind, weight, color, fresnel)
        total += sel
        fj, pj = lobe_eval_bumped(kind, color, rough, ior, fresnel, tint, ms, bump, wo, wi)
        f = add(f, mul(weight, fj))
        pdf += sel * pj
    return f, (pdf / total if total > 0.0 else 0.0)


@kernel
def bsdf_sample_bumped(mt, m, front, bump, wo, u_sel, u1, u2, u3):
    """bsdf_sample on a bumped surface; a scatter's weight is bsdf_eval_bumped's f cos / pdf.
    A drawn direction whose lobe weighs it zero (its bump factor) still scatters: the other
    lobes may reflect there, and the mixture pdf counts the chosen lobe's density."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    through = neg(wo)
    chosen, p_lobe = _pick_lobe(lobes, start, start + mats[m, M_COUNT], front, u_sel)
    if chosen == _NO_LOBES:
        return through, (1.0, 1.0, 1.0), 0.0, EVENT_PASS_THROUGH
    if chosen < 0:
        return through, _ZERO3, 0.0, EVENT_ABSORB
    kind, weight, color, rough, ior, fresnel, tint, ms = _lobe(lobes, chosen)
    wi, w, pdf, delta = lobe_sample_bumped(kind, color, rough, ior, fresnel, tint, ms, bump, wo, u1, u2, u3)
    if kind == TRANSPARENT or delta:
        if max3(w) <= 0.0:
            return wi, _ZERO3, 0.0, EVENT_ABSORB
        event = EVENT_PASS_THROUGH if kind == TRANSPARENT else EVENT_DELTA
        return wi, scale(mul(weight, w), 1.0 / p_lobe), 0.0, event
    if pdf <= 0.0:  # the lobe drew no direction
        return wi, _ZERO3, 0.0, EVENT_ABSORB
    f, pdf_total = bsdf_eval_bumped(mt, m, front, bump, wo, wi)
    if pdf_total <= 0.0:
        return wi, _ZERO3, 0.0, EVENT_ABSORB
    return wi, scale(f, 1.0 / pdf_total), pdf_total, EVENT_SCATTER
