"""BSDF lobes as numba kernels.

Every lobe works in the local shading frame: z is the shading normal on the mesh's front
side, `wo` points from the surface back along the path, `wi` toward the next vertex.
`f` never includes the cosine; pdfs are per solid angle of `wi`.

This module binds the integer codes of the scene's vocabulary (renderer.scene: LOBE_KINDS,
FRESNEL_MODES, SIDES) to module-level constants the kernels dispatch on
(renderer.bsdfs.lobe); the lobe table itself is laid out in renderer.bsdfs.layout.
"""

from renderer.scene import FRESNEL_MODES, LOBE_KINDS, SIDES

DIFFUSE = LOBE_KINDS["diffuse"]
DIELECTRIC = LOBE_KINDS["dielectric"]  # smooth glass
CONDUCTOR = LOBE_KINDS["conductor"]  # smooth mirror tinted by color
ROUGH_CONDUCTOR = LOBE_KINDS["rough_conductor"]  # GGX reflection, Cycles' Glossy BSDF
PLASTIC = LOBE_KINDS["plastic"]  # GGX dielectric coat over a Lambertian base
TRANSPARENT = LOBE_KINDS["transparent"]  # straight pass-through tinted by color

# Fresnel of the conductor lobes (field "fresnel" of the lobe table):
#   constant  F = color at every angle (Cycles' Glossy BSDF);
#   f82       Cycles' F82-tint Schlick curve: F0 = color, the value near 82 degrees scaled by
#             `tint` (Principled BSDF metallic, Metallic BSDF's F82 mode).
FRESNEL_CONSTANT = FRESNEL_MODES["constant"]
FRESNEL_F82 = FRESNEL_MODES["f82"]

# Roughness below which a GGX lobe is treated as perfectly smooth (alpha = roughness^2 < 1e-6:
# the lobe is then far narrower than any pixel and D overflows usefulness).
SMOOTH_ROUGHNESS = 1e-3

# Bits of the lobe table's "sides" field.
SIDE_FRONT = SIDES["front"]
SIDE_BACK = SIDES["back"]
