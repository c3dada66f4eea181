"""BSDF lobes as numba kernels.

Every lobe works in the local shading frame: z is the shading normal on the mesh's front
side, `wo` points from the surface back along the path, `wi` toward the next vertex.
`f` never includes the cosine; pdfs are per solid angle of `wi`.

This module only names the lobe kinds; the scene compiler maps `scene.Lobe.kind` through
LOBE_KINDS and the kernels dispatch on the integer (renderer.bsdfs.lobe).
"""

DIFFUSE = 0
DIELECTRIC = 1  # smooth glass
CONDUCTOR = 2  # smooth mirror tinted by color
ROUGH_CONDUCTOR = 3  # GGX reflection, Cycles' Glossy BSDF
PLASTIC = 4  # GGX dielectric coat over a Lambertian base
TRANSPARENT = 5  # straight pass-through tinted by color

LOBE_KINDS: dict[str, int] = {
    "diffuse": DIFFUSE,
    "dielectric": DIELECTRIC,
    "conductor": CONDUCTOR,
    "rough_conductor": ROUGH_CONDUCTOR,
    "plastic": PLASTIC,
    "transparent": TRANSPARENT,
}

# Fresnel of the conductor lobes (column L_FRESNEL of the lobe table):
#   constant  F = color at every angle (Cycles' Glossy BSDF);
#   f82       Cycles' F82-tint Schlick curve: F0 = color, the value near 82 degrees scaled by
#             `tint` (Principled BSDF metallic, Metallic BSDF's F82 mode).
FRESNEL_CONSTANT = 0
FRESNEL_F82 = 1
FRESNEL_MODES: dict[str, int] = {"constant": FRESNEL_CONSTANT, "f82": FRESNEL_F82}

# Roughness below which a GGX lobe is treated as perfectly smooth (alpha = roughness^2 < 1e-6:
# the lobe is then far narrower than any pixel and D overflows usefulness).
SMOOTH_ROUGHNESS = 1e-3

# Bitmask of lobe_sides in the material table.
SIDE_FRONT = 1
SIDE_BACK = 2
