"""Phase function of a medium stack: the mixture of the entries' Henyey-Greenstein lobes.

Overlapping media add their scattering, so at point p the stack scatters with

    f_k(wi) = sum_i sigma_s,i,k(p) hg(g_i, cos) / sum_i sigma_s,i,k(p)      per channel k.

An entry is picked with probability w_i = lum(sigma_s,i(p)) / sum_j lum(sigma_s,j(p)) (Cycles
picks closures by their luminance weight) and its lobe sampled, so the sampling pdf is the
luminance mixture sum_i w_i hg_i. With one entry, or entries of equal g, f == pdf; when
chromatic entries of different g overlap they differ, which is why sampling returns the
weight f / pdf per channel instead of assuming 1.
"""

from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import dot, luminance
from renderer.media.grid import medium_density
from renderer.media.stack import EMPTY, MAX_STACK
from renderer.media.table import phase_g, sigma_s
from renderer.phase.hg import hg_eval, hg_sample


@kernel
def _density(mt, m, p):
    """medium_density compiled once for the phase functions' four lookups (inlined, each one
    compiled the grid lookup again); reached only by stacks of more than one entry."""
    return medium_density(mt, m, p)


@inline_kernel
def _mixture(mt, stack, p, cos_theta):
    """(f3, pdf) of the stack's phase mixture at p for cos_theta = dot(d, wi)."""
    if stack[1] == EMPTY:  # one entry: no density lookups needed
        v = hg_eval(phase_g(mt, stack[0]), cos_theta)
        return (v, v, v), v
    f0 = f1 = f2 = 0.0
    n0 = n1 = n2 = 0.0
    pdf = 0.0
    wsum = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        rho = _density(mt, m, p)
        ss = sigma_s(mt, m)
        s = (rho * ss[0], rho * ss[1], rho * ss[2])
        v = hg_eval(phase_g(mt, m), cos_theta)
        w = luminance(s)
        pdf += w * v
        wsum += w
        f0 += s[0] * v
        f1 += s[1] * v
        f2 += s[2] * v
        n0 += s[0]
        n1 += s[1]
        n2 += s[2]
    if wsum <= 0.0:
        # Nothing scatters here (the distance sampler gives such a vertex weight 0);
        # fall back to the first lobe so the caller still gets a valid direction and pdf.
        v = hg_eval(phase_g(mt, stack[0]), cos_theta)
        return (v, v, v), v
    pdf /= wsum
    # A channel that does not scatter at p has weight 0 anyway; give it the pdf.
    return (f0 / n0 if n0 > 0.0 else pdf, f1 / n1 if n1 > 0.0 else pdf, f2 / n2 if n2 > 0.0 else pdf), pdf


@inline_kernel
def _pick_entry(mt, stack, p, u):
    """Entry chosen with probability proportional to lum(sigma_s(p))."""
    if stack[1] == EMPTY:
        return stack[0]
    wsum = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        wsum += _density(mt, m, p) * luminance(sigma_s(mt, m))
    if wsum <= 0.0:
        return stack[0]
    target = u * wsum
    acc = 0.0
    last = stack[0]
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        w = _density(mt, m, p) * luminance(sigma_s(mt, m))
        if w > 0.0:
            last = m
            acc += w
            if target < acc:
                return m
    return last


@kernel
def sample_phase(mt, stack, p, d, u_sel, u1, u2):
    """Scatter at world point p for propagation direction d: (wi, weight3, pdf).

    weight3 = f3 / pdf, the factor the path throughput is multiplied by ((1, 1, 1) unless
    chromatic entries of different g overlap); pdf is per steradian (for MIS).
    """
    m = _pick_entry(mt, stack, p, u_sel)
    wi, pdf_i = hg_sample(phase_g(mt, m), d, u1, u2)
    if stack[1] == EMPTY:
        return wi, (1.0, 1.0, 1.0), pdf_i
    f, pdf = _mixture(mt, stack, p, dot(d, wi))
    return wi, (f[0] / pdf, f[1] / pdf, f[2] / pdf), pdf


@kernel
def phase_eval(mt, stack, p, d, wi):
    """(f3, pdf) of scattering from propagation direction d into wi at p (for NEE / MIS)."""
    return _mixture(mt, stack, p, dot(d, wi))


@kernel
def phase_pdf(mt, stack, p, d, wi):
    """Sampling pdf of sample_phase for direction wi (per steradian)."""
    return _mixture(mt, stack, p, dot(d, wi))[1]
