"""The stability catalogue: adversarial scenes and cameras, defined in one place.

Each :class:`Case` builds a :class:`~renderer.geometry.scene.Scene` and says what it
attacks. ``test_catalogue.py`` runs every case through the GPU tracer with every
method of ``renderer.config.methods.METHODS`` and through the float64 reference, and
``docs/STABILITY.md`` is written from the results.

Images are small (49 × 81 by default) so the whole catalogue runs in well under
two minutes on two CPU cores. Both sides are **odd**: the centre column and the
centre row of an image go exactly through ``u = 0`` / ``v = 0``, so with an
axis-aligned camera those primary rays have direction components that are
exactly ±0 — rays parallel to split planes, where ``(clip − o) / d`` would be
±inf or NaN.

Thresholds (primid agreement ≥ 99.9 %, depth 1e-4 relative where
the ids agree, colour PSNR ≥ 35 dB). They apply twice: against the reference of the
scene as given (float64) and against the reference of the scene *as float32 stores
it* (:func:`float32_inputs`), which separates input quantization from the tracer's
own arithmetic. A case that cannot reach one pins the measured figure and says why
in ``why`` / ``depth_why`` / ``psnr_why`` / ``f32_why``; a lower threshold without a
reason is refused by ``Case.__post_init__``.

``max_prims`` defaults to 1 (the deepest trees, the most traversal steps); the
thesis-like scenes use its 8.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from renderer.accel import bih_layout as L
from renderer.accel.bih import build_for_spheres
from renderer.geometry.scene import Camera, Light, Material, Mesh, Plane, Scene
from renderer.geometry.shapes import Shapes
from renderer.scenes.scenarios import RED, TRANSPARENT, scenario

PRIMID_AGREEMENT = 0.999
DEPTH_REL = 1e-4
PSNR_MIN = 35.0
W, H = 49, 81


@dataclass(frozen=True)
class Case:
    name: str
    what_can_go_wrong: str
    build: Callable[[], Scene]
    width: int = W
    height: int = H
    max_prims: int = 1  # deepest trees, most traversal steps; thesis-like scenes use 8
    max_tree_depth: int = 64
    max_recursion_depth: int = 5
    min_primid_agreement: float = PRIMID_AGREEMENT
    why: str = ""
    max_depth_rel: float = DEPTH_REL
    depth_why: str = ""
    color_psnr_min: float | None = PSNR_MIN
    psnr_why: str = ""
    # The same three figures against the reference of ``float32_inputs(scene)`` (the
    # scene as the GPU stores it): strict unless pinned here, with ``f32_why``.
    f32_min_primid_agreement: float = PRIMID_AGREEMENT
    f32_max_depth_rel: float = DEPTH_REL
    f32_color_psnr_min: float | None = PSNR_MIN
    f32_why: str = ""
    # BIH only: the built tree must reach at least this depth (stats depth_max).
    min_tree_depth: int | None = None
    # Extra checks: f(scene, reference_result, gpu_result, method) -> list of failure messages.
    checks: tuple[Callable, ...] = field(default_factory=tuple)
    # Facts about the case for the report (e.g. how many rays have ±0 components).
    facts: Callable[[Scene], str] | None = None
    # What the figures mean, for the report.
    note: str = ""
    # The methods the case runs with (None: every method of METHODS). Mesh cases name the
    # methods that trace triangles (the ray engines draw spheres and planes only).
    methods: tuple[str, ...] | None = None
    # The methods must return identical ids (the default); a case where two triangles meet a
    # ray at the same t (a shared edge) may let them differ on ties only, with this reason.
    method_ties_why: str = ""
    # (method, reason): the case is known to fail with that method (the test expects the
    # failure, strictly: a fix shows up as an unexpected pass).
    known_failures: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if self.min_primid_agreement < PRIMID_AGREEMENT and not self.why:
            raise ValueError(f"{self.name}: a primid threshold below {PRIMID_AGREEMENT} needs a reason")
        if self.max_depth_rel > DEPTH_REL and not self.depth_why:
            raise ValueError(f"{self.name}: a depth tolerance above {DEPTH_REL} needs a reason")
        if self.color_psnr_min is not None and self.color_psnr_min < PSNR_MIN and not self.psnr_why:
            raise ValueError(f"{self.name}: a PSNR threshold below {PSNR_MIN} dB needs a reason")
        relaxed = (
            self.f32_min_primid_agreement < PRIMID_AGREEMENT
            or self.f32_max_depth_rel > DEPTH_REL
            or (self.f32_color_psnr_min is not None and self.f32_color_psnr_min < PSNR_MIN)
        )
        if relaxed and not self.f32_why:
            raise ValueError(f"{self.name}: a relaxed float32-input threshold needs a reason")


# --------------------------------------------------------------------------- materials

MIRROR = Material(
    color=(0.8, 0.8, 0.8),
    ambient=0.05,
    diffuse=0.1,
    specular=0.2,
    shininess=60.0,
    reflective=0.9,
    transmissive=0.0,
    ior=1.0,
)
WALL_MIRROR = Material(
    color=(0.5, 0.7, 0.9),
    ambient=0.05,
    diffuse=0.2,
    specular=0.1,
    shininess=20.0,
    reflective=1.0,
    transmissive=0.0,
    ior=1.0,
)
MATTE = Material(
    color=(0.3, 0.8, 0.4),
    ambient=0.2,
    diffuse=0.7,
    specular=0.3,
    shininess=30.0,
    reflective=0.0,
    transmissive=0.0,
    ior=1.0,
)
HALF_GLASS = Material(
    color=(1.0, 1.0, 1.0),
    ambient=0.02,
    diffuse=0.05,
    specular=0.2,
    shininess=80.0,
    reflective=0.5,
    transmissive=0.5,
    ior=1.5,
)


def glass(ior: float, kt: float = 0.8, kr: float = 0.1) -> Material:
    return Material(
        color=(1.0, 1.0, 1.0),
        ambient=0.05,
        diffuse=0.05,
        specular=0.2,
        shininess=60.0,
        reflective=kr,
        transmissive=kt,
        ior=ior,
    )


FLOOR = Plane(point=(0.0, -20.0, 0.0), normal=(0.0, 1.0, 0.0), material=0)
LIGHT = Light(position=(0.0, 40.0, 0.0), color=(1.0, 1.0, 1.0))


def make_scene(
    camera: Camera, centers, radii, mats, materials=(RED, TRANSPARENT, MATTE), planes=(FLOOR,), lights=(LIGHT,)
) -> Scene:
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    radii = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(centers),))
    mats = np.broadcast_to(np.asarray(mats, dtype=np.int32), (len(centers),))
    return Scene(camera, tuple(lights), tuple(materials), centers, radii, mats, tuple(planes))


def transformed(scene: Scene, scale: float = 1.0, offset=(0.0, 0.0, 0.0)) -> Scene:
    """Every position scaled by ``scale`` then shifted by ``offset``; radii scaled."""
    off = np.asarray(offset, dtype=np.float64)
    f = lambda p: tuple((np.asarray(p, dtype=np.float64) * scale + off).tolist())
    cam = scene.camera
    camera = Camera(f(cam.position), f(cam.target), cam.up, cam.fov_y)
    lights = tuple(Light(f(light.position), light.color) for light in scene.lights)
    planes = tuple(Plane(f(p.point), p.normal, p.material) for p in scene.planes)
    return Scene(
        camera,
        lights,
        scene.materials,
        scene.sphere_centers * scale + off,
        scene.sphere_radii * scale,
        scene.sphere_materials,
        planes,
    )


def float32_inputs(scene: Scene) -> Scene:
    """The scene as the GPU receives it: every coordinate, radius and material value
    rounded to float32. The camera *position* is rounded and the target moved with it,
    so the viewing basis stays the float64 one the renderer computes on the host."""
    f32 = lambda v: tuple(np.asarray(v, dtype=np.float32).astype(np.float64).tolist())
    cam = scene.camera
    pos = np.asarray(f32(cam.position))
    tgt = np.asarray(cam.target) + (pos - np.asarray(cam.position))
    camera = Camera(tuple(pos.tolist()), tuple(tgt.tolist()), cam.up, cam.fov_y)
    mats = tuple(
        Material(
            f32(m.color),
            *(
                float(np.float32(getattr(m, k)))
                for k in ("ambient", "diffuse", "specular", "shininess", "reflective", "transmissive", "ior")
            ),
        )
        for m in scene.materials
    )
    return Scene(
        camera,
        tuple(Light(f32(light.position), f32(light.color)) for light in scene.lights),
        mats,
        scene.sphere_centers.astype(np.float32).astype(np.float64),
        scene.sphere_radii.astype(np.float32).astype(np.float64),
        scene.sphere_materials,
        tuple(Plane(f32(p.point), f32(p.normal), p.material) for p in scene.planes),
        tuple(
            Mesh(
                m.vertices.astype(np.float32).astype(np.float64),
                m.triangles,
                m.material,
                None if m.normals is None else m.normals.astype(np.float32).astype(np.float64),
            )
            for m in scene.meshes
        ),
        shapes=Shapes(
            scene.shapes.kind, scene.shapes.params.astype(np.float32).astype(np.float64), scene.shapes.material
        ),
    )


def same_scene(a: Scene, b: Scene) -> bool:
    return a.to_json() == b.to_json()


# ------------------------------------------------------------------------------ scenes


def axis_grid_spheres() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """5 × 5 × 5 grid at −16, −8, 0, 8, 16 (centres on every axis through 0), radius 1.5."""
    ax = np.array([-16.0, -8.0, 0.0, 8.0, 16.0])
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    c = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    mats = np.arange(len(c)) % 3  # red, glass (ior 0.95), matte
    return c, np.full(len(c), 1.5), mats


def axis_scene(camera: Camera) -> Scene:
    c, r, m = axis_grid_spheres()
    return make_scene(camera, c, r, m)


AXIS_CAMERAS = {
    "-z": Camera((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
    "+z": Camera((0.0, 0.0, -100.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
    "-x": Camera((100.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
    "+x": Camera((-100.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
    "-y": Camera((0.0, 100.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, -1.0), 40.0),
    # from between the floor (y = −20) and the grid (y ≥ −17.5), looking up
    "+y": Camera((0.0, -19.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 100.0),
}


def zero_components(scene: Scene, width: int = W, height: int = H) -> str:
    """How many of the reference's primary rays have direction components exactly +0 / −0."""
    from renderer.oracle.reference import primary_rays

    _, d = primary_rays(scene.camera, width, height)
    parts = []
    for a, name in enumerate("xyz"):
        z = d[:, a] == 0.0
        neg = int((z & np.signbit(d[:, a])).sum())
        if z.any():
            parts.append(f"d.{name}: {int(z.sum()) - neg} × +0, {neg} × −0")
    return "zero direction components in the reference's primary rays: " + ("; ".join(parts) if parts else "none")


def root_clip(scene_spheres, max_prims: int, which: str, depth: int = 1) -> tuple[int, float]:
    """(axis, clip value) of the first inner node at ``depth`` (root = 1) of the BIH the
    case will build: a camera placed exactly on it starts its rays on a clip plane."""
    c, r = scene_spheres
    bih = build_for_spheres(c, r, max_prims=max_prims)
    w0 = bih.nodes[:, 0]
    inner = np.flatnonzero(~L.is_leaf(w0) & (bih.node_depths == depth))
    k = int(inner[0])
    cl, cr = L.clips(bih.nodes)
    value = cl[k] if which == "left" else cr[k]
    return int(L.axis_of(w0[k : k + 1])[0]), float(value)


def clip_plane_scene(which: str, depth: int, inside: bool) -> Scene:
    """The axis grid, camera position exactly on a clip plane of the BIH (max_prims 1),
    looking along another axis so the centre row/column is parallel to that plane."""
    c, r, m = axis_grid_spheres()
    axis, value = root_clip((c, r), 1, which, depth)
    view = (axis + 2) % 3  # look along another axis
    pos = np.zeros(3)
    pos[axis] = value
    pos[view] = 3.5 if inside else 100.0  # inside the global box: between grid layers
    tgt = pos.copy()
    tgt[view] = -100.0  # exactly along −view: d[axis] = 0 on the centre line
    up = np.zeros(3)
    up[(view + 1) % 3] = 1.0
    cam = Camera(tuple(pos.tolist()), tuple(tgt.tolist()), tuple(up.tolist()), 100.0 if inside else 40.0)
    return make_scene(cam, c, r, m)


def geometric_series(n: int = 80) -> Scene:
    """Centres 20·2^−i·(1, 0.5, 0.25), radii 0.2·20·2^−i: every split peels off one
    sphere, the maximally unbalanced BIH; 80 spheres reach the 64-level limit."""
    i = np.arange(n)
    s = 20.0 * 0.5**i
    c = np.stack([s, 0.5 * s, 0.25 * s], axis=1)
    r = 0.2 * s
    # looking from the far side of the accumulation point (the origin): the centre
    # ray passes right by the tiny spheres and traverses the whole depth
    cam = Camera((-40.0, -12.0, -25.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0)
    return make_scene(cam, c, r, i % 3)


def room_planes(half: float, material: int) -> tuple[Plane, ...]:
    """Six planes bounding the cube [−half, half]³, normals pointing inwards."""
    out = []
    for a in range(3):
        for s in (-1.0, 1.0):
            p = [0.0, 0.0, 0.0]
            n = [0.0, 0.0, 0.0]
            p[a] = s * half
            n[a] = -s
            out.append(Plane(tuple(p), tuple(n), material))
    return tuple(out)


def mirror_room(glass_spheres: bool, seams: bool = False) -> Scene:
    planes = room_planes(30.0, 0)
    c = np.array(
        [
            [-10.0, -10.0, -10.0],
            [10.0, -12.0, 0.0],
            [0.0, 8.0, -15.0],
            [-12.0, 10.0, 12.0],
            [14.0, 14.0, -14.0],
            [0.0, -25.0, 5.0],
        ]
    )
    r = np.array([6.0, 5.0, 7.0, 4.0, 3.0, 5.0])
    m = np.full(len(c), 2 if glass_spheres else 1)
    if seams:  # 33 × 33, fov 90°: columns 7 and 25 have u = ∓30/55 exactly
        cam = Camera((0.0, 0.0, 25.0), (0.0, 0.0, -30.0), (0.0, 1.0, 0.0), 90.0)
    else:
        cam = Camera((0.37, 0.21, 24.3), (-3.1, -1.7, -30.0), (0.0, 1.0, 0.0), 90.0)
    return make_scene(
        cam,
        c,
        r,
        m,
        materials=(WALL_MIRROR, MIRROR, HALF_GLASS),
        planes=planes,
        lights=(Light((5.0, 25.0, 10.0), (1.0, 1.0, 1.0)),),
    )


def refraction_scene(ior: float) -> Scene:
    """A big glass sphere before a wall of coloured spheres and the floor."""
    ax = np.array([-18.0, -9.0, 0.0, 9.0, 18.0])
    y, x = np.meshgrid(ax, ax, indexing="ij")
    back = np.stack([x.ravel(), y.ravel(), np.full(x.size, -25.0)], axis=1)
    c = np.concatenate([[[0.0, 0.0, 0.0]], back, [[0.0, -16.0, 8.0]]])
    r = np.concatenate([[9.0], np.full(len(back), 3.5), [4.0]])
    m = np.concatenate([[3], np.arange(len(back)) % 2 * 2, [0]])
    cam = Camera((3.0, 6.0, 55.0), (0.0, -2.0, 0.0), (0.0, 1.0, 0.0), 45.0)
    return make_scene(cam, c, r, m, materials=(RED, TRANSPARENT, MATTE, glass(ior)))


def nested_scene() -> Scene:
    """Concentric glass shells (ior 1.5, 0.95, 2.4), an off-centre inner sphere and a red core."""
    c = np.array(
        [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [2.5, 1.0, 1.0],
            [0.0, 0.0, 0.0],
            [-15.0, -10.0, -30.0],
            [15.0, 5.0, -30.0],
        ]
    )
    r = np.array([12.0, 8.0, 5.0, 1.5, 1.0, 8.0, 8.0])
    m = np.array([3, 4, 5, 3, 0, 2, 0])
    cam = Camera((0.0, 4.0, 45.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 45.0)
    return make_scene(cam, c, r, m, materials=(RED, TRANSPARENT, MATTE, glass(1.5), glass(0.95), glass(2.4)))


def inside_glass() -> Scene:
    """Camera inside a glass sphere (ior 1.5) off its centre: most rays leave at
    oblique angles, beyond the critical angle 41.8° many are totally reflected."""
    ring = np.array(
        [
            [25.0 * np.cos(a), 6.0 * np.sin(3 * a), 25.0 * np.sin(a)]
            for a in np.linspace(0, 2 * np.pi, 12, endpoint=False)
        ]
    )
    c = np.concatenate([[[0.0, 0.0, 0.0]], ring])
    r = np.concatenate([[12.0], np.full(len(ring), 4.0)])
    m = np.concatenate([[3], np.arange(len(ring)) % 2 * 2])
    cam = Camera((5.0, 2.0, 4.0), (-20.0, -6.0, -10.0), (0.0, 1.0, 0.0), 90.0)
    return make_scene(cam, c, r, m, materials=(RED, TRANSPARENT, MATTE, glass(1.5, kt=0.85, kr=0.1)))


def light_leak_room() -> Scene:
    """A closed room of six planes with the light outside it (above the ceiling):
    nothing inside may receive direct light. A sphere rests exactly on the floor
    (tangent) and two spheres touch each other; the camera is inside."""
    planes = room_planes(20.0, 2)
    c = np.array([[0.0, -15.0, 0.0], [-8.0, -12.0, -6.0], [-2.0, -12.0, -6.0], [8.0, 5.0, -10.0]])
    r = np.array([5.0, 3.0, 3.0, 4.0])  # 0 touches the floor, 1 and 2 touch each other
    m = np.array([0, 2, 0, 1])
    cam = Camera((3.0, 2.0, 18.0), (-1.0, -8.0, -10.0), (0.0, 1.0, 0.0), 80.0)
    return make_scene(
        cam,
        c,
        r,
        m,
        materials=(RED, TRANSPARENT, MATTE),
        planes=planes,
        lights=(Light((5.0, 35.0, 3.0), (1.0, 1.0, 1.0)),),
    )


def no_direct_light(scene, ref, gpu, method) -> list[str]:
    """With the light outside the closed room no point inside may be lit: the GPU frame
    must equal the reference of the same room with no light at all (ambient and its
    reflections only), and nowhere be brighter than the reference."""
    from renderer.config.settings import RenderSettings
    from renderer.oracle.reference import render_reference

    h, w = gpu.primid.shape
    dark = render_reference(
        Scene(
            scene.camera,
            (),
            scene.materials,
            scene.sphere_centers,
            scene.sphere_radii,
            scene.sphere_materials,
            scene.planes,
        ),
        RenderSettings(width=w, height=h, max_recursion_depth=5, max_prims=1),
    )
    out = []
    if not np.array_equal(ref.image_u8(), dark.image_u8()):
        out.append("the reference itself lets light into the closed room")
    img = gpu.image.astype(np.float64)
    leak = img.sum(axis=2) > dark.image.sum(axis=2) + 2.0 / 255.0
    if leak.any():
        out.append(f"{int(leak.sum())} pixels brighter than the unlit room (light leaking)")
    return out


def _tiny_at(offset: float) -> Scene:
    """27 spheres of radius 1e-3 on a 3×3×3 grid of spacing 4e-3, seen from 0.03 away.

    The camera position and target are float32-representable at any offset (multiples
    of 0.0625), so the GPU's camera is exact; the sphere centres, the light and the
    plane are not (fractional offsets), so at 1e6 float32 moves them by up to 0.031.
    """
    p = np.array([offset + 0.25, offset + 0.5, offset + 0.75])
    look = np.array([-0.125, -0.1875, -1.0])
    mid = p + 0.03 * look / np.linalg.norm(look)
    ax = np.array([-4e-3, 0.0, 4e-3])
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    c = mid + np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    cam = Camera(tuple(p.tolist()), tuple((p + look).tolist()), (0.0, 1.0, 0.0), 40.0)
    plane = Plane(tuple((mid + [0.0, -0.008, 0.0]).tolist()), (0.0, 1.0, 0.0), 0)
    light = Light(tuple((mid + [0.01, 0.05, 0.02]).tolist()), (1.0, 1.0, 1.0))
    return make_scene(cam, c, 1e-3, np.arange(27) % 3, planes=(plane,), lights=(light,))


def _camera_on_plane() -> Scene:
    """Camera exactly on the floor plane looking along it: t = 0 / dot(d, n) = ±0 for
    every ray (never > 0), and the centre row has dot(d, n) = 0 exactly."""
    c, r, m = axis_grid_spheres()
    cam = Camera((0.0, -20.0, 60.0), (0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    return make_scene(cam, c, r, m)


def _light_on_surface() -> Scene:
    """Lights exactly on the floor and exactly on a sphere's surface, each straight below
    a camera ray: the hit point is the light (dist = 0, l = 0/0), or the light lies in the
    surface's tangent plane (cos = 0)."""
    c = np.array([[10.0, -12.0, 0.0], [-10.0, -10.0, -5.0]])
    r = np.array([4.0, 6.0])
    cam = Camera((0.0, 60.0, 0.0), (0.0, -20.0, 0.0), (0.0, 0.0, -1.0), 60.0)
    lights = (
        Light((0.0, -20.0, 0.0), (1.0, 1.0, 1.0)),  # on the floor, under the centre pixel
        Light((10.0, -8.0, 0.0), (0.6, 0.6, 0.6)),  # the top of sphere 0
        Light((0.0, 40.0, 0.0), (0.5, 0.5, 0.5)),
    )
    return make_scene(cam, c, r, [0, 2], lights=lights)


def _fov(fov: float) -> Scene:
    """An oblique camera with an extreme field of view on the axis grid, aimed at a point
    of the silhouette of the sphere at the origin (radius 1.5)."""
    cam = np.array([37.0, 23.0, 81.0])
    w = -cam / np.linalg.norm(cam)
    side = np.cross(w, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    dist = np.linalg.norm(cam)
    # the tangent point: at angle asin(r / dist) off the axis to the centre
    a = np.arcsin(1.5 / dist)
    target = cam + (np.cos(a) * w + np.sin(a) * side) * np.sqrt(dist**2 - 1.5**2)
    return axis_scene(Camera(tuple(cam.tolist()), tuple(target.tolist()), (0.0, 1.0, 0.0), fov))


def float32_centre_ray(scene: Scene) -> str:
    """Which spheres the centre pixel's ray hits when its float64 direction is moved by up
    to ±3 float32 ulps per component (the GPU computes it in float32)."""
    from renderer.oracle.reference import trace_rays

    _, _, fwd = scene.camera.basis()
    base = fwd.astype(np.float32)
    dirs = []
    for steps in np.ndindex(7, 7, 7):
        v = base.copy()
        for a, n in enumerate(np.array(steps) - 3):
            for _ in range(abs(int(n))):
                v[a] = np.nextafter(v[a], np.float32(np.inf if n > 0 else -np.inf))
        dirs.append(v.astype(np.float64))
    d = np.array(dirs)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(scene.camera.position, dtype=np.float64), d.shape)
    _, ids = trace_rays(scene, o, d)
    _, id64 = trace_rays(scene, o[:1], fwd[None, :])
    hit = ids[ids >= 0]
    return (
        f"centre ray (it passes ~1e-6 from the accumulation point): the float64 direction hits "
        f"{int(id64[0])}; of the {len(d)} float32 directions within ±3 ulps per component, {len(hit)} hit "
        f"one of spheres {int(hit.min())}…{int(hit.max())} (radii ~1e-6): which one the GPU sees is "
        "float32 rounding of the direction"
        if len(hit)
        else "centre ray: no float32 neighbour hits"
    )


def _grid_shifted(offset: float) -> Scene:
    return transformed(scenario(2, 64, seed=3), offset=(offset, -offset, offset))


def _scaled(k: float) -> Scene:
    return transformed(scenario(1, 64), scale=k)


def _one_centre() -> Scene:
    n = 256
    cam = Camera((3.0, 4.0, 30.0), (1.25, -0.5, 2.0), (0.0, 1.0, 0.0), 40.0)
    return make_scene(cam, np.broadcast_to([1.25, -0.5, 2.0], (n, 3)), 4.0, np.arange(n) % 3)


def _concentric() -> Scene:
    n = 64
    cam = Camera((3.0, 4.0, 50.0), (1.25, -0.5, 2.0), (0.0, 1.0, 0.0), 40.0)
    return make_scene(
        cam,
        np.broadcast_to([1.25, -0.5, 2.0], (n, 3)),
        np.linspace(12.0, 0.25, n),
        np.where(np.arange(n) < n - 1, 3, 0),
        materials=(RED, TRANSPARENT, MATTE, glass(1.2, 0.9, 0.0)),
    )


def _duplicates() -> Scene:
    s = scenario(1, 64)
    c = np.concatenate([s.sphere_centers, s.sphere_centers])
    r = np.concatenate([s.sphere_radii, s.sphere_radii])
    m = np.concatenate([np.zeros(64, np.int32), np.full(64, 1, np.int32)])  # copies differ in material
    return Scene(s.camera, s.lights, s.materials, c, r, m, s.planes)


def _overlapping() -> Scene:
    rng = np.random.default_rng(7)
    c = rng.normal(0.0, 3.0, (300, 3))
    r = rng.uniform(1.0, 4.0, 300)
    cam = Camera((0.0, 10.0, 60.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    return make_scene(cam, c, r, rng.integers(0, 3, 300))


def _spanning() -> Scene:
    s = scenario(2, 64, seed=1, radius=1.5)
    c = np.concatenate([[[0.0, 0.0, 0.0]], s.sphere_centers])
    r = np.concatenate([[20.0], s.sphere_radii])
    m = np.concatenate([[1], s.sphere_materials])
    cam = Camera((30.0, 25.0, 70.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0)
    return Scene(cam, s.lights, s.materials, c, r, m, s.planes)


def _one_sphere() -> Scene:
    cam = Camera((0.0, 0.0, 30.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    return make_scene(cam, [[0.0, 0.0, 0.0]], 8.0, 0)


def _no_spheres(with_plane: bool) -> Scene:
    cam = Camera((0.0, 5.0, 50.0), (0.0, -10.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    return make_scene(cam, np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), planes=(FLOOR,) if with_plane else ())


def _inside_box() -> Scene:
    cam = Camera((0.3, 0.2, 4.0), (3.0, 2.0, -20.0), (0.0, 1.0, 0.0), 90.0)
    return axis_scene(cam)


def _inside_opaque_sphere() -> Scene:
    c, r, m = axis_grid_spheres()
    r = r.copy()
    centre = int(np.flatnonzero((c == 0.0).all(axis=1))[0])
    r[centre] = 5.0  # the camera sits inside this one (red)
    m = m.copy()
    m[centre] = 0
    cam = Camera((1.0, 0.5, 0.25), (0.0, 0.0, -20.0), (0.0, 1.0, 0.0), 100.0)
    return make_scene(cam, c, r, m)


def _huge_among_unit() -> Scene:
    s = scenario(1, 64)
    c = np.concatenate([s.sphere_centers, [[0.0, -1015.0, 0.0]]])
    r = np.concatenate([s.sphere_radii, [1000.0]])
    m = np.concatenate([s.sphere_materials, [0]])
    cam = Camera((0.0, 30.0, 90.0), (0.0, -10.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    return Scene(cam, s.lights, s.materials, c, r, m, s.planes)


def _near_axis(tiny: float) -> Scene:
    """Camera looking down −z with the target off-axis by ``tiny``: components of ~1e-20
    (crossings at t ~ 1e21) or float32 denormals (~1e-38), which a GPU may flush to 0.
    With ``tiny`` < 0 the centre row points down by |tiny| and meets the floor at
    t = 20 / |tiny|."""
    return axis_scene(Camera((0.0, 0.0, 100.0), (tiny * 100.0, tiny * 100.0, 0.0), (0.0, 1.0, 0.0), 40.0))


# ----------------------------------------------------------------- pins and their checks

_BEYOND_FLOAT32 = (
    "measured 99.647 % (14 px): the pixels of the centre row that see the floor at t ≈ 2e39 > 3.4e38, the "
    "largest float32; the GPU cannot represent that distance (and llvmpipe flushes the 1e-38 denormal "
    "direction component to 0, so its ray is parallel to the floor) and reports a miss, the float64 reference "
    "a hit. The same camera at 1e-37 (t ≈ 2e38, near_axis_1e-37_down) agrees on every pixel."
)
_TINY_AT_1E6 = (
    "measured 0.93 % agreement, depth error 0.97, 16.2 dB: float32's spacing at 1e6 is 0.0625, 62 times the "
    "radius; the GPU's sphere centres move by up to 0.031 (31 radii), so it renders another scene (one "
    "sphere lands on the camera). Against the float32-input scene every strict threshold holds."
)
_SEAMS = (
    "measured 97.888 % (23 px, every one a tie) and 20.0 dB: pixel columns 7, 25 and rows 7, 25 hit an edge "
    "of the room exactly, where two walls are at the same t in exact arithmetic; float32 and float64 "
    "rounding break the tie differently (the lower-id rule needs exactly equal t), and with kr = 1 walls "
    "the whole ray tree of such a pixel differs. The same room from a generic camera (mirror_room_depth8) "
    "meets every strict threshold."
)


_ZOOM = (
    "measured 99.597 % (16 px, all on the silhouette): the pixel pitch is 2.2e-7 rad, 2e-5 world units at "
    "t ≈ 92; float32 resolves the direction to ~6e-8 rad and the sphere test's offset f = oc − b·d to "
    "~93·6e-8 ≈ 5.6e-6, together ~0.5 px, so the GPU's silhouette is jagged by one pixel where the "
    "reference's is straight. Not a traversal error: bih and bruteforce give the same ids."
)
_COINCIDENT = (
    "why the colour is not exact although every id agrees: a secondary ray leaving sphere i starts exactly "
    "on the coincident spheres j ≠ i, whose near root is 0 in exact arithmetic; SHADING.md's exclusion rule "
    "only covers the source primitive, so the rounded sign of that root decides whether j is hit at t ≈ 0 — "
    "independently in float32 and float64. The reference is as far from itself under a one-ulp camera move "
    "(≈ 36 dB, measured while writing this case); a convention for coincident primitives would be needed to "
    "do better."
)


def only_centre_row_misses(scene, ref, gpu, method) -> list[str]:
    bad = np.argwhere(gpu.primid != ref.primid)
    rows = set(bad[:, 0].tolist())
    if rows - {scene_height_centre(gpu)}:
        return [f"ids differ outside the centre row (rows {sorted(rows)})"]
    if (gpu.primid[tuple(bad.T)] != -1).any() or (ref.primid[tuple(bad.T)] != scene.n_spheres).any():
        return ["a centre-row disagreement is not 'GPU miss, reference floor'"]
    return []


def scene_height_centre(result) -> int:
    return result.primid.shape[0] // 2


def only_ties(scene, ref, gpu, method) -> list[str]:
    """Every pixel whose id differs has the same depth on both sides (two surfaces at one t)."""
    diff = gpu.primid != ref.primid
    both = diff & (gpu.primid >= 0) & (ref.primid >= 0)
    rel = np.abs(gpu.depth.astype(np.float64)[diff] - ref.depth[diff]) / ref.depth[diff]
    if not (both == diff).all() or not (rel <= 1e-5).all():
        return [f"{int(diff.sum())} px differ in id and not all of them are ties"]
    return []


# -------------------------------------------------------------------------------- cases

CASES: list[Case] = []


def _add(*cases: Case) -> None:
    CASES.extend(cases)


for _dir, _cam in AXIS_CAMERAS.items():
    _add(
        Case(
            f"axis_down_{_dir}",
            f"camera exactly down {_dir[0]}{_dir[1]}; the centre column/row has d components exactly 0, "
            "parallel to split planes: (clip − o)/d = ±inf or NaN",
            (lambda cam=_cam: axis_scene(cam)),
            facts=zero_components,
        )
    )

_add(
    Case(
        "signed_zero_+z",
        "target (−0, −0, 0): forward = (−0, −0, 1), so the centre column mixes d.x = +0 and "
        "d.x = −0; a sign test instead of a zero test would pick the wrong near child",
        lambda: axis_scene(Camera((0.0, 0.0, -100.0), (-0.0, -0.0, 0.0), (0.0, 1.0, 0.0), 40.0)),
        facts=zero_components,
    ),
    Case(
        "near_axis_1e-20",
        "direction components ~1e-20: plane crossings at t ~ 1e21, intervals of huge magnitude",
        lambda: _near_axis(1e-20),
        facts=zero_components,
    ),
    Case(
        "near_axis_denormal",
        "direction components ~1e-38, float32 denormals the GPU may flush to 0 "
        "(the zero test and the division must then agree)",
        lambda: _near_axis(1e-38),
        facts=zero_components,
    ),
    Case(
        "near_axis_1e-37_down",
        "the centre row points down by ~1e-37: the floor is met at t ≈ 2e38, "
        "just inside float32's range (and below the shader's 3e38 'no hit' sentinel)",
        lambda: _near_axis(-1e-37),
        facts=zero_components,
    ),
    Case(
        "near_axis_denormal_down",
        "the centre row points down by ~1e-38: the floor is met at t ≈ 2e39, beyond float32's range",
        lambda: _near_axis(-1e-38),
        facts=zero_components,
        min_primid_agreement=0.996,
        f32_min_primid_agreement=0.996,
        why=_BEYOND_FLOAT32,
        f32_why=_BEYOND_FLOAT32,
        checks=(only_centre_row_misses,),
    ),
    Case(
        "camera_on_plane",
        "camera exactly on the floor plane, looking along it: t = 0/dot(d, n) is ±0 "
        "(never a hit), the centre row has dot(d, n) = 0",
        _camera_on_plane,
        facts=zero_components,
    ),
    Case(
        "origin_on_clip_left",
        "camera origin exactly on the root's clip_left, rays parallel to it on the "
        "centre line: tL = 0/d = ±0, and o == clip in the parallel test",
        lambda: clip_plane_scene("left", 1, False),
        facts=zero_components,
    ),
    Case(
        "origin_on_clip_right",
        "as above on clip_right",
        lambda: clip_plane_scene("right", 1, False),
        facts=zero_components,
    ),
    Case(
        "origin_on_inner_clip_inside_box",
        "camera inside the global box, exactly on a depth-3 node's clip plane",
        lambda: clip_plane_scene("left", 3, True),
        facts=zero_components,
    ),
    Case(
        "camera_inside_box",
        "camera inside the global AABB: t0 = 0, the root interval starts at the origin",
        _inside_box,
    ),
    Case(
        "camera_inside_sphere",
        "camera inside an opaque sphere: every primary ray must take the far root; shadow rays start inside",
        _inside_opaque_sphere,
    ),
    # degenerate distributions
    Case(
        "all_one_centre",
        "256 identical spheres at one centre: the build never separates them "
        "(listing 3.4 loops forever); ties must go to the lowest id",
        _one_centre,
        note=_COINCIDENT,
    ),
    Case(
        "concentric_64", "64 spheres at one centre, radii 0.25 … 12, glass: a forced leaf of nested shells", _concentric
    ),
    Case(
        "duplicate_pairs",
        "every sphere twice (same centre and radius, other material): bitwise equal t, ties to the lower id",
        _duplicates,
        note=_COINCIDENT,
    ),
    Case(
        "many_overlapping",
        "300 heavily overlapping spheres: AABBs straddle every split, empty gaps are rare",
        _overlapping,
        max_prims=8,
    ),
    Case(
        "sphere_spans_box",
        "one sphere as large as the global box among small ones: a primitive that straddles every split plane",
        _spanning,
    ),
    Case("one_sphere", "a single sphere: the root is a leaf", _one_sphere),
    Case(
        "root_leaf_max_prims",
        "125 spheres, max_prims ≥ n: the whole scene in the root leaf",
        lambda: axis_scene(AXIS_CAMERAS["-z"]),
        max_prims=1 << 24,
    ),
    Case(
        "max_tree_depth_1",
        "max_tree_depth = 1: the root is a leaf however many primitives",
        lambda: axis_scene(AXIS_CAMERAS["-x"]),
        max_tree_depth=1,
    ),
    Case("no_spheres", "empty scene: global box (+inf, −inf), no nodes to fetch", lambda: _no_spheres(False)),
    Case(
        "only_plane",
        "no spheres, only the plane: BIH empty, planes still shaded and shadowed",
        lambda: _no_spheres(True),
    ),
    # scales
    Case("offset_1e4", "all coordinates offset by 1e4 (float32 spacing 1e-3)", lambda: _grid_shifted(1e4), max_prims=8),
    Case(
        "offset_1e6",
        "all coordinates offset by 1e6 (float32 spacing 0.0625 at 1e6: centres and hit points "
        "are rounded by up to 3 % of a unit radius)",
        lambda: _grid_shifted(1e6),
        max_prims=8,
        max_depth_rel=2e-3,
        depth_why="measured 1.4e-3: float32 moves the random sphere centres by up to "
        "0.031 (half the spacing 0.0625 at 1e6), which shifts t by up to ~0.1 near a silhouette (t ≈ 80); "
        "against the float32-input scene the depth error is below 1e-6 and every strict threshold holds.",
    ),
    Case(
        "radius_1e-3_at_1e6",
        "radius 1e-3 at coordinates 1e6: float32 spacing there is 0.0625, 62 radii; "
        "hit points and normals from them are meaningless",
        lambda: _tiny_at(1e6),
        min_primid_agreement=0.009,
        max_depth_rel=1.0,
        color_psnr_min=15.0,
        why=_TINY_AT_1E6,
        depth_why=_TINY_AT_1E6,
        psnr_why=_TINY_AT_1E6,
    ),
    Case("radius_1e-3_near_origin", "the same 1e-3 spheres near the origin, seen from 0.03", lambda: _tiny_at(0.0)),
    Case(
        "radius_1e-3_thesis",
        "the thesis's memory test (Fig. 4.5): 1024 spheres of radius 1e-3, far below a pixel",
        lambda: scenario(2, 1024, radius=1e-3),
    ),
    Case(
        "scale_1e-3",
        "the whole scene scaled by 1e-3 (radius 1e-3, camera at 0.1): secondary rays at tiny scale",
        lambda: _scaled(1e-3),
        max_prims=8,
    ),
    Case("scale_1e3", "the whole scene scaled by 1e3 (radius 1e3, camera at 1e5)", lambda: _scaled(1e3), max_prims=8),
    Case(
        "radius_1e3_among_unit",
        "a radius-1e3 sphere cutting the floor under unit spheres: mixed scales, one AABB 1000× the others",
        _huge_among_unit,
        max_prims=8,
    ),
    Case(
        "geometric_series_depth64",
        "positions in a geometric series: a maximally unbalanced tree at the "
        "shader's 64-entry stack limit; the centre ray traverses every level",
        geometric_series,
        max_tree_depth=64,
        min_tree_depth=40,
        facts=float32_centre_ray,
    ),
    Case("fov_179", "field of view 179°: tan(89.5°) = 115, rays up to 89.5° off the axis", lambda: _fov(179.0)),
    Case(
        "fov_1e-3",
        "field of view 0.001° on a sphere's silhouette: neighbouring pixel rays differ by 2e-7 "
        "rad, a few float32 ulps of the direction",
        lambda: _fov(1e-3),
        min_primid_agreement=0.995,
        f32_min_primid_agreement=0.995,
        why=_ZOOM,
        f32_why=_ZOOM,
    ),
    # secondary rays
    Case(
        "light_on_surface",
        "lights exactly on the floor and on a sphere, under camera rays: dist = 0 (l = 0/0) and cos = 0 at the light",
        _light_on_surface,
    ),
    Case(
        "light_leak_room",
        "a closed room, light outside: a shadow ray must never escape through the walls, "
        "the seams, or a sphere resting exactly on the floor",
        light_leak_room,
        checks=(no_direct_light,),
    ),
    # refraction
    *[
        Case(
            f"refraction_ior_{ior:g}",
            f"glass sphere with ior {ior:g}"
            + {
                0.95: " (the thesis's): η > 1 on entry, total internal reflection from outside",
                1.0: ": the transmitted ray continues straight through both surfaces",
                1.5: ": ordinary glass",
                2.4: ": diamond, critical angle 24.6°, much TIR inside",
            }[ior],
            (lambda ior=ior: refraction_scene(ior)),
            max_recursion_depth=6,
        )
        for ior in (0.95, 1.0, 1.5, 2.4)
    ],
    Case(
        "tir_inside_glass",
        "camera inside a glass sphere: rays leave it (η = ior), beyond 41.8° they are "
        "totally reflected and must take the far root again",
        inside_glass,
        max_recursion_depth=6,
    ),
    Case(
        "nested_spheres",
        "concentric glass shells of different ior with an off-centre inner sphere",
        nested_scene,
        max_recursion_depth=8,
    ),
    # bounded work
    Case(
        "mirror_room_exact_seams_depth8",
        "the mirror room seen so that whole pixel columns and rows hit the "
        "room's edges exactly (u = ±30/55): two walls at the same t",
        lambda: mirror_room(False, seams=True),
        width=33,
        height=33,
        max_recursion_depth=8,
        min_primid_agreement=0.975,
        color_psnr_min=19.0,
        f32_min_primid_agreement=0.975,
        f32_color_psnr_min=19.0,
        why=_SEAMS,
        psnr_why=_SEAMS,
        f32_why=_SEAMS,
        checks=(only_ties,),
    ),
    Case(
        "mirror_room_depth8",
        "six perfect-mirror walls and mirror spheres, recursion depth 8: bounded work, no hang",
        lambda: mirror_room(False),
        width=33,
        height=33,
        max_recursion_depth=8,
    ),
    Case(
        "glass_mirror_room_depth8",
        "mirror walls with half-mirror half-glass spheres: a full binary ray tree (255 rays per pixel) at depth 8",
        lambda: mirror_room(True),
        width=33,
        height=33,
        max_recursion_depth=8,
    ),
)


# ------------------------------------------------------------------------- triangle meshes


def _mesh_methods() -> tuple[str, ...]:
    from renderer.config.methods import METHODS

    return tuple(m for m, x in METHODS.items() if "triangles" in x.capabilities.primitives)


MESH_METHODS = _mesh_methods()
MESH_LIGHT = Light((40.0, 60.0, 80.0), (1.0, 1.0, 1.0))


def _mesh_scene(camera: Camera, *meshes: Mesh, planes=(FLOOR,), materials=(RED, TRANSPARENT, MATTE)) -> Scene:
    return Scene(
        camera,
        (MESH_LIGHT,),
        tuple(materials),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        tuple(planes),
        tuple(meshes),
    )


def _inside_silhouette(ref_ids: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """Pixels whose reference hit and all 8 neighbours' hits are triangles with ids in [lo, hi)."""
    on = (ref_ids >= lo) & (ref_ids < hi)
    p = np.pad(on, 1, constant_values=False)
    h, w = on.shape
    out = on.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out &= p[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
    return out


def no_leak(scene, ref, gpu, method) -> list[str]:
    """Watertightness: no pixel strictly inside a mesh's reference silhouette (it and its 8
    neighbours hit that mesh) may miss the mesh on the GPU — every mesh, separately."""
    out, base = [], scene.triangle_id_base
    for k, m in enumerate(scene.meshes):
        lo, hi = base, base + m.n_triangles
        base = hi
        inside = _inside_silhouette(ref.primid, lo, hi)
        leak = inside & ~((gpu.primid >= lo) & (gpu.primid < hi))
        if leak.any():
            ys, xs = np.nonzero(leak)
            out.append(
                f"mesh {k}: {int(leak.sum())} of {int(inside.sum())} px inside its silhouette leak "
                f"through it (first at x {xs[0]}, y {ys[0]}: GPU id {int(gpu.primid[ys[0], xs[0]])})"
            )
    return out


def centre_pixel_hits_mesh(scene, ref, gpu, method) -> list[str]:
    """The centre pixel's ray goes exactly through a vertex shared by several triangles: it
    must hit one of them (the reference does)."""
    h, w = gpu.primid.shape
    i, base = int(gpu.primid[h // 2, w // 2]), scene.triangle_id_base
    if not base <= i < base + scene.n_triangles:
        return [f"the centre ray through the shared vertex hits id {i}, not a triangle"]
    if not base <= int(ref.primid[h // 2, w // 2]) < base + scene.n_triangles:
        return ["the reference's centre ray misses the shared vertex's triangles"]
    return []


def never_degenerate(scene, ref, gpu, method) -> list[str]:
    """No pixel may show a zero-area triangle (the reference never hits one)."""
    deg = np.flatnonzero(np.concatenate([m.degenerate for m in scene.meshes])) + scene.triangle_id_base
    out = []
    for name, r in (("GPU", gpu), ("reference", ref)):
        n = int(np.isin(r.primid, deg).sum())
        if n:
            out.append(f"{name}: {n} px hit a degenerate triangle")
    return out


def on_box_seams(scene, ref, gpu, method) -> list[str]:
    """mesh_box_seams: every pixel whose id differs from the reference's is a seam pixel
    (the front face's diagonal, its rims in columns/rows 7 and 25) and a tie."""
    h, w = gpu.primid.shape
    y, x = np.mgrid[0:h, 0:w]
    seam = (x + y == w - 1) | (x == y) | np.isin(x, (7, 25)) | np.isin(y, (7, 25))
    off = (gpu.primid != ref.primid) & ~seam
    if off.any():
        ys, xs = np.nonzero(off)
        return [f"{int(off.sum())} px off the seams differ in id from the reference (first x {xs[0]}, y {ys[0]})"]
    return only_ties(scene, ref, gpu, method)


def _mesh_facts(scene: Scene) -> str:
    return (
        f"{scene.n_triangles:,} triangles in {len(scene.meshes)} mesh(es), {scene.n_degenerate_triangles} of zero area"
    )


def mesh_box_seams() -> Scene:
    """The closed box [−30, 30]² × [−60, 0] seen from (0, 0, 55), fov 90°, 33 × 33: columns 7
    and 25 (rows too) have u = ∓30/55, so their rays meet the front face exactly on its edges
    x = ±30 (shared with the side faces, seen edge-on), the pixels (7, 7) … exactly on its
    corners (three faces' shared vertex), and the diagonal pixels (u = v) exactly on the
    front face's diagonal, the edge its two triangles share."""
    from renderer.geometry.meshes import box

    cam = Camera((0.0, 0.0, 55.0), (0.0, 0.0, -30.0), (0.0, 1.0, 0.0), 90.0)
    return _mesh_scene(
        cam,
        box((-30.0, -30.0, -60.0), (30.0, 30.0, 0.0), material=2),
        planes=(Plane((0.0, 0.0, -200.0), (0.0, 0.0, 1.0), 0),),
    )


def mesh_box_corner() -> Scene:
    """The box [−10, 10]³ seen along its diagonal: the centre ray goes exactly through the
    corner (10, 10, 10) shared by three faces (and their diagonals: up to six triangles)."""
    from renderer.geometry.meshes import box

    cam = Camera((50.0, 50.0, 50.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    return _mesh_scene(cam, box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0), material=0))


def mesh_icosphere_edges() -> Scene:
    """Icosphere (3 subdivisions, 1280 triangles, radius 10) from (0, 0, 60) down −z: its
    vertices (0, ±1, g) and their edge's midpoints all lie in the plane x = 0, so the centre
    column's rays (d.x = +0/−0, o.x = 0) run exactly along a chain of shared edges, and the
    centre ray through the shared vertex (0, 0, 10) (six triangles)."""
    from renderer.geometry.meshes import icosphere

    cam = Camera((0.0, 0.0, 60.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    return _mesh_scene(cam, icosphere(3, radius=10.0, material=2, smooth=False))


def _grid(n: int, half: float, y: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    ax = np.linspace(-half, half, n + 1)
    z, x = np.meshgrid(ax, ax, indexing="ij")
    v = np.stack([x.ravel(), np.full(x.size, y), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = i * (n + 1) + j
    t = np.concatenate(
        [np.stack([a, a + n + 1, a + 1], -1).reshape(-1, 3), np.stack([a + 1, a + n + 1, a + n + 2], -1).reshape(-1, 3)]
    )
    return v, t


def mesh_grazing() -> Scene:
    """A 16 × 16-quad grid of 512 triangles in the plane y = 0 (normal +y), the camera exactly
    in that plane: the centre row's rays lie in the triangles' plane (det = 0: never a hit,
    they must reach the icosphere behind), the rows below meet the grid at grazing angles
    down to 1/40 of a pixel's angle from the plane, across its shared edges."""
    from renderer.geometry.meshes import icosphere

    v, t = _grid(16, 80.0)
    cam = Camera((0.0, 0.0, 100.0), (0.0, 0.0, -100.0), (0.0, 1.0, 0.0), 30.0)
    return _mesh_scene(cam, Mesh(v, t, 2), icosphere(2, radius=8.0, center=(0.0, 4.0, -40.0), material=0), planes=())


def mesh_needles() -> Scene:
    """Needles and degenerate triangles in front of a backdrop triangle: a fan of 40 needles
    10 long and 1e-4 … 1e-9 wide (far thinner than a pixel), triangles of zero area (a
    repeated index; three collinear points with exactly representable coordinates) and, for
    scale, ordinary triangles."""
    rng = np.random.default_rng(3)
    verts, tris = [], []

    def tri(a, b, c):
        k = len(verts)
        verts.extend([a, b, c])
        tris.append((k, k + 1, k + 2))

    for i, w in enumerate(np.geomspace(1e-4, 1e-9, 40)):
        ang = 2 * np.pi * i / 40
        d = np.array([np.cos(ang), np.sin(ang), 0.0])
        n = np.array([-d[1], d[0], 0.0])
        tri((0.0, 0.0, 1.0), tuple(10 * d + w * n + (0, 0, 1)), tuple(10 * d - w * n + (0, 0, 1)))
    for _ in range(20):  # zero area: a repeated corner
        p = rng.uniform(-12, 12, 3) * (1, 1, 0.1)
        q = rng.uniform(-12, 12, 3) * (1, 1, 0.1)
        tri(tuple(p), tuple(q), tuple(p))
    for _ in range(20):  # zero area: collinear, dyadic coordinates
        p = np.round(rng.uniform(-12, 12, 3) * 8) / 8
        e = np.round(rng.uniform(-4, 4, 3) * 8) / 8
        tri(tuple(p), tuple(p + e), tuple(p + 2 * e))
    for _ in range(12):  # ordinary triangles among them
        p = rng.uniform(-12, 12, 3) * (1, 1, 0.1)
        tri(tuple(p), tuple(p + rng.uniform(-3, 3, 3)), tuple(p + rng.uniform(-3, 3, 3)))
    front = Mesh(np.array(verts), np.array(tris), 0)
    back = Mesh(np.array([[-40.0, -40.0, -5.0], [40.0, -40.0, -5.0], [0.0, 60.0, -5.0]]), np.array([[0, 1, 2]]), 2)
    cam = Camera((0.3, -0.2, 40.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    return _mesh_scene(cam, front, back, planes=())


def mesh_huge(subdivisions: int = 5, k: int = 4) -> Scene:
    """``k`` icospheres of ``subdivisions`` levels (4 × 20,480 = 81,920 triangles), packed
    in view and overlapping: far more triangles than pixels."""
    from renderer.geometry.meshes import icosphere

    rng = np.random.default_rng(11)
    c = rng.uniform([-14, -10, -6], [14, 10, 6], (k, 3))
    meshes = [
        icosphere(subdivisions, radius=6.0, center=tuple(p), material=i % 3, smooth=False) for i, p in enumerate(c)
    ]
    return _mesh_scene(Camera((0.0, 0.0, 70.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0), *meshes)


def mesh_offset_1e4() -> Scene:
    """An icosphere (radius 1, 2 subdivisions) and a box 1e4 units from the origin along every
    axis, the camera 6 units from them: float32 spacing there is 1e-3 (0.1 % of the radius)."""
    from renderer.geometry.meshes import box, icosphere

    o = np.array([1e4, 1e4, 1e4])
    cam = Camera(tuple(o + (0.5, 0.8, 6.0)), tuple(o), (0.0, 1.0, 0.0), 40.0)
    return _mesh_scene(
        cam,
        icosphere(2, radius=1.0, center=tuple(o), material=0, smooth=False),
        box(tuple(o + (1.5, -1.5, -2.0)), tuple(o + (2.5, 1.0, -1.0)), material=2),
        planes=(Plane(tuple(o + (0.0, -1.0, 0.0)), (0.0, 1.0, 0.0), 2),),
    )


_EDGE_TIES = (
    "a ray exactly through an edge two triangles share meets both at the same t up to float32 "
    "rounding, so which one wins is a tie that float32 and float64, and traversals that test "
    "the two in different orders, may decide differently; every differing pixel must be such a "
    "tie (only_ties) and none a leak (no_leak)"
)
_BOX_SEAMS = (
    "measured: 16 of the 1089 px differ, every one on a seam (13 on the front face's diagonal, "
    "3 on its rims and corners) and a tie; on the rims the other triangle is a side face seen "
    "edge-on, whose other normal gives another colour (hence the PSNR). " + _EDGE_TIES
)
_OFFSET_MESH = (
    "float32 moves the vertices by up to 4.9e-4 (half the spacing 9.8e-4 at 1e4), which shifts "
    "t by up to ~1.6e-3 relative near the silhouettes and moves a few silhouette pixels to "
    "another triangle (measured: 11 px, 99.72 %; depth 1.64e-3); against the float32-input "
    "scene every strict threshold holds."
)
_add(
    Case(
        "mesh_box_seams",
        "rays exactly on a closed box's shared edges (the front face's diagonal, its rims "
        "shared with side faces seen edge-on) and on its corners: a ray between two triangles must hit one",
        mesh_box_seams,
        width=33,
        height=33,
        checks=(no_leak, on_box_seams),
        facts=_mesh_facts,
        methods=MESH_METHODS,
        min_primid_agreement=0.985,
        color_psnr_min=30.0,
        why=_BOX_SEAMS,
        psnr_why=_BOX_SEAMS,
        f32_min_primid_agreement=0.985,
        f32_color_psnr_min=30.0,
        f32_why=_BOX_SEAMS,
    ),
    Case(
        "mesh_box_corner",
        "the centre ray exactly through a box corner shared by three faces",
        mesh_box_corner,
        checks=(no_leak, centre_pixel_hits_mesh, only_ties),
        facts=_mesh_facts,
        methods=MESH_METHODS,
        min_primid_agreement=0.998,
        why="measured: the BIH takes the other triangle on 4 px of one edge (99.90 %); " + _EDGE_TIES,
        f32_min_primid_agreement=0.998,
        f32_why=_EDGE_TIES,
        method_ties_why=_EDGE_TIES,
    ),
    Case(
        "mesh_icosphere_edges",
        "a column of rays exactly along a chain of an icosphere's shared edges, the "
        "centre ray through a vertex of six triangles",
        mesh_icosphere_edges,
        checks=(no_leak, centre_pixel_hits_mesh, only_ties),
        facts=_mesh_facts,
        methods=MESH_METHODS,
        min_primid_agreement=0.993,
        why="measured: the BVH takes the other triangle on 24 px, 23 of them in the centre "
        "column (99.40 %), the kd-tree and two-level on 2; " + _EDGE_TIES,
        f32_min_primid_agreement=0.993,
        f32_why=_EDGE_TIES,
        method_ties_why=_EDGE_TIES,
    ),
    Case(
        "mesh_grazing",
        "rays in a triangle grid's plane (det = 0) and at grazing angles across its edges",
        mesh_grazing,
        checks=(no_leak, only_ties),
        facts=_mesh_facts,
        methods=MESH_METHODS,
        min_primid_agreement=0.997,
        why="measured: the BVH takes the other triangle on 10 px of the centre "
        "column (99.75 %), where the grazing rays cross the grid's shared edges; " + _EDGE_TIES,
        f32_min_primid_agreement=0.997,
        f32_why=_EDGE_TIES,
        method_ties_why=_EDGE_TIES,
    ),
    Case(
        "mesh_needles",
        "needle triangles far thinner than a pixel; zero-area (repeated corner, collinear) "
        "triangles that must never be hit",
        mesh_needles,
        checks=(never_degenerate,),
        facts=_mesh_facts,
        methods=MESH_METHODS,
    ),
    # Brute force is left out: past limits.MAX_LOOP_PRIMITIVES (65,533, llvmpipe's loop limiter) it
    # refuses the scene (tests/renderer/config/test_methods.py) rather than drop the last triangles.
    Case(
        "mesh_huge_81920",
        "81,920 triangles at 25 × 41 (80 per pixel): deep trees, many triangles per "
        "pixel, past the 65,533 primitives a brute-force loop reaches on llvmpipe (so brute force refuses it)",
        mesh_huge,
        width=25,
        height=41,
        max_prims=8,
        checks=(no_leak,),
        facts=_mesh_facts,
        methods=tuple(m for m in MESH_METHODS if m != "bruteforce"),
    ),
    Case(
        "mesh_offset_1e4",
        "meshes 1e4 from the origin, camera 6 units away (float32 spacing 1e-3)",
        mesh_offset_1e4,
        max_prims=8,
        checks=(no_leak,),
        facts=_mesh_facts,
        methods=MESH_METHODS,
        min_primid_agreement=0.997,
        max_depth_rel=2e-3,
        why=_OFFSET_MESH,
        depth_why=_OFFSET_MESH,
    ),
)


# ------------------------------------------------------------------------ analytic shapes
# The hard cases of shaders/shapes.glsl (tests/renderer/accel/shapes_cases.py, there as ray
# sets against the closed forms) as scenes: trees over shapes, shading, the rays that leave them.


def _shape_methods() -> tuple[str, ...]:
    from renderer.config.methods import METHODS

    return tuple(m for m, x in METHODS.items() if "shapes" in x.capabilities.primitives)


SHAPE_METHODS = _shape_methods()


def _shapes_scene(camera: Camera, shapes: dict, spheres=(), planes=(FLOOR,)) -> Scene:
    """A scene of ``shapes`` (the JSON keys) lit by MESH_LIGHT, materials RED, TRANSPARENT, MIRROR."""
    d = {
        "camera": {"position": list(camera.position), "target": list(camera.target), "fov_y": camera.fov_y},
        "lights": [{"position": list(MESH_LIGHT.position), "color": list(MESH_LIGHT.color)}],
        "materials": [m.to_json() for m in (RED, TRANSPARENT, MIRROR)],
        "spheres": [{"center": list(c), "radius": r, "material": m} for c, r, m in spheres],
        "planes": [p.to_json() for p in planes],
        **shapes,
    }
    return Scene.from_json(d)


def shape_torus_far() -> Scene:
    """A torus (R = 100, r = 25) 1e4 from the camera at the origin, and a glass one inside it."""
    c = [0.0, 0.0, -1e4]
    return _shapes_scene(
        Camera((0.0, 0.0, 0.0), tuple(c), (0.0, 1.0, 0.0), 1.8),
        {
            "tori": [
                {"center": c, "axis": [0.2, 1.0, 0.3], "major_radius": 100.0, "minor_radius": 25.0},
                {"center": c, "axis": [1.0, 0.1, 0.0], "major_radius": 40.0, "minor_radius": 12.0, "material": 1},
            ]
        },
        planes=(),
    )


def shape_torus_thin() -> Scene:
    """Thin tori (r/R = 1e-2, 3e-3) seen obliquely, a mirror torus reflecting them."""
    return _shapes_scene(
        Camera((0.0, 2.0, 4.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0),
        {
            "tori": [
                {"center": [0, 0, 0], "axis": [0.2, 1.0, 0.3], "major_radius": 1.0, "minor_radius": 1e-2},
                {"center": [0, 0, 0], "axis": [1.0, 0.2, 0.0], "major_radius": 0.8, "minor_radius": 3e-3},
                {"center": [0, -0.8, -1], "axis": [0, 1, 0], "major_radius": 1.2, "minor_radius": 0.3, "material": 2},
            ]
        },
    )


def shape_coin_and_tubes() -> Scene:
    """A capped cylinder of height 1e-6 (a coin), a glass tube seen along its axis, an open
    mirror tube the camera looks into, a cone with an apex."""
    return _shapes_scene(
        Camera((0.0, 1.0, 6.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0),
        {
            "cylinders": [
                {"base": [-1.2, 0.5, 0], "axis": [0.1, 1, 0.8], "radius": 0.8, "height": 1e-6, "caps": True},
                {"base": [0, 0, -3], "axis": [0, 1 / 6, 1], "radius": 0.5, "height": 2.5, "caps": True, "material": 1},
                {"base": [1.5, -1, 0], "axis": [0, 0.3, 1], "radius": 0.6, "height": 2.0, "caps": False, "material": 2},
            ],
            "cones": [{"base": [0, -1.5, 1], "axis": [0, 1, 0], "base_radius": 0.6, "top_radius": 0.0, "height": 1.0}],
        },
        spheres=(((0.0, 0.0, -6.0), 1.0, 0),),
        planes=(Plane((0.0, -1.5, 0.0), (0.0, 1.0, 0.0), 0),),
    )


def shape_disk_edge_on() -> Scene:
    """Annuli and a disk seen from 0.01 above their plane, 3 away; a disk exactly edge-on."""
    return _shapes_scene(
        Camera((0.0, 0.01, 3.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
        {
            "disks": [
                {"center": [0, 0, 0], "normal": [0, 1, 0], "radius": 1.0, "inner_radius": 0.3},
                {"center": [0, 0.5, -1], "normal": [0, 1, 0.05], "radius": 0.8, "material": 2},
                {"center": [0.8, 0.01, -0.5], "normal": [0, 1, 0], "radius": 0.4},
            ]
        },
        planes=(),
    )


_add(
    Case(
        "shape_torus_far",
        "tori 1e4 from the camera (f = p0 − b·d carries ~1e-3 of rounding), one of glass inside the other",
        shape_torus_far,
        methods=SHAPE_METHODS,
    ),
    Case(
        "shape_torus_thin",
        "thin tori (r/R = 1e-2, 3e-3: the quartic's coefficients cancel) and their reflections",
        shape_torus_thin,
        methods=SHAPE_METHODS,
    ),
    Case(
        "shape_coin_and_tubes",
        "a cylinder 1e-6 high, a glass tube along its axis (the lateral quadratic degenerates), "
        "the inside of an open mirror tube, a cone's apex",
        shape_coin_and_tubes,
        methods=SHAPE_METHODS,
    ),
    Case(
        "shape_disk_edge_on",
        "annuli seen from 1e-2 above their plane, a disk in the camera's plane (dz = 0 rays)",
        shape_disk_edge_on,
        methods=SHAPE_METHODS,
    ),
)
