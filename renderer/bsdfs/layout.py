"""The material table's flat layouts, declared by field name (renderer.layout).

The BSDF kernels (renderer.bsdfs.material) take a material table `mt`, the pair
    (mats  int32   (M, MATERIAL.size): per material, its lobes' place in `lobes`;
     lobes float32 (L, LOBE.size):     per lobe, its parameters),
built by renderer.bsdfs.table. Two arrays rather than one per field: every array handed to
a non-inlined numba function costs a reference-count round trip per call, which dominated
shading time (measured: 296 ns per diffuse bsdf_sample with eight arrays).
"""

from renderer.layout import Layout

# Material m owns lobes first .. first + count - 1.
MATERIAL = Layout("material", [("first", 1), ("count", 1)])
M_FIRST = MATERIAL.offset("first")
M_COUNT = MATERIAL.offset("count")

LOBE = Layout("lobe", [
    ("kind", 1),  # renderer.scene.LOBE_KINDS code
    ("weight", 3),  # RGB
    ("color", 3),  # RGB
    ("roughness", 1),
    ("ior", 1),
    ("sides", 1),  # bitmask, renderer.scene.SIDES (1 front, 2 back)
    ("fresnel", 1),  # renderer.scene.FRESNEL_MODES code
    ("tint", 3),  # RGB
    ("multiscatter", 1),  # 1: Cycles' Multiscatter GGX energy compensation (GGX lobes)
])
L_KIND = LOBE.offset("kind")
L_WEIGHT = LOBE.offset("weight")
L_COLOR = LOBE.offset("color")
L_ROUGH = LOBE.offset("roughness")
L_IOR = LOBE.offset("ior")
L_SIDES = LOBE.offset("sides")
L_FRESNEL = LOBE.offset("fresnel")
L_TINT = LOBE.offset("tint")
L_MS = LOBE.offset("multiscatter")
