"""The Principled BSDF to closure terms, with Cycles' semantics (svm/closure.h), including
the inputs shader programs may drive: Base Color, Metallic, Roughness, Transmission Weight,
IOR, Alpha, Emission Color and Strength (closure_bindings)."""

from __future__ import annotations

import numpy as np

from renderer.shading.names import VECTOR_OPS

from .closure_bindings import (
    capped_color,
    emission_binds,
    factor_pair,
    normal_bind,
    roughness_bind,
    scaled_by,
)
from .node_closures import (
    Inputs,
    Term,
    adjusted_specular_ior,
    reflection_kind,
    rgb,
    saturate,
    warn_ignored_distribution,
)


def principled_ignored_inputs(read: Inputs) -> list[str]:
    """Inputs of the Principled BSDF set to something Haze cannot render."""
    checks = [
        ("Coat Weight", read("Coat Weight") > 0.0),
        ("Sheen Weight", read("Sheen Weight") > 0.0),
        ("Subsurface Weight (rendered as diffuse)", read("Subsurface Weight") > 0.0),
        ("Anisotropic", read("Anisotropic") > 0.0),
        ("Thin Film Thickness", read("Thin Film Thickness") > 0.0),
        ("Diffuse Roughness", read("Diffuse Roughness") > 0.0),
        ("Specular Tint above 1 (clamped to 1)", np.any(np.asarray(read("Specular Tint")) > 1.0)),
    ]
    return [name for name, ignored in checks if ignored]


def principled_emission(read: Inputs, weight: float) -> list[Term]:
    """Emission Color x Emission Strength, scaled by the constant part of the alpha weight."""
    binds = emission_binds(read, "Emission Color", "Emission Strength")
    if binds:
        if weight != 1.0:
            binds = (("emission", _times(read, binds[0][1], weight)),)
        return [Term("emission", np.ones(3), binds=binds)]
    emission = np.asarray(read("Emission Color")) * read("Emission Strength")
    if np.any(emission != 0.0):
        return [Term("emission", np.broadcast_to(emission * weight, (3,)).astype(np.float64))]
    return []


def _times(read: Inputs, reg, factor: float):
    p = read.program
    multiply = VECTOR_OPS.index("MULTIPLY")
    return p.emit("vector_math", 3, reg, p.const((factor,) * 3), reg, p.const(1.0), i0=multiply)


def ior_binds(read: Inputs, ior_reg, level: float) -> tuple:
    """The dielectric layer's IOR from a program: the node's IOR itself at the default
    Specular IOR Level 0.5 (other levels fold the IOR to its constant, warned)."""
    if ior_reg is None:
        return ()
    if level != 0.5:
        read.warn("a textured IOR with Specular IOR Level other than 0.5 is rendered with the IOR "
                  "socket's own value on the specular layer")
        return ()
    return (("ior", ior_reg),)


def shader_principled(read: Inputs) -> list[Term]:
    """Cycles' Principled BSDF (svm/closure.h) as Haze lobes: alpha, metal (F82-tint Fresnel of
    Base Color and Specular Tint), glass (refraction tinted by sqrt(Base Color), reflection
    untinted), then the dielectric specular layer (F0 x Specular Tint) over diffuse (Haze's
    "plastic"). Multiscatter GGX (the node's default) compensates the metal's and the
    layer's energy as Cycles does. A textured Alpha weighs a transparent closure by 1 - a
    and everything else by a per shading point, as Cycles does."""
    ignored = principled_ignored_inputs(read)
    if ignored:
        read.warn("ignored inputs: " + ", ".join(ignored))
    base_reg, rough, normal = read.varying("Base Color"), roughness_bind(read), normal_bind(read)
    metal_reg, glass_reg = read.varying("Metallic"), read.varying("Transmission Weight")
    alpha_reg, ior_reg = read.varying("Alpha"), read.varying("IOR")
    base = np.maximum(read("Base Color"), 0.0)
    specular_tint = rgb(np.clip(read("Specular Tint"), 0.0, 1.0))
    multiscatter = warn_ignored_distribution(read, read.node)
    metallic, alpha = saturate(read("Metallic")), saturate(read("Alpha"))
    roughness, transmission = saturate(read("Roughness")), saturate(read("Transmission Weight"))
    ior = max(read("IOR"), 1e-5)
    weight = 1.0
    if alpha_reg is None and alpha < 1.0:
        transparent = [Term("transparent", np.full(3, 1.0 - alpha))]
        weight = alpha
    elif alpha_reg is not None:
        a, rest = factor_pair(read.program, alpha_reg)
        transparent = [Term("transparent", np.ones(3), scales=(rest,))]
    else:
        transparent = []
    terms: list[Term] = principled_emission(read, weight)
    under = ()  # weight scales of the layers under the metal when Metallic varies
    if metallic > 0.0 or metal_reg is not None:
        binds = rough + normal + (() if base_reg is None else (("color", capped_color(read, base_reg)),))
        kind = "rough_conductor" if rough else reflection_kind(roughness)
        metal_weight, over = weight * metallic, ()
        if metal_reg is not None:  # the program weighs the metal by m and what is under by 1 - m
            (m, rest), metal_weight = factor_pair(read.program, metal_reg), weight
            over, under = (m,), (rest,)
        terms.append(Term(kind, np.full(3, metal_weight),
                          color=rgb(np.minimum(base, 1.0)), roughness=roughness, fresnel="f82",
                          tint=specular_tint, binds=binds, scales=over, multiscatter=multiscatter))
        weight *= 1.0 if metal_reg is not None else 1.0 - metallic
    if (transmission > 0.0 or glass_reg is not None) and weight > 0.0:
        if roughness > 0.0 or rough:
            read.warn(f"rough transmission (Roughness {roughness:g}) is rendered as smooth glass")
        binds = normal + (() if base_reg is None else (("color", capped_color(read, base_reg, 0.5)),))
        binds += () if ior_reg is None else (("ior", ior_reg),)
        glass_weight, over = weight * transmission, under
        if glass_reg is not None:  # as the metal: glass by t, the dielectric layer by 1 - t
            (t, rest), glass_weight = factor_pair(read.program, glass_reg), weight
            over, under = under + (t,), under + (rest,)
        terms.append(Term("dielectric", np.full(3, glass_weight),
                          color=rgb(np.sqrt(np.minimum(base, 1.0))), ior=ior, binds=binds, scales=over))
        weight *= 1.0 if glass_reg is not None else 1.0 - transmission
    if weight > 0.0:
        level = max(read("Specular IOR Level"), 0.0)
        eta = adjusted_specular_ior(ior, level)
        ior_bind = ior_binds(read, ior_reg, level)
        kind = "diffuse" if eta == 1.0 and not ior_bind else "plastic"
        binds = rough + normal + (() if base_reg is None else (("color", base_reg),)) + ior_bind
        layer = {} if kind == "diffuse" else {"tint": specular_tint, "multiscatter": multiscatter}
        terms.append(Term(kind, np.full(3, weight), color=rgb(base), roughness=roughness, ior=eta,
                          binds=binds, scales=under, **layer))
    if alpha_reg is not None:
        terms = scaled_by(terms, a)
    return transparent + terms

