"""Scene builders for the examples, tests and benchmarks (plain renderer Scenes, no bpy).

The Cornell box spans [-1, 1]^3 with its open side toward +z; the camera looks down -z.
Figure references are to the paper in shared/seed/volumetric-path-tracing.txt.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import (
    Camera,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Medium,
    Mesh,
    PointLight,
    Scene,
)

FIG1_SIGMA_A = (0.001764, 0.0032095, 0.0019617)
FIG1_SIGMA_S = (0.31845, 0.31324, 0.30147)
CORNELL_LIGHT = (17.0, 12.0, 4.0)


def quad(center, u, v) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles spanning center +- u +- v, front face along cross(u, v)."""
    c, u, v = (np.asarray(a, np.float64) for a in (center, u, v))
    verts = np.array([c - u - v, c + u - v, c + u + v, c - u + v], np.float32)
    return verts, np.array([[0, 1, 2], [0, 2, 3]], np.int32)


def box(center, half, rot_y_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed box with outward normals, rotated about +y."""
    a = math.radians(rot_y_deg)
    r = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    hx, hy, hz = half
    ex, ey, ez = r @ [hx, 0, 0], r @ [0, hy, 0], r @ [0, 0, hz]
    c = np.asarray(center, np.float64)
    faces = [(c + ex, ey, ez), (c - ex, ez, ey), (c + ey, ez, ex), (c - ey, ex, ez), (c + ez, ex, ey),
             (c - ez, ey, ex)]
    return merge([quad(*f) for f in faces])


def merge(parts) -> tuple[np.ndarray, np.ndarray]:
    verts, idx, off = [], [], 0
    for v, i in parts:
        verts.append(v)
        idx.append(i + off)
        off += v.shape[0]
    return np.concatenate(verts).astype(np.float32), np.concatenate(idx).astype(np.int32)


def diffuse(name: str, color) -> Material:
    return Material(name, [Lobe("diffuse", color=tuple(color))])


def cornell_box(size: int = 128, spp: int = 64, max_bounces: int = 3, medium: Medium | None = None,
                boxes: bool = True, light_radiance=CORNELL_LIGHT) -> Scene:
    """The Cornell box; with `medium`, the medium fills the scene (camera included)."""
    walls = [
        ("floor", quad((0, -1, 0), (0, 0, 1), (1, 0, 0)), "white"),
        ("ceiling", quad((0, 1, 0), (1, 0, 0), (0, 0, 1)), "white"),
        ("back", quad((0, 0, -1), (1, 0, 0), (0, 1, 0)), "white"),
        ("left", quad((-1, 0, 0), (0, 1, 0), (0, 0, 1)), "red"),
        ("right", quad((1, 0, 0), (0, 0, 1), (0, 1, 0)), "green"),
    ]
    meshes = [Mesh(n, v, i, [m]) for n, (v, i), m in walls]
    lv, li = quad((0, 0.999, 0), (0.25, 0, 0), (0, 0, 0.25))  # faces down
    meshes.append(Mesh("light", lv, li, ["light"]))
    if boxes:
        meshes.append(Mesh("short_box", *box((0.35, -0.7, 0.35), (0.3, 0.3, 0.3), -17), ["white"]))
        meshes.append(Mesh("tall_box", *box((-0.35, -0.4, -0.3), (0.3, 0.6, 0.3), 17), ["white"]))
    materials = [
        diffuse("white", (0.73, 0.73, 0.73)),
        diffuse("red", (0.65, 0.05, 0.05)),
        diffuse("green", (0.12, 0.45, 0.15)),
        Material("light", [Lobe("diffuse", color=(0.78, 0.78, 0.78))], emission=tuple(light_radiance)),
    ]
    cam = np.eye(4)
    cam[:3, 3] = (0.0, 0.0, 3.9)
    scene = Scene(
        camera=Camera(to_world=cam, fov=37.0),
        film=Film(size, size),
        integrator=IntegratorSettings(spp=spp, max_bounces=max_bounces),
        materials=materials,
        meshes=meshes,
    )
    if medium is not None:
        scene.media = [medium]
        scene.medium = medium.name
    return scene


def fog(g: float = 0.0) -> Medium:
    """The paper's Fig. 1 fog."""
    return Medium("fog", "homogeneous", sigma_a=FIG1_SIGMA_A, sigma_s=FIG1_SIGMA_S, g=g)


def cornell_fog(size: int = 128, spp: int = 64, g: float = 0.0, max_bounces: int = 3) -> Scene:
    return cornell_box(size, spp, max_bounces, medium=fog(g))


def furnace_sphere(albedo: float = 1.0, size: int = 32, spp: int = 64, max_bounces: int = 64,
                   subdiv: int = 3) -> Scene:
    """A closed diffuse sphere under a uniform environment of radiance 1."""
    v, i = icosphere(subdiv)
    cam = np.eye(4)
    cam[:3, 3] = (0, 0, 4)
    return Scene(camera=Camera(cam, fov=30.0), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=max_bounces, rr_depth=1000),
                 materials=[diffuse("white", (albedo, albedo, albedo))],
                 meshes=[Mesh("sphere", v, i, ["white"])], environment=Environment((1.0, 1.0, 1.0)))


def icosphere(subdiv: int = 3, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    t = (1 + 5**0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, np.float64) / np.linalg.norm(p) for p in v]
    for _ in range(subdiv):
        midpoints: dict = {}
        nf = []
        for a, b, c in f:
            ab, bc, ca = (_midpoint(verts, midpoints, x, y) for x, y in ((a, b), (b, c), (c, a)))
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return (np.array(verts) * radius).astype(np.float32), np.array(f, np.int32)


def _midpoint(verts: list, midpoints: dict, a: int, b: int) -> int:
    """Index of the unit-sphere midpoint of edge (a, b), created once per edge."""
    k = (min(a, b), max(a, b))
    if k not in midpoints:
        m = verts[a] + verts[b]
        verts.append(m / np.linalg.norm(m))
        midpoints[k] = len(verts) - 1
    return midpoints[k]


def point_light_plane(size: int = 64, spp: int = 16, height: float = 1.0, intensity: float = 10.0,
                      albedo: float = 0.5) -> Scene:
    """A diffuse plane z = 0 under a point light at (0, 0, height); camera above looking down."""
    v, i = quad((0, 0, 0), (2, 0, 0), (0, 2, 0))
    cam = np.eye(4)
    cam[:3, 3] = (0, 0, 3)
    return Scene(camera=Camera(cam, fov=60.0), film=Film(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=0),
                 materials=[diffuse("plane", (albedo,) * 3)], meshes=[Mesh("plane", v, i, ["plane"])],
                 lights=[PointLight((0.0, 0.0, height), (intensity,) * 3)])
