"""Scene builders for the paper's media figures (plain renderer Scenes, no bpy).

Figure and sigma references are to shared/seed/volumetric-path-tracing.txt. Every builder
takes (size, spp) and returns a Scene; BUILDERS maps the gallery names to them. The scenes
sit in the Cornell box of examples.scenes ([-1, 1]^3, open toward the camera at +z), so
one unit is half the box.

Stand-ins: the paper's Ajax bust is replaced by a small mesh built here (`bust`: an
icosphere head on a box plinth) in the fire, and by a sphere where it holds water; the
pbrt cloud data of Fig. 2 is not reproduced.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from examples.scenes import FIG1_SIGMA_A, FIG1_SIGMA_S, box, cornell_box, diffuse, fog, icosphere, merge, quad
from renderer.media.generators import gaussian_smoke_density, smoke_ball_density
from renderer.scene import (
    Camera,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Medium,
    Mesh,
    Scene,
    SunLight,
)

# Fig. 1: "max-depth 5". The paper's integrator follows pbrt, whose maxDepth d gathers
# direct light at up to d path vertices; Cycles' max_bounces = d - 1 does the same.
FIG1_MAX_BOUNCES = 4
FIG5_SIGMA_A = (90.0, 90.0, 90.0)
FIG5_SIGMA_S = (10.0, 10.0, 10.0)
FIG6_SIGMA_A = (2.4, 4.5, 7.2)
FIG6_SIGMA_S = (5.6, 3.5, 0.8)
FIG6_G = -0.7
FIG8_SIGMA_A = (0.5, 0.25, 0.01)
FIG8_SIGMA_S = (0.01, 0.26, 0.5)
FIG8_G = -0.1
WATER_IOR = 1.33
MEDIA_MAX_BOUNCES = 16  # dense smoke and water need more than the Cornell box's 3
INTERFACE = "interface"  # the name of the invisible medium-boundary material


def interface_material() -> Material:
    """No lobes, no emission: a surface that only says where a medium begins."""
    return Material(INTERFACE)


def grid_box_mesh(name: str, medium: str, center, half) -> Mesh:
    """A closed interface box carrying `medium`, to enclose a grid medium's box."""
    v, i = box(center, half)
    return Mesh(name, v, i, [INTERFACE], medium=medium)


# ------------------------------------------------------------------------ Fig. 1: fog


def fog_cornell(size: int = 128, spp: int = 64, g: float = 0.0) -> Scene:
    """The Cornell box filled with the Fig. 1 fog (camera inside the fog)."""
    return cornell_box(size, spp, FIG1_MAX_BOUNCES, medium=fog(g))


def fog_isotropic(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 1a: g = 0."""
    return fog_cornell(size, spp, 0.0)


def fog_backward(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 1b: g = -0.9, light scatters back toward the lamp (a darker image)."""
    return fog_cornell(size, spp, -0.9)


def fog_forward(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 1c: g = 0.9, light scatters on away from the lamp (toward the camera)."""
    return fog_cornell(size, spp, 0.9)


# ------------------------------------------------------------- Fig. 3 / 5: smoke ball
# The Fig. 3 generator (smoke_ball_density) and Fig. 6's gaussian smoke live in
# renderer/media/generators.py, shared with the Blender add-on.


def grid_medium(name: str, density: np.ndarray, center, half, sigma_a, sigma_s, g: float = 0.0,
                **extra) -> Medium:
    """A grid medium filling the axis-aligned box center +- half."""
    c, h = np.asarray(center, np.float64), np.asarray(half, np.float64)
    return Medium(name, "grid", sigma_a=tuple(sigma_a), sigma_s=tuple(sigma_s), g=g, density=density,
                  p0=tuple(c - h), p1=tuple(c + h), **extra)


def with_grid_medium(scene: Scene, medium: Medium, margin: float = 0.01) -> Scene:
    """Add `medium` and an interface box slightly larger than its grid box (so that the
    box's faces never cut into the density)."""
    p0, p1 = np.asarray(medium.p0), np.asarray(medium.p1)
    scene.materials.append(interface_material())
    scene.media.append(medium)
    scene.meshes.append(grid_box_mesh(f"{medium.name}_box", medium.name, (p0 + p1) / 2,
                                      (p1 - p0) / 2 + margin))
    scene.integrator.max_bounces = MEDIA_MAX_BOUNCES
    return scene


def smoke_ball(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 5: the Fig. 3 ball (11^3 voxels, sigma_a 90, sigma_s 10, g 0) in the Cornell box."""
    ball = grid_medium("smoke", smoke_ball_density(11), (0.0, -0.25, 0.0), (0.6, 0.6, 0.6), FIG5_SIGMA_A,
                       FIG5_SIGMA_S)
    return with_grid_medium(cornell_box(size, spp, boxes=False), ball)


# ------------------------------------------------------------- Fig. 6: yellow smoke


YELLOW_SMOKE_PEAK = 0.6  # peak density: a translucent cloud about a unit across


def yellow_smoke(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 6: gaussian-random smoke with sigma_a [2.4, 4.5, 7.2], sigma_s [5.6, 3.5, 0.8],
    g -0.7 (blue is absorbed and red scattered: the smoke looks yellow)."""
    density = YELLOW_SMOKE_PEAK * gaussian_smoke_density()
    smoke = grid_medium("yellow_smoke", density, (0.0, -0.35, 0.0), (0.65, 0.65, 0.65),
                        FIG6_SIGMA_A, FIG6_SIGMA_S, FIG6_G)
    return with_grid_medium(cornell_box(size, spp, boxes=False), smoke)


# ------------------------------------------------------------- Fig. 7: fire


def bust(center=(0.0, -0.55, 0.0), scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The Ajax stand-in: a head (icosphere) on a plinth (box), two closed meshes merged."""
    c = np.asarray(center, np.float32)
    hv, hi = icosphere(3, 0.28 * scale)
    head = (hv + c + np.float32([0.0, 0.1 * scale, 0.0]), hi)
    plinth = box(c + np.float32([0.0, -0.3 * scale, 0.0]), (0.22 * scale, 0.15 * scale, 0.22 * scale), 20)
    return merge([head, plinth])


def fire_temperature(n: int = 32, seed: int = 7, peak: float = 3400.0) -> np.ndarray:
    """Kelvin: a hot core fading outward, with seeded lumpy variation (a ball of fire).
    (n, n, n) float32 indexed [z, y, x]; 0 K (no emission) outside radius 0.48."""
    rng = np.random.default_rng(seed)
    axis = (np.arange(n) + 0.5) / n - 0.5
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    r = np.sqrt(x * x + (y + 0.08) ** 2 * 0.7 + z * z)
    lumps = np.zeros_like(r)
    for _ in range(12):
        c = rng.normal(0.0, 0.2, 3)
        lumps += np.exp(-((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2) / (2 * 0.08**2))
    heat = np.clip(1.0 - r / 0.48, 0.0, 1.0) ** 0.6 * (0.6 + 0.4 * lumps / lumps.max())
    return (peak * heat).astype(np.float32)


def fire_ball(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 7: the bust (rough conductor, a microfacet BSDF as Ajax in the paper) inside a
    ball of fire: a temperature grid with blackbody emission (Cycles' Principled Volume
    units) and a thin smoke density that scatters the fire light. The Cornell lamp is
    dimmed so the fire is the main light."""
    scene = cornell_box(size, spp, boxes=False, light_radiance=(1.7, 1.2, 0.4))
    temperature = fire_temperature()
    smoke = np.clip(temperature / temperature.max(), 0.0, 1.0) ** 2
    fire = grid_medium("fire", smoke.astype(np.float32), (0.0, -0.35, 0.0), (0.65, 0.65, 0.65),
                       (0.3, 0.3, 0.3), (0.6, 0.6, 0.6), 0.3, temperature=temperature,
                       blackbody_intensity=1.0)
    v, i = bust()
    scene.materials.append(Material("bronze", [Lobe("rough_conductor", color=(0.95, 0.64, 0.54),
                                                    roughness=0.35)]))
    scene.meshes.append(Mesh("bust", v, i, ["bronze"]))
    return with_grid_medium(scene, fire)


# ------------------------------------------------------------- Fig. 8: underwater


def water_medium(scale: float = 1.0) -> Medium:
    """Fig. 8 water: sigma_a [0.5, 0.25, 0.01], sigma_s [0.01, 0.26, 0.5], g -0.1."""
    return Medium("water", sigma_a=FIG8_SIGMA_A, sigma_s=FIG8_SIGMA_S, g=FIG8_G, scale=scale)


def water_material() -> Material:
    """Smooth water surface: a white dielectric lobe, ior 1.33 (water over air)."""
    return Material("water_surface", [Lobe("dielectric", color=(1.0, 1.0, 1.0), ior=WATER_IOR)])


def widen_lamp(scene: Scene, factor: float) -> Scene:
    """Make the Cornell lamp `factor` times wider and deeper at the same power: caustics
    (light through smooth glass, found only by BSDF sampling) then converge much faster."""
    lamp = next(m for m in scene.meshes if m.name == "light")
    centre = lamp.vertices.mean(axis=0)
    lamp.vertices = ((lamp.vertices - centre) * np.float32([factor, 1.0, factor]) + centre).astype(np.float32)
    material = next(m for m in scene.materials if m.name == "light")
    material.emission = tuple(e / factor**2 for e in material.emission)
    return scene


def underwater(size: int = 128, spp: int = 64) -> Scene:
    """Fig. 8: Ajax made of water, here a water sphere: a dielectric surface (ior 1.33)
    around the Fig. 8 medium. (A sphere, not `bust()`: a medium's mesh must be one closed
    surface.) It is about a unit across while the paper's Ajax is tens of units, so the
    medium's `scale` (which multiplies both sigmas) stands in for that size. The lamp is
    widened (same power) to tame the glass's caustics."""
    scene = widen_lamp(cornell_box(size, spp, boxes=False), 2.5)
    scene.integrator.max_bounces = MEDIA_MAX_BOUNCES
    v, i = icosphere(4, 0.55)
    scene.materials.append(water_material())
    scene.media.append(water_medium(scale=4.0))
    scene.meshes.append(Mesh("water_bust", v + np.float32([0.0, -0.42, 0.0]), i, ["water_surface"],
                             medium="water"))
    return scene


# ------------------------------------------------ scenes with closed-form answers (tests)


def camera_at(position, fov: float = 40.0, look=(0.0, 0.0, -1.0)) -> Camera:
    """A camera at `position` looking along `look` (+y up unless looking straight up/down)."""
    z = -np.asarray(look, np.float64)
    z /= np.linalg.norm(z)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.99 else np.array([0.0, 0.0, -1.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, position
    return Camera(m, fov=fov)


# A 0.05 degree field of view: every camera ray is within 4.4e-4 rad of the view axis, so
# path lengths through slabs facing the camera differ from the axial one by < 1e-7.
PARALLEL_FOV = 0.05


def emitter_behind_box(media: list[Medium], boxes: list[tuple], radiance=(2.0, 3.0, 4.0), size: int = 4,
                       spp: int = 16) -> Scene:
    """A pure emitter (the plane z = -2 facing +z) seen through interface boxes along -z.

    boxes: (medium name, center, half extents) per box. The camera sits at z = 5, slightly
    off the axis (so no ray runs along a triangle's diagonal), with a nearly parallel view.
    """
    lv, li = quad((0.0, 0.0, -2.0), (3.0, 0.0, 0.0), (0.0, 3.0, 0.0))
    meshes = [Mesh("emitter", lv, li, ["emitter"])]
    for k, (medium, center, half) in enumerate(boxes):
        meshes.append(Mesh(f"box{k}", *box(center, half), [INTERFACE], medium=medium))
    return Scene(camera=camera_at((0.011, 0.017, 5.0), PARALLEL_FOV), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=8),
                 materials=[interface_material(), Material("emitter", [], emission=tuple(radiance))],
                 meshes=meshes, media=list(media))


def media_in_front_of_black(media: list[Medium], boxes: list[tuple], size: int = 4, spp: int = 4) -> Scene:
    """Interface boxes seen along -z against a black background (for emitting media)."""
    scene = emitter_behind_box(media, boxes, (0.0, 0.0, 0.0), size, spp)
    scene.meshes = scene.meshes[1:]
    scene.materials = scene.materials[:1]
    return scene


SUN_IRRADIANCE = (1.0, 2.0, 3.0)
PLANE_ALBEDO = 0.5


def sunlit_plane(size: int = 8, spp: int = 16) -> Scene:
    """A diffuse plane y = 0 (albedo PLANE_ALBEDO) under a sun straight overhead, seen from
    below any slab placed at y > 0.4: the camera rays never enter the slabs, only the sun's
    shadow rays do, straight up. With max_bounces 0 each pixel is
    albedo / pi * irradiance * T(shadow ray)."""
    pv, pi = quad((0.0, 0.0, 0.0), (0.0, 0.0, 4.0), (4.0, 0.0, 0.0))  # front face +y
    return Scene(camera=camera_at((0.0, 0.4, 2.0), 10.0, look=(0.0, -0.4, -2.0)), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=0),
                 materials=[interface_material(), diffuse("plane", (PLANE_ALBEDO,) * 3)],
                 meshes=[Mesh("plane", pv, pi, ["plane"])],
                 lights=[SunLight((0.0, 1.0, 0.0), SUN_IRRADIANCE)])


def add_slab(scene: Scene, medium: Medium | None, y0: float, y1: float, half_xz: float = 3.0) -> Scene:
    """Add an interface box spanning y0..y1 (and +-half_xz in x and z) carrying `medium`."""
    if medium is not None and all(m.name != medium.name for m in scene.media):
        scene.media.append(medium)
    name = medium.name if medium is not None else None
    v, i = box((0.0, (y0 + y1) / 2, 0.0), (half_xz, (y1 - y0) / 2, half_xz))
    scene.meshes.append(Mesh(f"slab{len(scene.meshes)}", v, i, [INTERFACE], medium=name))
    return scene


def furnace_medium(medium: Medium, shape: str = "box", camera_inside: bool = False,
                   surface: Material | None = None, size: int = 16, spp: int = 16,
                   max_bounces: int = 1000) -> Scene:
    """`medium` inside a closed mesh (the box [-1, 1]^3 or a unit icosphere) under a uniform
    environment of radiance 1; the mesh's material is `surface` (default: an interface).
    With an albedo-1 medium and a lossless surface every pixel is 1. The camera looks at the
    mesh from z = 4, or from its centre. Russian roulette is off (it would start after
    more bounces than a path may have)."""
    v, i = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)) if shape == "box" else icosphere(3, 1.0)
    surface = surface or interface_material()
    position = (0.0, 0.0, 0.0) if camera_inside else (0.0, 0.0, 4.0)
    return Scene(camera=camera_at(position, 60.0 if camera_inside else 35.0), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=max_bounces, rr_depth=max_bounces + 2),
                 materials=[surface], meshes=[Mesh("furnace", v, i, [surface.name], medium=medium.name)],
                 media=[medium], environment=Environment((1.0, 1.0, 1.0)))


def infinite_medium(medium: Medium, size: int = 8, spp: int = 4, max_bounces: int = 8) -> Scene:
    """Nothing but `medium` everywhere (the world medium): no surfaces, no lights.

    With emission E (per unit length), extinction sigma_t and albedo a per channel, a path
    gains E / sigma_t on each free flight, and Cycles' max_bounces = N lets it fly N + 2
    times (emission on the flight after the last allowed scattering is still direct light),
    so L = E / sigma_t * sum_{k=0}^{N+1} a^k, for any phase function. Russian roulette is off.
    """
    return Scene(camera=camera_at((0.0, 0.0, 0.0), 60.0), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=max_bounces, rr_depth=max_bounces + 2),
                 media=[medium], medium=medium.name)


BUILDERS: dict[str, Callable[[int, int], Scene]] = {
    "fog_isotropic": fog_isotropic,
    "fog_backward": fog_backward,
    "fog_forward": fog_forward,
    "smoke_ball": smoke_ball,
    "yellow_smoke": yellow_smoke,
    "fire_ball": fire_ball,
    "underwater": underwater,
}

# Sigmas per gallery entry, for the gallery's captions.
SIGMAS: dict[str, str] = {
    "fog_isotropic": f"sigma_a {FIG1_SIGMA_A}, sigma_s {FIG1_SIGMA_S}, g 0",
    "fog_backward": f"sigma_a {FIG1_SIGMA_A}, sigma_s {FIG1_SIGMA_S}, g -0.9",
    "fog_forward": f"sigma_a {FIG1_SIGMA_A}, sigma_s {FIG1_SIGMA_S}, g 0.9",
    "smoke_ball": f"sigma_a {FIG5_SIGMA_A}, sigma_s {FIG5_SIGMA_S}, g 0 (x Fig. 3 density)",
    "yellow_smoke": f"sigma_a {FIG6_SIGMA_A}, sigma_s {FIG6_SIGMA_S}, g {FIG6_G} (x gaussian density, peak "
                    f"{YELLOW_SMOKE_PEAK})",
    "fire_ball": "sigma_a 0.3, sigma_s 0.6, g 0.3 (x smoke density); blackbody emission, peak 3400 K",
    "underwater": f"sigma_a {FIG8_SIGMA_A}, sigma_s {FIG8_SIGMA_S}, g {FIG8_G}, scale 4; ior {WATER_IOR}",
}
