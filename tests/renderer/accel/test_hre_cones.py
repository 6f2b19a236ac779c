"""The cones of the hierarchical ray engine (renderer.accel.hre_cones), in NumPy float64.

Every ray of a tile lies in its tile's cone (brute force over points along each ray), and
the cone-against-sphere cull never drops a sphere that a ray of the tile hits. The GPU's
cones against the GPU's own rays are checked in ``tests/renderer/gl/test_ray_engine.py``.
"""

from __future__ import annotations

import numpy as np

from renderer.accel import hre_cones
from tests.renderer.accel.support import any_hit, check_contained


def coherent_tiles(rng, n_tiles: int, k: int):
    """Tiles of camera rays, of their reflections off a sphere, and of converging shadow rays."""
    o = np.zeros((n_tiles, k, 3))
    d = np.zeros((n_tiles, k, 3))
    for t in range(n_tiles):
        kind = t % 3
        base = rng.normal(size=3)
        base /= np.linalg.norm(base)
        jitter = rng.normal(scale=0.01, size=(k, 3))
        dirs = base + jitter
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        if kind == 0:  # one origin (a camera)
            o[t] = rng.normal(scale=50, size=3)
            d[t] = dirs
        elif kind == 1:  # reflections: origins on a sphere patch, directions mirrored
            c = rng.normal(scale=20, size=3)
            nrm = -base + rng.normal(scale=0.02, size=(k, 3))
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            o[t] = c + 3.0 * nrm
            d[t] = dirs - 2.0 * np.einsum("ij,ij->i", dirs, nrm)[:, None] * nrm
        else:  # shadow rays towards a light from a surface patch
            light = rng.normal(scale=40, size=3)
            o[t] = rng.normal(scale=2, size=3) + rng.normal(scale=0.3, size=(k, 3))
            v = light - o[t]
            d[t] = v / np.linalg.norm(v, axis=1, keepdims=True)
    return o, d


def test_python_cones_hold_every_ray():
    rng = np.random.default_rng(1)
    k = 64
    o, d = coherent_tiles(rng, 60, k)
    live = rng.random((60, k)) < 0.8
    live[5] = False  # an empty tile
    cones = hre_cones.build_cones(o, d, live)
    check_contained(o, d, live, cones)
    useful = cones[:, 3] >= 0
    assert useful.sum() >= 50, "coherent tiles should get useful cones"
    assert np.median(cones[useful, 3]) < 0.2, "coherent tiles should get narrow cones"
    # incoherent rays: either a cone that holds them, or an honest "no cull"
    o2 = rng.normal(scale=10, size=(20, k, 3))
    d2 = rng.normal(size=(20, k, 3))
    d2 /= np.linalg.norm(d2, axis=2, keepdims=True)
    cones2 = hre_cones.build_cones(o2, d2, np.ones((20, k), bool))
    check_contained(o2, d2, np.ones((20, k), bool), cones2)
    assert (cones2[:, 3] == hre_cones.NO_CULL).all()
    # parallel rays with different origins (a zero-angle cone must open before it moves)
    o3 = np.zeros((1, k, 3))
    o3[0, :, 0] = np.arange(k)
    d3 = np.tile([0.0, 0.0, -1.0], (1, k, 1))
    cones3 = hre_cones.build_cones(o3, d3, np.ones((1, k), bool))
    check_contained(o3, d3, np.ones((1, k), bool), cones3)


def test_python_cull_test_is_conservative():
    """No sphere that a ray of the tile hits is culled by the float64 test of the shader."""
    rng = np.random.default_rng(2)
    k = 64
    o, d = coherent_tiles(rng, 30, k)
    live = np.ones((30, k), bool)
    cones = hre_cones.build_cones(o, d, live)
    centers = rng.normal(scale=40, size=(400, 3))
    radii = rng.uniform(0.5, 6.0, 400)
    miss = hre_cones.cone_misses_sphere(cones, centers, radii)
    assert miss.any(), "some spheres should be culled"
    for t, s in zip(*np.nonzero(miss), strict=True):
        assert not any_hit(o[t], d[t], centers[s], radii[s]).any()
