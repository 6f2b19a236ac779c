"""The thesis's test scenes (chapter IV.B): scenarios 1, 2 and 3 for any n.

All sphere centres lie so that every sphere is inside the cube [-20, 20]³.
The plane is at (0, -20, 0) with normal (0, 1, 0); the camera at (0, 0, 100)
looks at the origin; one white point light at (0, 40, 0); materials of
Table 4.1.

Material assignment (the thesis does not say): sphere ``i`` is transparent
when ``i % 4 == 3`` and red otherwise, so a quarter of the spheres refract;
the plane is red. The assignment depends only on the index, so any scene of
the same n has the same mix.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..geometry.scene import Camera, Light, Material, Plane, Scene, SceneError, make_mesh
from ..geometry.shapes import Shapes

CUBE_HALF = 20.0
# Edge of each of scenario 2's eight corner cubes.
CORNER_CUBE_EDGE = 8.0
SCREEN_WIDTH, SCREEN_HEIGHT = 640, 1088

RED = Material(
    color=(0.9, 0.3, 0.3),
    ambient=0.30,
    diffuse=0.30,
    specular=0.10,
    shininess=40.0,
    reflective=0.30,
    transmissive=0.0,
    ior=1.0,
)
TRANSPARENT = Material(
    color=(1.0, 1.0, 1.0),
    ambient=0.10,
    diffuse=0.10,
    specular=0.10,
    shininess=50.0,
    reflective=0.0,
    transmissive=0.70,
    ior=0.95,
)
TABLE_4_1 = (RED, TRANSPARENT)


def grid_centers(n: int, radius: float) -> np.ndarray:
    """Scenario 1: n centres evenly spaced across the cube.

    A k×k×k grid of cell centres with k = ceil(cbrt(n)); when n < k³, n of the
    k³ cells are taken at evenly spaced positions in x-fastest order.
    """
    if n == 0:
        return np.zeros((0, 3))
    k = max(1, math.ceil(round(n ** (1.0 / 3.0), 9)))
    while k**3 < n:
        k += 1
    half = CUBE_HALF - radius
    if k == 1:
        axis = np.zeros(1)
    else:
        cell = 2.0 * CUBE_HALF / k
        axis = -CUBE_HALF + cell * (np.arange(k) + 0.5)
        axis = np.clip(axis, -half, half) if half > 0 else np.zeros(k)
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    if n < len(pts):
        pick = np.floor(np.arange(n) * (len(pts) / n)).astype(np.int64)
        pts = pts[pick]
    return pts


def corner_centers(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """Scenario 2: n centres at random inside eight small cubes at the corners.

    Corner ``c`` (bits of c pick the sign of x, y, z) gets ``n // 8`` spheres,
    the first ``n % 8`` corners one more. Centres are uniform in the corner cube
    shrunk by the radius, so each sphere lies inside the corner cube.
    """
    per = np.full(8, n // 8)
    per[: n % 8] += 1
    lo = CUBE_HALF - CORNER_CUBE_EDGE + radius
    hi = CUBE_HALF - radius
    if hi < lo:  # radius larger than half a corner cube: centre them
        lo = hi = CUBE_HALF - CORNER_CUBE_EDGE / 2
    out = []
    for c in range(8):
        sign = np.array([1.0 if c & 1 else -1.0, 1.0 if c & 2 else -1.0, 1.0 if c & 4 else -1.0])
        out.append(sign * rng.uniform(lo, hi, size=(per[c], 3)))
    return np.concatenate(out) if out else np.zeros((0, 3))


def with_sky(scene: Scene) -> Scene:
    """``scene`` under the procedural daylight sky (renderer/materials/sky.py) instead of its environment colour."""
    from ..materials.envmap import SKY_REF, EnvironmentMap
    from ..materials.sky import sky_texels

    # (replace validates the new scene; every other field, textures included, stays the scene's)
    return replace(scene, environment=(0.0, 0.0, 0.0), environment_map=EnvironmentMap(SKY_REF, sky_texels()))


def scenario(number: int, n: int, seed: int = 0, radius: float = 1.0, sky: bool = False) -> Scene:
    """Scenario 1, 2 or 3 of the thesis with n spheres of the given radius.

    Scenario 3 is n // 2 spheres as scenario 1 followed by n - n // 2 as
    scenario 2. ``seed`` drives the random placement (scenarios 2 and 3). ``sky``: under the
    procedural sky (:func:`with_sky`; the thesis's scenes have a black background).
    """
    if sky:
        return with_sky(scenario(number, n, seed, radius))
    if number not in (1, 2, 3):
        raise SceneError("scenario", f"must be 1, 2 or 3, got {number!r}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n <= Scene.MAX_SPHERES:
        raise SceneError("n", f"must be an integer in 0 … {Scene.MAX_SPHERES}, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SceneError("seed", f"must be a non-negative integer, got {seed!r}")
    if not (isinstance(radius, (int, float)) and math.isfinite(radius) and 0 < radius <= CUBE_HALF):
        raise SceneError("radius", f"must be a number in (0, {CUBE_HALF}], got {radius!r}")
    rng = np.random.default_rng(seed)
    if number == 1:
        centers = grid_centers(n, radius)
    elif number == 2:
        centers = corner_centers(n, radius, rng)
    else:
        centers = np.concatenate([grid_centers(n // 2, radius), corner_centers(n - n // 2, radius, rng)])
    materials = (np.arange(n) % 4 == 3).astype(np.int32)
    return Scene(
        camera=Camera(position=(0.0, 0.0, 100.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=60.0),
        lights=(Light(position=(0.0, 40.0, 0.0), color=(1.0, 1.0, 1.0)),),
        materials=TABLE_4_1,
        sphere_centers=centers,
        sphere_radii=np.full(n, float(radius)),
        sphere_materials=materials,
        planes=(Plane(point=(0.0, -CUBE_HALF, 0.0), normal=(0.0, 1.0, 0.0), material=0),),
    )


# ---- scenes with triangle meshes -------------------------------------------------------
MESH_SCENES = ("spheres", "teapot", "mixed", "room", "cornell", "table", "materials")
MAX_MESH_DETAIL = 5

PORCELAIN = Material(
    color=(0.92, 0.9, 0.85),
    ambient=0.15,
    diffuse=0.65,
    specular=0.4,
    shininess=60.0,
    reflective=0.1,
    transmissive=0.0,
    ior=1.0,
)
GLASS = Material(
    color=(1.0, 1.0, 1.0),
    ambient=0.05,
    diffuse=0.05,
    specular=0.3,
    shininess=80.0,
    reflective=0.1,
    transmissive=0.8,
    ior=1.5,
)
WALLS = Material(
    color=(0.75, 0.72, 0.65),
    ambient=0.25,
    diffuse=0.6,
    specular=0.05,
    shininess=10.0,
    reflective=0.0,
    transmissive=0.0,
    ior=1.0,
)


def mesh_scene(kind: str = "teapot", detail: int = 2, smooth: bool = True, sky: bool = False) -> Scene:
    """A scene with triangle meshes inside the thesis's cube [−20, 20]³, for demos and tests.

    - ``teapot``: the closed Utah teapot (:func:`renderer.geometry.meshes.teapot`, 5.5 units to the
      data's 1: about 17 high and 36 long) standing on the floor plane y = −20;
    - ``mixed``: a grid of 27 red spheres above the floor, a glass icosphere and a red
      torus among them (spheres, planes and triangles together, the ids of every kind);
    - ``room``: a closed box room seen from inside (walls wound inwards, no plane), with
      a teapot, a glass icosphere and four spheres;
    - ``cornell``: a Cornell box for the path integrator (``integrator=path``): five wall
      planes (red left, green right, white floor, ceiling and back; the front open onto a
      black environment), an emitting panel under the ceiling (a quad, its only light:
      ``lights`` is empty), a mirror sphere, a glass sphere (its caustic on the floor) and a
      diffuse teapot;
    - ``table``: analytic shapes only (:mod:`renderer.geometry.shapes`, no triangle): a round table (a
      disk top with an open cylinder as its edge, on four cylinder legs) on the floor plane,
      with a torus, a metal can (a capped cylinder), a glass lens (a short wide capped glass
      cylinder standing on its rim: its caps are the lens's two flat faces, its tube the rim)
      and a table lamp — a cone foot, a cylinder stand and a lampshade (an open cone frustum)
      with an emitting disk inside facing down (as wide as the shade allows: the path
      integrator meets an emitting shape by BSDF sampling alone, and a wider one is met more
      often). Lit by a point light, and with ``integrator=path`` by that disk too (the lamp's
      pool of light on the table);
    - ``materials``: glTF metallic-roughness materials on textures the project draws itself
      (:mod:`renderer.materials.procedural_textures`, :func:`_materials`): a checkerboard floor, a wooden
      plank, a brushed metal ball, a wall of bevelled tiles (a normal map) and a ball of tinted
      glass, under the procedural sky and a point light where its sun is.

    ``detail`` (0 … MAX_MESH_DETAIL) sets the tessellation: teapot ``2 + 2·detail``
    segments per patch, icosphere subdivisions ``detail``, torus ``12 (detail + 1)``
    segments. ``smooth``: vertex normals (else flat shading). ``sky``: under the procedural sky
    (:func:`with_sky`). Deterministic.
    """
    if sky:
        return with_sky(mesh_scene(kind, detail, smooth))
    from ..geometry import meshes as M

    if kind not in MESH_SCENES:
        raise SceneError("kind", f"unknown mesh scene {kind!r}; one of {', '.join(MESH_SCENES)}")
    if isinstance(detail, bool) or not isinstance(detail, (int, np.integer)) or not 0 <= detail <= MAX_MESH_DETAIL:
        raise SceneError("detail", f"must be an integer in 0 … {MAX_MESH_DETAIL}, got {detail!r}")
    seg = 2 + 2 * int(detail)
    light = Light(position=(20.0, 40.0, 30.0), color=(1.0, 1.0, 1.0))
    floor = Plane(point=(0.0, -CUBE_HALF, 0.0), normal=(0.0, 1.0, 0.0), material=0)

    def placed(x: float, y: float, z: float, s: float = 1.0) -> list:
        return [[s, 0.0, 0.0, x], [0.0, s, 0.0, y], [0.0, 0.0, s, z], [0.0, 0.0, 0.0, 1.0]]

    empty = (np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    if kind == "teapot":
        pot = M.teapot(seg, size=5.5, material=1, smooth=smooth, transform=placed(-1.0, -CUBE_HALF, 0.0))
        return Scene(
            Camera((0.0, 8.0, 75.0), (0.0, -10.0, 0.0), (0.0, 1.0, 0.0), 45.0),
            (light,),
            (RED, PORCELAIN),
            *empty,
            (floor,),
            (pot,),
        )
    if kind == "mixed":
        axis = np.array([-12.0, 0.0, 12.0])
        z, y, x = np.meshgrid(axis, axis + 2.0, axis, indexing="ij")
        centers = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        meshes = (
            M.icosphere(int(detail), radius=5.0, center=(-6.0, -12.0, 6.0), material=1, smooth=smooth),
            M.torus(
                6.0,
                1.8,
                12 * (int(detail) + 1),
                6 * (int(detail) + 1),
                center=(6.0, -16.0, -4.0),
                material=0,
                smooth=smooth,
            ),
        )
        return Scene(
            Camera((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0),
            (light,),
            (RED, GLASS),
            centers,
            np.full(len(centers), 2.0),
            np.zeros(len(centers), np.int32),
            (floor,),
            meshes,
        )
    if kind == "spheres":
        return _spheres()
    if kind == "cornell":
        return _cornell(M, seg, smooth, placed)
    if kind == "table":
        return _table(light, floor)
    if kind == "materials":
        return _materials(int(detail), smooth)
    room = M.box((-CUBE_HALF,) * 3, (CUBE_HALF,) * 3, inward=True, material=0)
    # The furniture stands together at the back, seen from high by the front wall: a portrait
    # screen shows all of it from inside the room (framing never puts the camera through a wall).
    pot = M.teapot(seg, size=2.2, material=1, smooth=smooth, transform=placed(-2.0, -CUBE_HALF, -8.0))
    ball = M.icosphere(int(detail), radius=3.0, center=(6.0, -17.0, -13.0), material=2, smooth=smooth)
    centers = np.array([[-8.0, -17.5, -1.0], [7.0, -17.5, -3.0], [-7.0, -17.5, -14.0], [0.0, -17.5, -16.0]])
    return Scene(
        Camera((0.0, 14.0, 18.0), (0.0, -16.0, -6.0), (0.0, 1.0, 0.0), 70.0),
        (Light((0.0, 18.0, 5.0), (1.0, 1.0, 1.0)),),
        (WALLS, PORCELAIN, GLASS, RED),
        centers,
        np.full(4, 2.5),
        np.full(4, 3, np.int32),
        (),
        (room, pot, ball),
    )


def _matte(color, ambient: float = 0.3) -> Material:
    """A Lambertian wall (path integrator: albedo ``color``; Whitted: ambient and diffuse only)."""
    return Material(
        color=color,
        ambient=ambient,
        diffuse=1.0,
        specular=0.0,
        shininess=1.0,
        reflective=0.0,
        transmissive=0.0,
        ior=1.0,
    )


def _emitter(emission) -> Material:
    """A light's surface: it emits ``emission`` and reflects nothing."""
    return Material(
        color=(1.0, 1.0, 1.0),
        ambient=0.0,
        diffuse=0.0,
        specular=0.0,
        shininess=1.0,
        reflective=0.0,
        transmissive=0.0,
        ior=1.0,
        emission=emission,
    )


CORNELL_MATERIALS = (
    _matte((0.73, 0.73, 0.73)),  # 0 white: floor, ceiling, back wall
    _matte((0.63, 0.065, 0.05)),  # 1 red: the left wall
    _matte((0.14, 0.45, 0.091)),  # 2 green: the right wall
    _emitter((17.0, 12.0, 4.0)),  # 3 the ceiling panel
    Material(
        color=(1.0, 1.0, 1.0),
        ambient=0.0,
        diffuse=0.0,
        specular=0.5,
        shininess=200.0,
        reflective=1.0,
        transmissive=0.0,
        ior=1.0,
    ),  # 4 mirror
    Material(
        color=(1.0, 1.0, 1.0),
        ambient=0.0,
        diffuse=0.0,
        specular=0.5,
        shininess=200.0,
        reflective=0.0,
        transmissive=1.0,
        ior=1.5,
    ),  # 5 clear glass
    _matte((0.8, 0.75, 0.6)),  # 6 the teapot
)


def _cornell(M, seg: int, smooth: bool, placed) -> Scene:
    h = CUBE_HALF
    planes = (
        Plane((0.0, -h, 0.0), (0.0, 1.0, 0.0), 0),
        Plane((0.0, h, 0.0), (0.0, -1.0, 0.0), 0),
        Plane((0.0, 0.0, -h), (0.0, 0.0, 1.0), 0),
        Plane((-h, 0.0, 0.0), (1.0, 0.0, 0.0), 1),
        Plane((h, 0.0, 0.0), (-1.0, 0.0, 0.0), 2),
    )
    y = h - 0.01  # a quad just under the ceiling, wound to face down
    panel = make_mesh([[-5.0, y, -5.0], [5.0, y, -5.0], [5.0, y, 5.0], [-5.0, y, 5.0]], [[0, 1, 2], [0, 2, 3]], 3)
    pot = M.teapot(seg, size=3.2, material=6, smooth=smooth, transform=placed(0.0, -h, -10.0))
    centers = np.array([[-9.0, -h + 6.0, -4.0], [8.0, -h + 6.0, 6.0]])
    # The camera sees the open front exactly: 2h wide at 2h·(1 + 1/tan(fov/2)) / 2 from the back.
    fov = 40.0
    z = h + h / np.tan(np.radians(fov / 2.0))
    return Scene(
        Camera((0.0, 0.0, float(z)), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), fov),
        (),
        CORNELL_MATERIALS,
        centers,
        np.array([6.0, 6.0]),
        np.array([4, 5], np.int32),
        planes,
        (panel, pot),
    )


TABLE_MATERIALS = (
    _matte((0.55, 0.55, 0.6), ambient=0.25),  # 0 the floor
    Material(
        color=(0.55, 0.34, 0.18),
        ambient=0.25,
        diffuse=0.7,
        specular=0.2,
        shininess=30.0,
        reflective=0.05,
        transmissive=0.0,
        ior=1.0,
    ),  # 1 the table's wood
    _matte((0.8, 0.2, 0.15)),  # 2 the torus
    GLASS,  # 3 the lens
    Material(
        color=(0.85, 0.85, 0.9),
        ambient=0.1,
        diffuse=0.3,
        specular=0.6,
        shininess=120.0,
        reflective=0.6,
        transmissive=0.0,
        ior=1.0,
        roughness=0.15,
    ),  # 4 brushed metal: the can, the lamp's foot and stand
    _matte((0.92, 0.86, 0.7)),  # 5 the lampshade
    _emitter((15.0, 12.0, 7.5)),  # 6 the lamp's bulb: a disk facing down
)
TABLE_TOP = -8.0  # the table top's height
TABLE_RADIUS = 12.0


def _table(light: Light, floor: Plane) -> Scene:
    """``mesh_scene("table")``: see there. Every object stands on the top or the floor."""
    top, r = TABLE_TOP, TABLE_RADIUS
    up = [0.0, 1.0, 0.0]
    legs = [
        {"base": [x, -CUBE_HALF, z], "axis": up, "radius": 0.7, "height": top - 0.8 + CUBE_HALF, "material": 1}
        for x, z in ((-7.5, -7.5), (7.5, -7.5), (-7.5, 7.5), (7.5, 7.5))
    ]
    lamp = (6.0, -6.0)  # the lamp's place on the top (x, z)
    shapes = Shapes.from_json(
        {
            "cylinders": [
                {"base": [0.0, top - 0.8, 0.0], "axis": up, "radius": r, "height": 0.8, "caps": False, "material": 1},
                *legs,
                {"base": [5.0, top, 5.0], "axis": up, "radius": 1.5, "height": 3.5, "material": 4},  # the can
                # the lens: 6 wide, 0.8 thick, on its rim, its faces turned towards the camera's left
                {
                    "base": [-0.3, top + 3.0, 0.5],
                    "axis": [0.5, 0.0, 0.866],
                    "radius": 3.0,
                    "height": 0.8,
                    "material": 3,
                },
                {"base": [lamp[0], top + 0.6, lamp[1]], "axis": up, "radius": 0.3, "height": 6.8, "material": 4},
            ],
            "cones": [
                {"base": [lamp[0], top, lamp[1]], "axis": up, "base_radius": 2.2, "top_radius": 0.3, "height": 0.6}
                | {"material": 4},  # the lamp's foot
                {"base": [lamp[0], top + 6.0, lamp[1]], "axis": up, "base_radius": 4.0, "top_radius": 2.0}
                | {"height": 3.5, "caps": False, "material": 5},  # the shade, open at both ends
            ],
            "disks": [
                # the top, both sides (its underside closes the edge), and the bulb under the stand's end
                {"center": [0.0, top, 0.0], "normal": up, "radius": r, "material": 1},
                {"center": [0.0, top - 0.8, 0.0], "normal": up, "radius": r, "material": 1},
                {"center": [lamp[0], top + 7.5, lamp[1]], "normal": [0.0, -1.0, 0.0], "radius": 2.8, "material": 6},
            ],
            "tori": [
                {"center": [-6.0, top + 0.9, 3.0], "axis": up, "major_radius": 2.6, "minor_radius": 0.9, "material": 2},
            ],
        }
    )
    empty = (np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    return Scene(
        Camera((0.0, 10.0, 42.0), (0.0, -6.0, 0.0), (0.0, 1.0, 0.0), 45.0),
        (light,),
        TABLE_MATERIALS,
        *empty,
        (floor,),
        (),
        (0.02, 0.02, 0.025),  # a faint sky: the path integrator's image is not black beyond the lamp's light
        None,
        shapes,
    )


# ---- materials and textures the project makes itself -------------------------------------
MATERIALS_TEXTURE_SIZE = 256  # pixels a side of each of the scene's textures
BOARD = ((-10.0, 10.0), (-14.0, 14.0))  # the checkerboard's x and z extents on the floor: deep, for a phone upright
BOARD_SQUARE = 2.0  # world units a side of one of its squares


def materials_scene_parts(detail: int = 2, smooth: bool = True) -> tuple[Scene, dict[str, int]]:
    """``mesh_scene("materials")`` (see there; :func:`_materials`) and which mesh is which
    object (``board``, ``tiles``, ``plank``, ``metal``, ``glass``: indices into its meshes)."""
    from ..geometry import meshes as M
    from ..materials import procedural_textures as T
    from ..materials.pbr import PbrMaterial
    from ..materials.sky import SUN_DIRECTION

    size = MATERIALS_TEXTURE_SIZE
    checker = T.checker(size, squares=8)
    wood, wood_mr = T.wood(size)
    brushed = T.brushed_metal(size, roughness=0.3, spread=0.4)
    glaze, tile_normals = T.tiles(size, count=4)
    textures = (checker, wood, wood_mr, brushed, glaze, tile_normals)

    (x0, x1), (z0, z1) = BOARD
    repeat = 8 * BOARD_SQUARE  # world units of one repeat of the checker image (8 squares)
    board_uv = ((x1 - x0) / repeat, 0.0, 0.0, (z1 - z0) / repeat)
    tiles_uv = (2.0, 0.0, 0.0, 1.5)  # 8 × 6 tiles of 2.5 on the wall's 20 × 15 face
    materials = (
        PbrMaterial(
            base_color=(0.2, 0.19, 0.18), metallic=0.0, roughness=0.9
        ),  # 0 the floor: dark, the board stands out
        PbrMaterial(metallic=0.0, roughness=0.4, base_color_texture=0, base_color_uv_matrix=board_uv),  # 1 board
        PbrMaterial(
            metallic=1.0, roughness=1.0, base_color_texture=1, metallic_roughness_texture=2
        ),  # 2 the plank: colour and roughness from the wood, metallic 0 from its blue
        PbrMaterial(
            base_color=(0.91, 0.92, 0.92), metallic=1.0, roughness=1.0, metallic_roughness_texture=3
        ),  # 3 brushed aluminium: the roughness from its streaks
        PbrMaterial(
            metallic=0.0,
            roughness=0.25,
            base_color_texture=4,
            base_color_uv_matrix=tiles_uv,
            normal_texture=5,
            normal_uv_matrix=tiles_uv,
        ),  # 4 glazed tiles
        T.tinted_glass((0.3, 0.75, 0.5), distance=4.0),  # 5
    )
    y = -CUBE_HALF + 0.02  # the board lies just above the floor plane
    board = make_mesh(
        [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]],
        [[0, 3, 2], [0, 2, 1]],  # wound to face up
        1,
        uvs=[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],  # the image's top at the far side
        tangents=[[1.0, 0.0, 0.0, 1.0]] * 4,
    )
    floor_y = -CUBE_HALF
    tiles = M.box((-10.0, floor_y, -15.0), (10.0, floor_y + 15.0, -14.0), material=4, uvs=True)
    plank = M.box((-9.0, floor_y, -10.0), (1.0, floor_y + 2.5, -5.0), material=2, uvs=True)
    sub = min(int(detail) + 1, M.MAX_SUBDIVISIONS)
    metal = M.icosphere(sub, radius=4.0, center=(5.0, floor_y + 4.0, -4.0), material=3, smooth=smooth, uvs=True)
    glass = M.icosphere(sub, radius=3.5, center=(-2.0, floor_y + 3.5, 5.0), material=5, smooth=smooth)
    sun = tuple(float(c) for c in SUN_DIRECTION * 80.0)
    scene = Scene(
        Camera((0.0, 22.0, 36.0), (0.0, -14.0, 0.0), (0.0, 1.0, 0.0), 45.0),
        (
            Light(position=(sun[0], sun[1], sun[2]), color=(0.7, 0.7, 0.7)),
        ),  # Whitted's sun; the path's sun is in the sky too
        materials,
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        (Plane((0.0, floor_y, 0.0), (0.0, 1.0, 0.0), 0),),
        (board, tiles, plank, metal, glass),
        textures=textures,
    )
    return with_sky(scene), {"board": 0, "tiles": 1, "plank": 2, "metal": 3, "glass": 4}


def _materials(detail: int, smooth: bool) -> Scene:
    """``mesh_scene("materials")``: a 20 × 28 checkerboard (squares of :data:`BOARD_SQUARE`) on a
    grey floor, deeper than wide so that a phone held upright shows it large; at its back a wall of
    glazed tiles (20 × 15, a normal map of bevelled tiles); before it a wooden plank on the left
    (its grain along x, its roughness from the wood's rings) and a brushed aluminium ball (r 4) on
    the right whose streaks run around it like a lathe's; a ball of green-tinted glass (r 3.5) in
    front. Every material is glTF's metallic-roughness kind; every
    texture is :data:`MATERIALS_TEXTURE_SIZE` pixels a side. The balls are icospheres of
    ``detail + 1`` subdivisions."""
    return materials_scene_parts(detail, smooth)[0]


# ---- the default scene: the thesis's grid in colour, under the sky ---------------------
SPHERES_N = 512  # the phone client's first scene: scenario 1's grid of 512 (8 × 8 × 8)
SPHERES_PALETTE = (
    (0.95, 0.45, 0.2),  # orange
    (0.2, 0.55, 0.95),  # blue
    (0.3, 0.8, 0.35),  # green
    (0.95, 0.8, 0.2),  # yellow
    (0.75, 0.35, 0.85),  # violet
)


def _glossy(color) -> Material:
    return Material(
        color=color,
        ambient=0.25,
        diffuse=0.7,
        specular=0.5,
        shininess=60.0,
        reflective=0.15,
        transmissive=0.0,
        ior=1.0,
    )


SPHERES_MATERIALS = (
    Material(
        color=(0.78, 0.78, 0.74),
        ambient=0.35,
        diffuse=0.6,
        specular=0.05,
        shininess=10.0,
        reflective=0.1,
        transmissive=0.0,
        ior=1.0,
    ),  # 0 the floor: light stone, so that coloured spheres stand out on it
    *(_glossy(c) for c in SPHERES_PALETTE),  # 1 … 5
    GLASS,  # 6: every fourth sphere, as the thesis's quarter of transparent ones
)


def _spheres() -> Scene:
    """``mesh_scene("spheres")``: scenario 1's geometry (512 spheres, radius 1, the floor) exactly,
    in colours on a light floor under the procedural sky: the thesis's red-on-red under a black
    sky reads badly on a phone."""
    base = scenario(1, SPHERES_N, seed=1, radius=1.0)
    i = np.arange(SPHERES_N)
    glass = len(SPHERES_MATERIALS) - 1
    # colours run diagonally through the grid (8 to a row, 64 to a layer): no row or column of one colour
    materials = np.where(i % 4 == 3, glass, 1 + (i + i // 8 + i // 64) % len(SPHERES_PALETTE)).astype(np.int32)
    coloured = Scene(
        Camera((0.0, 18.0, 95.0), (0.0, -2.0, 0.0), (0.0, 1.0, 0.0), 50.0),
        (Light(position=(25.0, 60.0, 40.0), color=(1.0, 1.0, 1.0)),),
        SPHERES_MATERIALS,
        base.sphere_centers,
        base.sphere_radii,
        materials,
        base.planes,
    )
    return with_sky(coloured)


# ---- framing: a camera that shows a box on a screen of any aspect --------------------------
FRAME_MARGIN = 0.06  # of the half-frame, each side: the content never touches the screen's edge
MAX_FRAMING_FOV_Y = 100.0  # degrees: the widest view framing opens inside an enclosure (beyond: fisheye-like)
WALL_INSET = 1.0  # world units: a framed camera inside an enclosure stays this far from its walls


def object_boxes(scene: Scene) -> np.ndarray:
    """float64 (K, 2, 3): the (min, max) box of every sphere, mesh and analytic shape of ``scene``
    (planes are unbounded: none)."""
    from ..geometry.shapes import bounds as shape_bounds

    c, r = scene.sphere_centers, scene.sphere_radii[:, None]
    parts = [np.stack([c - r, c + r], axis=1)] if len(c) else []
    parts += [np.stack([m.vertices.min(axis=0), m.vertices.max(axis=0)])[None] for m in scene.meshes if len(m.vertices)]
    if scene.n_shapes:
        parts.append(shape_bounds(scene.shapes))
    return np.concatenate(parts).astype(np.float64) if parts else np.zeros((0, 2, 3))


@dataclass(frozen=True)
class ContentBox:
    """What framing must show: ``lo``/``hi`` (world units), and ``enclosure``, the box of a mesh
    the camera is inside of (a room seen from inside), which the camera may not leave."""

    lo: np.ndarray
    hi: np.ndarray
    enclosure: np.ndarray | None = field(default=None)


def content_box(scene: Scene, camera: Camera | None = None) -> ContentBox:
    """The box framing shows: every object's box, except a mesh's that holds the camera (an
    enclosure), grown to the axis-aligned planes that face it (a Cornell box's walls, a floor).
    An empty scene: the thesis's cube."""
    eye = np.array((camera or scene.camera).position, dtype=np.float64)
    boxes = object_boxes(scene)
    enclosure = None
    if scene.meshes:
        mesh_rows = range(scene.n_spheres, scene.n_spheres + len(scene.meshes))
        holds = [k for k in mesh_rows if np.all(boxes[k, 0] < eye) and np.all(eye < boxes[k, 1])]
        if holds:
            enclosure = boxes[holds[0]]
            boxes = np.delete(boxes, holds, axis=0)
    if not len(boxes):
        lo, hi = np.full(3, -CUBE_HALF), np.full(3, CUBE_HALF)
    else:
        lo, hi = boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)
    reach = float(np.max(hi - lo))
    for plane in scene.planes:
        n = np.asarray(plane.normal, dtype=np.float64)
        axis = int(np.argmax(np.abs(n)))
        if abs(n[axis]) < 0.999:  # a slanted plane bounds no axis
            continue
        at = float(plane.point[axis])
        if n[axis] > 0 and lo[axis] - reach <= at <= lo[axis]:
            lo[axis] = at
        elif n[axis] < 0 and hi[axis] <= at <= hi[axis] + reach:
            hi[axis] = at
    return ContentBox(lo, hi, enclosure)


def fit_camera(
    box: ContentBox,
    aspect: float,
    fov_y: float,
    view_from: Sequence[float],
    up: Sequence[float] = (0.0, 1.0, 0.0),
    margin: float = FRAME_MARGIN,
) -> Camera:
    """A camera looking at the box's centre from direction ``view_from`` (towards the camera) whose
    frame of ``aspect`` (width / height) and vertical field of view ``fov_y`` (degrees) holds all
    eight corners, each at least ``margin`` of the half-frame inside its edges: as near as that
    allows. Inside an enclosure the camera stops ``WALL_INSET`` short of its walls and opens its
    field of view instead (up to ``MAX_FRAMING_FOV_Y``)."""
    centre = (box.lo + box.hi) / 2.0
    back = np.asarray(view_from, dtype=np.float64)
    back = back / np.linalg.norm(back)
    forward = -back
    right = np.cross(forward, np.asarray(up, dtype=np.float64))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    corners = box.lo + corners * (box.hi - box.lo) - centre
    x, y, z = np.abs(corners @ right), np.abs(corners @ true_up), corners @ forward
    keep = 1.0 - margin

    def distance(tan_half: float) -> float:
        need = np.maximum(x / (tan_half * aspect * keep), y / (tan_half * keep)) - z
        size = float(np.max(box.hi - box.lo)) or 1.0
        return max(float(np.max(need)), float(np.max(-z)) + 1e-3 * size)

    tan_half = math.tan(math.radians(fov_y) / 2.0)
    d = distance(tan_half)
    if box.enclosure is not None:
        lo, hi = box.enclosure[0] + WALL_INSET, box.enclosure[1] - WALL_INSET
        with np.errstate(divide="ignore"):
            exits = np.where(back > 0, (hi - centre) / back, np.where(back < 0, (lo - centre) / back, np.inf))
        room = float(np.min(exits))
        if d > room and np.all(room + z > 0):
            depth = (room + z) * keep
            tan_half = min(
                float(np.max(np.maximum(x / (aspect * depth), y / depth))),
                math.tan(math.radians(MAX_FRAMING_FOV_Y) / 2.0),
            )
            d = room
            fov_y = math.degrees(2.0 * math.atan(tan_half))
    position = centre + d * back
    return Camera(tuple(position.tolist()), tuple(centre.tolist()), tuple(np.asarray(up, float).tolist()), fov_y)


def framed(scene: Scene, aspect: float, camera: Camera | None = None) -> Scene:
    """``scene`` through a camera fitted to its content (:func:`content_box`) for a screen of
    ``aspect`` (width / height), from the direction, field of view and up of ``camera`` (default:
    the scene's)."""
    cam = camera or scene.camera
    view_from = tuple(p - t for p, t in zip(cam.position, cam.target, strict=True))
    return scene.with_camera(fit_camera(content_box(scene, cam), aspect, cam.fov_y, view_from, cam.up))


# ---- the demo scenes: one registry for the API, the client's picker, the CLI and the README ----
@dataclass(frozen=True)
class DemoScene:
    """One entry of the scene picker: ``value`` (the client's scenario value), ``label``, ``recipe``
    (the body of POST /api/sessions that makes it) and ``settings`` (its recommended render
    settings: names of :data:`renderer.config.settings.SETTINGS`; a session's body wins over them)."""

    value: int | str
    label: str
    recipe: Mapping[str, Any]
    settings: Mapping[str, Any] = field(default_factory=dict)
    default: bool = False

    def to_json(self) -> dict[str, Any]:
        out = {"value": self.value, "label": self.label, "recipe": dict(self.recipe), "settings": dict(self.settings)}
        if self.default:
            out["default"] = True
        return out


PATH_DENOISED = {"integrator": "path", "denoise": "oidn"}
_THESIS = {"n": 512, "seed": 1}
DEMO_SCENES: tuple[DemoScene, ...] = (
    DemoScene("mesh:spheres", "Spheres under the sky", {"mesh_scene": {"kind": "spheres"}}, default=True),
    DemoScene(1, "1 — grid", {"scenario": 1, **_THESIS}),
    DemoScene(2, "2 — eight corner clusters", {"scenario": 2, **_THESIS}),
    DemoScene(3, "3 — half grid, half clusters", {"scenario": 3, **_THESIS}),
    DemoScene("sky:2", "2 under the sky — path traced", {"scenario": 2, **_THESIS, "sky": True}, PATH_DENOISED),
    DemoScene("museum", "Museum — animated (Reiter)", {"museum": {"n": 64}}),
    DemoScene("mesh:teapot", "Teapot — triangles (Newell)", {"mesh_scene": {"kind": "teapot"}}),
    DemoScene("mesh:mixed", "Icosphere, torus and spheres", {"mesh_scene": {"kind": "mixed"}}),
    DemoScene("mesh:room", "Mesh room — teapot, icosphere, spheres", {"mesh_scene": {"kind": "room"}}),
    DemoScene("mesh:cornell", "Cornell box — path traced", {"mesh_scene": {"kind": "cornell"}}, PATH_DENOISED),
    DemoScene(
        "mesh:table",
        "Table and lamp — cylinders, cones, disks, a torus; path traced",
        {"mesh_scene": {"kind": "table"}},
        PATH_DENOISED,
    ),
    DemoScene(
        "mesh:materials",
        "Materials — checker, wood, brushed metal, tiles, tinted glass; path traced",
        {"mesh_scene": {"kind": "materials"}},
        # the sky's sun and the point light together: a stop down, and ACES keeps the white tiles' glaze
        {**PATH_DENOISED, "tone_map": "aces", "exposure": -1.0},
    ),
)
DEFAULT_DEMO = next(d for d in DEMO_SCENES if d.default)


def demo_for_recipe(
    scenario_number: int | None = None, sky: bool = False, museum: bool = False, mesh_kind: str | None = None
) -> DemoScene | None:
    """The registry's entry a session's recipe makes (its recommended settings apply), or None."""
    if mesh_kind is not None:
        value: int | str | None = f"mesh:{mesh_kind}"
    elif museum:
        value = "museum"
    elif scenario_number is not None:
        value = f"sky:{scenario_number}" if sky else scenario_number
    else:
        return None
    return next((d for d in DEMO_SCENES if d.value == value), None)


def demo_scenes_markdown() -> str:
    """The README's list of the demo scenes (between its ``demo-scenes`` markers), made from
    :data:`DEMO_SCENES`: a test keeps the two the same."""
    rows = ["| scene (`?scenario=`) | POST /api/sessions | opens with |", "|---|---|---|"]
    for d in DEMO_SCENES:
        recipe = json.dumps(dict(d.recipe), separators=(", ", ": "))
        settings = ", ".join(f"`{k}={v}`" for k, v in d.settings.items()) or "the service's defaults"
        mark = " (the default: an empty body)" if d.default else ""
        rows.append(f"| *{d.label}* (`{d.value}`){mark} | `{recipe}` | {settings} |")
    return "\n".join(rows)
