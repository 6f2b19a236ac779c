"""Fixtures shared by the tests of several renderer modules."""

from __future__ import annotations

import pytest

from renderer.meshes import icosphere, teapot, torus
from renderer.scenarios import mesh_scene
from renderer.scene import Camera


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
