"""Fixtures shared by the tests of several renderer modules."""

from __future__ import annotations

import pytest

from renderer.geometry.meshes import icosphere, teapot, torus
from renderer.geometry.scene import Camera
from renderer.scenes.scenarios import mesh_scene


@pytest.fixture(scope="session")
def mixed_trees_scene():
    """27 spheres, the floor plane, a teapot, two icospheres and two tori, some overlapping
    each other and the spheres, filling most of the view: the scene of the trees over
    spheres and triangles together (accel/test_cpu_trace.py, test_bih_traverse.py,
    test_primitives.py, test_base.py, test_twolevel.py and test_prepare.py)."""
    base = mesh_scene("mixed", detail=2)
    pot = teapot(4, size=4.0, material=0, transform=[[1, 0, 0, 0.0], [0, 1, 0, -20.0], [0, 0, 1, 0.0], [0, 0, 0, 1]])
    meshes = (
        pot,
        icosphere(2, radius=6.0, center=(-10.0, -4.0, 8.0), material=1),
        torus(6.0, 2.0, 24, 12, center=(9.0, -9.0, 6.0)),
        icosphere(1, radius=2.5, center=(12.0, 2.0, 12.0)),
        torus(3.0, 1.0, 16, 8, center=(0.0, 6.0, 6.0)),
    )
    cam = Camera((0.0, 2.0, 40.0), (0.0, -6.0, 0.0), (0.0, 1.0, 0.0), 62.0)
    return base.with_geometry(base.sphere_centers, base.sphere_radii, base.sphere_materials, meshes).with_camera(cam)


RED = {"color": [0.8, 0.3, 0.2], "ambient": 0.1, "diffuse": 0.7, "specular": 0.3, "shininess": 20}
MIRROR = {
    "color": [0.9, 0.9, 0.9],
    "ambient": 0.05,
    "diffuse": 0.3,
    "specular": 0.2,
    "shininess": 40,
    "reflective": 0.6,
}
GLASS = {"color": [1, 1, 1], "diffuse": 0.1, "specular": 0.3, "shininess": 60, "transmissive": 0.8, "ior": 1.5}
EVERY_SHAPE = {
    "camera": {"position": [0, 3, 14], "target": [0, 0, 0], "fov_y": 50},
    "lights": [{"position": [5, 10, 10], "color": [1, 1, 1]}],
    "materials": [RED, MIRROR, GLASS],
    "spheres": [
        {"center": [-3, 1.5, -1], "radius": 1.0, "material": 1},
        {"center": [3.2, 2.5, 0], "radius": 0.7, "material": 0},
    ],
    "planes": [{"point": [0, -2, 0], "normal": [0, 1, 0], "material": 0}],
    "cylinders": [
        {"base": [-3, -2, 1], "axis": [0, 1, 0], "radius": 0.8, "height": 2.0, "caps": True, "material": 0},
        {"base": [3, -2, 1], "axis": [0.2, 1, 0.1], "radius": 0.7, "height": 2.5, "caps": False, "material": 1},
    ],
    "cones": [
        {"base": [0, -2, 3], "axis": [0, 1, 0], "base_radius": 1.0, "top_radius": 0.4, "height": 1.5, "material": 2}
    ],
    "disks": [
        {"center": [-1.5, 2.5, 0], "normal": [0, 0.3, 1], "radius": 0.8, "material": 0},
        {"center": [1.5, 2.5, 0], "normal": [0.2, 0, 1], "radius": 0.9, "inner_radius": 0.4, "material": 1},
    ],
    "tori": [{"center": [0, 0, 0], "axis": [0.3, 1, 0.2], "major_radius": 1.6, "minor_radius": 0.45, "material": 2}],
}


@pytest.fixture(scope="session")
def every_shape_scene():
    """A glass torus, a capped and an open (mirror) cylinder, a glass frustum, a disk and an
    annulus, two spheres and a plane: every kind of analytic shape, and rays that leave them."""
    from renderer.geometry.scene import Scene

    return Scene.from_json(EVERY_SHAPE)
