"""The scene description: plain dataclasses, saved as `scene.json` plus `.npy` arrays.

Units: world units are metres (Blender's); radiance in W/(m^2 sr) per linear RGB channel;
medium coefficients per world unit. Arrays are structure-of-arrays with the shapes given
on each field. Objects refer to one another by name (a mesh names its materials, a mesh
or the scene names its medium), so a scene file reads like the scene.

The scene's vocabulary (the words a string field may hold and, for the kernels, their
integer codes) and its limits are defined here once; `renderer.validate` checks a Scene
against them, `renderer.scenefile` reads and writes the folder format, `renderer.compile`
flattens a Scene into the kernels' arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .shading.program import ImageTexture, ShaderProgram

# 2: shader programs' opcodes were renumbered (the old Noise opcode removed): a folder written
# as version 1 would have its programs misread, so it is refused with the version named.
# 3: array files are named by their field's place (mesh1.attribute0.values.npy); version 2
# named corner attributes' files after the attribute only, so meshes sharing a UV map name
# overwrote each other's (renderer.scenefile reads version 2 folders that lost nothing).
SCENE_FORMAT_VERSION = 3

RGB = tuple[float, float, float]

# Luminance of a linear Rec.709 RGB colour (what "brightness" means for light selection,
# lobe selection and normalised blackbody colours).
LUMINANCE: RGB = (0.2126, 0.7152, 0.0722)

# ---------------------------------------------------------------------------- vocabulary
# A dict maps the words of a field to the integer codes the kernels dispatch on; a tuple
# lists the words of a field only Python reads.

LOBE_KINDS: dict[str, int] = {
    "diffuse": 0,
    "dielectric": 1,  # smooth glass
    "conductor": 2,  # smooth mirror tinted by color
    "rough_conductor": 3,  # GGX reflection, Cycles' Glossy BSDF
    "plastic": 4,  # GGX dielectric coat over a Lambertian base
    "transparent": 5,  # straight pass-through tinted by color
}
CONDUCTOR_KINDS = ("conductor", "rough_conductor")  # the kinds that take a `fresnel` mode
FRESNEL_MODES: dict[str, int] = {"constant": 0, "f82": 1}
# Faces a lobe or an emission exists on, as a bitmask: 1 front, 2 back.
SIDES: dict[str, int] = {"front": 1, "back": 2, "both": 3}
MEDIUM_TYPES: dict[str, int] = {"homogeneous": 0, "grid": 1}
FOV_AXES = ("x", "y")
# Camera projections (Cycles' camera types, the panoramic ones by their panorama type) and
# the codes the camera kernel dispatches on.
PROJECTIONS: dict[str, int] = {
    "perspective": 0,
    "orthographic": 1,
    "equirectangular": 2,
    "fisheye_equidistant": 3,
    "fisheye_equisolid": 4,
    "mirrorball": 5,
}
# How an environment map is read between pixel centres (Cycles' image interpolations).
ENV_INTERPOLATIONS: dict[str, int] = {"linear": 0, "closest": 1}
# How an environment map's image covers the sphere (Cycles' Environment Texture projections).
ENV_PROJECTIONS: dict[str, int] = {"equirectangular": 0, "mirror_ball": 1}
SAMPLING_MODES = ("mis", "nee", "bsdf")
TRANSMITTANCE_MODES = ("ratio", "delta")
DISTANCE_SAMPLING_MODES = ("spectral_mis", "uniform")
# Media overlapping at one point: a path's medium stack holds at most this many (a further
# overlapping medium is ignored rather than crashing a render).
MAX_STACK = 4


@dataclass
class Camera:
    """A camera with Cycles' projections. Looks down its local -Z axis with +Y up (Blender's).

    projection:
      "perspective"          pinhole (or thin lens with an aperture): `fov` along `fov_axis`.
      "orthographic"         parallel rays; the `fov_axis` side of the image spans
                             `ortho_scale` world units.
      "equirectangular"      longitude [longitude_min, longitude_max] across the image
                             (left to right), latitude [latitude_min, latitude_max] bottom
                             to top; longitude 0 looks down -Z.
      "fisheye_equidistant"  angle from the axis proportional to the distance from the image
                             centre; `fisheye_fov` across the image's width and height.
      "fisheye_equisolid"    Cycles' equisolid fisheye: a `fisheye_lens` mm lens on a
                             `sensor` mm sensor (fitted along `fov_axis`), cut at `fisheye_fov`.
      "mirrorball"           the view of a mirror ball filling the image.
    Depth of field (aperture_radius > 0): a thin lens of that radius (world units) focused
    at `focus_distance` along the view axis (along the ray for panoramic cameras), with a
    polygonal aperture of `aperture_blades` corners (< 3 = a disk) turned by
    `aperture_rotation` radians, its x extent divided by `aperture_ratio` (anamorphic).
    """

    to_world: np.ndarray = field(default_factory=lambda: np.eye(4))  # (4, 4) float64, camera-to-world
    fov: float = 40.0  # degrees, full angle along `fov_axis`, in (0, 180)
    fov_axis: str = "x"  # "x" (image width) or "y" (image height)
    shift: tuple[float, float] = (0.0, 0.0)  # Blender lens shift, in units of the larger image side
    clip_start: float = 1e-4  # world units; nothing nearer is seen
    clip_end: float = 1e30  # world units; nothing farther is seen
    projection: str = "perspective"  # a PROJECTIONS word
    ortho_scale: float = 6.0  # orthographic: world units across the `fov_axis` side
    aperture_radius: float = 0.0  # world units; 0 = pinhole
    focus_distance: float = 10.0  # world units from the lens, > 0
    aperture_blades: int = 0  # polygon corners; 0 (or < 3) = round aperture
    aperture_rotation: float = 0.0  # radians
    aperture_ratio: float = 1.0  # > 0; anamorphic bokeh: x extent / ratio
    longitude_min: float = -3.141592653589793  # equirectangular, radians
    longitude_max: float = 3.141592653589793
    latitude_min: float = -1.5707963267948966
    latitude_max: float = 1.5707963267948966
    fisheye_fov: float = 3.141592653589793  # fisheyes: radians
    fisheye_lens: float = 10.5  # fisheye_equisolid: mm
    sensor: float = 36.0  # fisheye_equisolid: mm along `fov_axis`


@dataclass
class Film:
    """The frame (width x height pixels) and what of it is rendered.

    region: (x, y, width, height) in pixels, row 0 at the top: only that window of the
    frame is rendered, and the image is the window (Blender's Render Region). None = all.
    transparent: the world seen directly (through pass-through surfaces and media, not
    through scattering or refraction) is left out of the image and gives alpha 0, as with
    Cycles' Film > Transparent; otherwise alpha is 1 everywhere.
    aovs: the film also sums the passes of renderer.passes (Depth, Position, Normal,
    Denoising Albedo and Normal); a render-time request, not part of the scene file.
    """

    width: int = 128
    height: int = 128
    region: tuple[int, int, int, int] | None = None
    transparent: bool = False
    aovs: bool = False  # also sum the data and denoising passes (renderer.passes); off = no cost
    light_aovs: bool = False  # also sum the light passes (Emission, Colors, Volume); off = no cost
    # The Mist pass (Blender's World > Mist Pass): 0 at mist_start from the camera, 1 at
    # mist_start + mist_depth, shaped by mist_falloff (exponent: 2 quadratic, 1 linear,
    # 0.5 inverse quadratic).
    mist_start: float = 5.0
    mist_depth: float = 25.0
    mist_falloff: float = 2.0

    def window(self) -> tuple[int, int, int, int]:
        """(x, y, width, height) of the rendered pixels."""
        if self.region is None:
            return (0, 0, self.width, self.height)
        x, y, w, h = self.region  # a scene file's numbers may arrive as floats
        return (int(x), int(y), int(w), int(h))


@dataclass
class Lobe:
    """One BSDF lobe of a material; a material's BSDF is the sum of its weighted lobes.

    kind:
      "diffuse"        Lambertian reflection, albedo `color`.
      "dielectric"     smooth glass: Fresnel reflection + refraction, `ior` = inside / outside.
      "conductor"      smooth mirror, reflectance per `fresnel` (Cycles' Glossy/Metallic at
                        roughness 0).
      "rough_conductor" GGX microfacet reflection, alpha = roughness^2, reflectance per
                        `fresnel`, visible-normal sampling.
      "plastic"        Cycles' Principled dielectric: a GGX specular layer (ior, roughness,
                        specular tint `tint`) over a diffuse base of albedo `color` weighted
                        by 1 - E(wo).
      "dielectric" reflection is tinted by `tint`, refraction by `color`.

    fresnel (conductors only):
      "constant"       reflectance = `color` at every angle (Cycles' Glossy BSDF).
      "f82"            Cycles' F82-tint Schlick curve: F0 = `color`, and near 82 degrees
                        Schlick's value times `tint` (Principled metallic, Metallic BSDF).
      "transparent"    straight pass-through tinted by `color` (Cycles' Transparent BSDF).
    """

    kind: str
    weight: RGB = (1.0, 1.0, 1.0)  # multiplies the lobe (Mix/Add shader weights)
    color: RGB = (0.8, 0.8, 0.8)
    roughness: float = 0.0  # Blender roughness in [0, 1]; alpha = roughness^2
    ior: float = 1.5  # > 0; the medium behind the front face over the one in front
    sides: str = "both"  # "front", "back" or "both": faces on which the lobe exists
    fresnel: str = "constant"  # conductors: "constant" or "f82"
    # conductors with fresnel "f82": edge tint; plastic: specular tint (F0 x tint); dielectric:
    # reflection tint (`color` tints the refraction). In [0, 1].
    tint: RGB = (1.0, 1.0, 1.0)
    multiscatter: bool = False  # rough_conductor, plastic: Cycles' Multiscatter GGX compensation


@dataclass
class Material:
    """Surface appearance. No lobes and no emission = an invisible interface (a medium boundary)."""

    name: str
    lobes: list[Lobe] = field(default_factory=list)
    emission: RGB = (0.0, 0.0, 0.0)  # radiance leaving the surface, W/(m^2 sr)
    emission_sides: str = "front"  # "front", "back" or "both"
    # The varying part of the node tree (textures...), run per shading point; None = constant.
    program: ShaderProgram | None = None


@dataclass
class CornerAttribute:
    """Values at each triangle corner, interpolated at a hit with its barycentrics."""

    name: str  # as ShaderProgram.attributes names it, e.g. "uv:UVMap", "generated"
    values: np.ndarray  # (T, 3, k) float32, k <= 3


@dataclass
class Mesh:
    """A triangle mesh in world space.

    A mesh with a `medium` encloses it: a ray entering through a front face (against the
    geometric normal, counter-clockwise winding) adds the medium to its stack, leaving
    removes it. Meshes that carry a medium must be closed.
    """

    name: str
    vertices: np.ndarray  # (V, 3) float32, world space
    indices: np.ndarray  # (T, 3) int32, counter-clockwise seen from the front
    materials: list[str]  # names of materials; material_ids index this list
    material_ids: np.ndarray | None = None  # (T,) int32; None = all zero
    normals: np.ndarray | None = None  # (V, 3) float32 shading normals, or None for flat
    medium: str | None = None  # name of the medium inside, or None
    # Per-corner data shader programs read (UV maps, generated and object coordinates...).
    attributes: list[CornerAttribute] = field(default_factory=list)


@dataclass
class PointLight:
    position: RGB
    intensity: RGB  # radiant intensity, W/sr per channel
    type: str = "point"


@dataclass
class SpotLight:
    """A point light restricted to a cone (Blender spot: smoothstep blend at the edge)."""

    position: RGB
    direction: RGB  # cone axis, need not be unit
    intensity: RGB  # W/sr on the axis
    spot_size: float = 45.0  # degrees, full cone angle
    blend: float = 0.15  # [0, 1], share of the cone faded by smoothstep
    type: str = "spot"


@dataclass
class SunLight:
    """Distant light from `direction` (pointing from the scene toward the sun)."""

    direction: RGB
    irradiance: RGB  # W/m^2 on a surface facing the sun
    angle: float = 0.0  # degrees, angular diameter; 0 = delta light
    type: str = "sun"


Light = PointLight | SpotLight | SunLight
# The one registry of light kinds: the `type` tag of each light class.
LIGHT_TYPES: dict[str, type] = {"point": PointLight, "spot": SpotLight, "sun": SunLight}


@dataclass
class Environment:
    """Radiance arriving from infinity: `radiance` from every direction, or, with a
    `radiance_map`, the map's radiance times `radiance` (Background strength x colour).

    radiance_map (H, W, 3) float32 >= 0: an image in `projection`: equirectangular with
    Cycles' mapping (u = 1/2 looks down the map's +X, row 0 is the bottom, the top row the
    zenith) or Cycles' mirror ball (the ball seen from -Y), read with `interpolation`;
    `to_world` (4, 4) turns the map's frame into the world (a rotation or reflection only;
    the last column is ignored). See renderer.lights.environment.
    """

    radiance: RGB = (0.0, 0.0, 0.0)  # W/(m^2 sr); with a map, its tint
    radiance_map: np.ndarray | None = None  # (H, W, 3) float32 radiance, W/(m^2 sr)
    interpolation: str = "linear"  # an ENV_INTERPOLATIONS word
    projection: str = "equirectangular"  # an ENV_PROJECTIONS word
    to_world: np.ndarray = field(default_factory=lambda: np.eye(4))  # (4, 4) float64, map -> world


@dataclass
class Medium:
    """A participating medium.

    Homogeneous: coefficients sigma_a, sigma_s times `scale` everywhere inside.
    Grid: those coefficients are further multiplied by `density`, trilinearly interpolated
    between voxel centres. The grid box spans local corners p0..p1; `to_world` places it:
    world-to-grid-unit-cube is (to_world * T(p0) * S(p1 - p0))^-1. Outside the box the
    density is 0.

    Emission is a source per unit length (Cycles' convention): along a ray a path gains
    the integral of T(t) * emission(t) dt. With `flame`, emission is multiplied by it;
    with `temperature` (kelvin) blackbody radiance times `blackbody_intensity` is added.

    Procedural (a grid medium with `program` instead of `density`): the density at a world
    point is register `program_density` of `program` run there, clamped at 0, inside the
    box p0..p1 (0 outside); renderer.media.procedural bounds it per majorant cell.
    """

    name: str
    type: str = "homogeneous"  # "homogeneous" or "grid"
    sigma_a: RGB = (0.0, 0.0, 0.0)  # absorption, per world unit, >= 0
    sigma_s: RGB = (0.0, 0.0, 0.0)  # scattering, per world unit, >= 0
    scale: float = 1.0  # multiplies sigma_a and sigma_s, >= 0
    g: float = 0.0  # Henyey-Greenstein asymmetry, |g| < 1
    emission: RGB = (0.0, 0.0, 0.0)  # W/(m^3 sr) per unit density/flame
    # grid media only
    # (nz, ny, nx) float32, x fastest, >= 0; density, flame and temperature may also be
    # SparseGrids (renderer/media/bricks.py), stored as bricks of occupied voxels
    density: np.ndarray | None = None
    p0: RGB = (0.0, 0.0, 0.0)
    p1: RGB = (1.0, 1.0, 1.0)
    to_world: np.ndarray = field(default_factory=lambda: np.eye(4))  # (4, 4) float64
    flame: np.ndarray | None = None  # (nz', ny', nx') float32 >= 0, scales `emission`
    temperature: np.ndarray | None = None  # (nz'', ny'', nx'') float32 kelvin >= 0
    blackbody_intensity: float = 0.0
    program: ShaderProgram | None = None  # procedural density (grid media without `density`)
    program_density: int = 0  # the program's register holding the density


@dataclass
class IntegratorSettings:
    """How to render. `max_bounces` means exactly what Cycles' max_bounces means: the number
    of scattering events (surface or medium) a path may have; 0 = direct light only."""

    spp: int = 64
    max_bounces: int = 8
    seed: int = 0
    rr_depth: int = 3  # Russian roulette from this bounce on
    sampling: str = "mis"  # "mis", "nee" (light sampling only) or "bsdf" (BSDF/phase only)
    transmittance: str = "ratio"  # shadow rays in grids: "ratio" or "delta" tracking
    distance_sampling: str = "spectral_mis"  # chromatic media: "spectral_mis" or "uniform"
    equiangular: bool = True  # MIS equiangular + free-flight in homogeneous media
    majorant_grid: bool = True  # coarse majorant grid walked by DDA (else one global bound)
    batch_size: int = 65536  # paths traced together
    time_limit: float = 0.0  # seconds; 0 = none


@dataclass
class Scene:
    camera: Camera = field(default_factory=Camera)
    film: Film = field(default_factory=Film)
    integrator: IntegratorSettings = field(default_factory=IntegratorSettings)
    materials: list[Material] = field(default_factory=list)
    meshes: list[Mesh] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)
    media: list[Medium] = field(default_factory=list)
    environment: Environment = field(default_factory=Environment)
    medium: str | None = None  # scene-wide medium the camera and every path start in
    images: list[ImageTexture] = field(default_factory=list)  # read by shader programs
