"""The integrator's settings as the kernels read them: one int64 array, `cfg`, indexed by CFG_*.

Kernels take the array instead of a dozen scalar arguments; its layout is declared once
here by field name, and the CFG_* integers bound from it are compile-time constants.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..layout import Layout

if TYPE_CHECKING:
    from ..compile import CompiledScene
    from ..scene import IntegratorSettings

CONFIG = Layout("integrator config", [
    ("max_bounces", 1),
    ("rr_depth", 1),
    ("sampling", 1),  # SAMPLING_*
    ("delta_tr", 1),  # shadow transmittance by delta tracking (else ratio)
    ("uniform_channel", 1),  # distance sampling picks channels uniformly (else by throughput)
    ("equiangular", 1),
    ("has_media", 1),
    ("walk_shadows", 1),  # shadow rays may pass interfaces (walk_shadows, not one occlusion test)
    ("nee_batch", 1),  # homogeneous next-event vertices in SIMD batches (nee_batch); 0 = scalar
    ("film_transparent", 1),  # Film > Transparent: the world seen directly gives alpha 0
    ("aovs", 1),  # write the render passes' columns of L (integrator.paths AOV_*); 0 = none
    ("light_aovs", 1),  # also the light and colour passes' columns (needs aovs); 0 = none
])
CFG_MAX_BOUNCES = CONFIG.offset("max_bounces")
CFG_RR_DEPTH = CONFIG.offset("rr_depth")
CFG_SAMPLING = CONFIG.offset("sampling")
CFG_DELTA_TR = CONFIG.offset("delta_tr")
CFG_UNIFORM_CHANNEL = CONFIG.offset("uniform_channel")
CFG_EQUIANGULAR = CONFIG.offset("equiangular")
CFG_HAS_MEDIA = CONFIG.offset("has_media")
CFG_WALK_SHADOWS = CONFIG.offset("walk_shadows")
CFG_NEE_BATCH = CONFIG.offset("nee_batch")
CFG_FILM_TRANSPARENT = CONFIG.offset("film_transparent")
CFG_AOVS = CONFIG.offset("aovs")
CFG_LIGHT_AOVS = CONFIG.offset("light_aovs")
CFG_SIZE = CONFIG.size

# How direct light is estimated: both techniques weighted by MIS, light sampling only, or
# BSDF/phase sampling only.
SAMPLING_MIS, SAMPLING_NEE, SAMPLING_BSDF = 0, 1, 2
SAMPLING_CODES = {"mis": SAMPLING_MIS, "nee": SAMPLING_NEE, "bsdf": SAMPLING_BSDF}


def make_config(cs: CompiledScene, settings: IntegratorSettings) -> np.ndarray:
    cfg = np.zeros(CFG_SIZE, np.int64)
    cfg[CFG_MAX_BOUNCES] = settings.max_bounces
    cfg[CFG_RR_DEPTH] = settings.rr_depth
    cfg[CFG_SAMPLING] = SAMPLING_CODES[settings.sampling]
    cfg[CFG_DELTA_TR] = settings.transmittance == "delta"
    cfg[CFG_UNIFORM_CHANNEL] = settings.distance_sampling == "uniform"
    cfg[CFG_EQUIANGULAR] = settings.equiangular
    cfg[CFG_HAS_MEDIA] = cs.has_media
    cfg[CFG_WALK_SHADOWS] = cs.needs_shadow_walk
    cfg[CFG_NEE_BATCH] = 1
    cfg[CFG_FILM_TRANSPARENT] = cs.transparent
    cfg[CFG_AOVS] = cs.aovs or cs.light_aovs
    cfg[CFG_LIGHT_AOVS] = cs.light_aovs
    return cfg
