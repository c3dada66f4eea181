"""Per-closure normals: which normal each lobe of a bumped surface sees, and which bump factor
weighs it, as Cycles gives them to its closures.

A surface is bumped where a program sets the shading normal (Normal Map or Bump into a BSDF's
Normal; renderer.shading.apply). Cycles then gives
  * diffuse closures (Diffuse BSDF, the Principled base) the program's normal N as it is
    (svm/closure.h: `bsdf->N = N`), and weighs them by the whole bump_shadowing_term
    (closure/bsdf.h): 0 for a direction on the wrong side of the mesh's own smooth normal for
    N (renderer.shading.normals.bump_visible), else a GGX shadowing of N's tilt that softens
    the terminator;
  * specular closures (metal, the Principled dielectric layer, coat, glass, Glossy) the normal
    maybe_ensure_valid_specular_reflection(sd, N) (closure/bsdf_util.h): N raised toward the
    geometric normal until its mirror reflection of the view direction stays above the
    surface (normals.valid_specular_normal). bump_shadowing_term gives them only the side test,
    in evaluation; a direction they sample is instead rejected below the geometric normal
    (closure/bsdf_microfacet.h), which on a flat mesh is the same test, so Haze applies the
    side test to their samples too.
Haze's DIFFUSE lobe and PLASTIC's base are diffuse closures; PLASTIC's layer, the conductors
and the dielectric specular ones; TRANSPARENT has no normal.

The surface stage shades a bumped surface in the frame of the specular normal (on the mesh's
front side, as every shading normal there) and hands the lobes `bump` = (n_map, n_mesh): the
program's normal and the mesh's smooth normal in that frame, front side too. Bump factors do
not change when both normals turn around, so they need no side. Without a program's normal
all these normals are the mesh's and the unbumped kernels (lobe.lobe_eval...) run.
"""

from renderer.bsdfs.warp import square_to_cosine_hemisphere
from renderer.kernels import inline_kernel
from renderer.kernels.vecmath import INV_PI, dot, neg, onb, scale, to_world
from renderer.shading.normals import bump_shadowing, bump_visible, valid_specular_normal

_ZERO3 = (0.0, 0.0, 0.0)
_UP = (0.0, 0.0, 1.0)


@inline_kernel
def specular_normal(n_map, ng, d, front):
    """The specular closures' normal (front side of ng) for the program's normal n_map (front
    side) hit along d: Cycles' ensure_valid_specular_reflection, on the viewer's side."""
    if front:
        return valid_specular_normal(ng, neg(d), n_map)
    return neg(valid_specular_normal(neg(ng), neg(d), neg(n_map)))


@inline_kernel
def diffuse_factor(n_mesh, n, w):
    """A diffuse closure of normal n sending light along w: Cycles' whole bump_shadowing_term."""
    return bump_shadowing(n_mesh, n, w)


@inline_kernel
def specular_factor(n_mesh, w):
    """A specular closure (normal z, the shading frame's) sending light along w: the side test."""
    return 1.0 if bump_visible(n_mesh, _UP, w) else 0.0


@inline_kernel
def diffuse_eval_bumped(color, n, n_mesh, wi):
    """(f cos, pdf) of a Lambertian closure of normal n (viewer's side) for wi, times its bump
    factor. Like Cycles' bsdf_diffuse_eval it looks at wi only, not at which side of n the
    viewer is."""
    c = dot(n, wi)
    if c <= 0.0:
        return _ZERO3, 0.0
    return scale(color, INV_PI * c * diffuse_factor(n_mesh, n, wi)), c * INV_PI


@inline_kernel
def diffuse_sample_bumped(color, n, n_mesh, u1, u2):
    """(wi, weight = f cos / pdf, pdf, False): cosine-weighted about n (viewer's side)."""
    s, t = onb(n)
    local = square_to_cosine_hemisphere(u1, u2)
    if local[2] <= 0.0:
        return local, _ZERO3, 0.0, False
    wi = to_world(local, s, t, n)
    return wi, scale(color, diffuse_factor(n_mesh, n, wi)), local[2] * INV_PI, False
