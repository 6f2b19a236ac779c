"""The quads and tile lists of rasterised first hits (renderer/frame/first_hits.py), on the CPU: every
pixel whose float64 primary ray meets a sphere lies in that sphere's quad and in a tile listing it,
the lists are ordered by near bound then id, and the near bounds lie below every hit."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.frame import first_hits as fh
from renderer.geometry.scene import Camera, Material, Scene
from renderer.gpu import gpu_layout
from renderer.oracle.reference import primary_rays
from renderer.scenes.scenarios import scenario

W, H = 64, 48
MASK = np.uint32(gpu_layout.SPHERE_ID_MASK)


def hits(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Per ray (row-major, row 0 at the top) and sphere: whether the float64 ray meets it, and t."""
    o, d = primary_rays(scene.camera, W, H)
    c, r = scene.sphere_centers, scene.sphere_radii
    oc = o[:, None, :] - c[None]
    b = np.einsum("ijk,ik->ij", oc, d)
    f = oc - b[..., None] * d[:, None, :]
    h2 = r[None] ** 2 - np.einsum("ijk,ijk->ij", f, f)
    h = np.sqrt(np.maximum(h2, 0.0))
    t = np.where(-b - h > 0, -b - h, -b + h)
    return (h2 >= 0) & (t > 0), t


SCENES = {
    "scenario 2": lambda: scenario(2, 64),
    "around the camera": lambda: Scene(
        Camera((0, 0, 10), (0, 0, 0), (0, 1, 0), 50.0),
        (),
        (Material(),),
        np.array([[0, 0, 10.0], [3, 0, 10.5], [0, 0, -30], [0, 0, 30]]),
        np.array([2.0, 1.0, 1.0, 1.0]),
        np.zeros(4, np.int32),
    ),
}


def window_of(rect: np.ndarray) -> np.ndarray:
    """A quad's rectangle in window coordinates (x0, y0, x1, y1)."""
    return (rect + 1.0) / 2.0 * np.array([W, H, W, H])


@pytest.mark.parametrize("name", list(SCENES))
def test_every_hit_lies_in_its_spheres_quad_and_tile(name):
    scene = SCENES[name]()
    meet, t = hits(scene)
    quads = fh.instances(scene, (W, H), (W, H))
    ids = quads["key"] & MASK
    assert list(ids) == sorted(ids, reverse=True), "descending ids: the lower id is drawn last"
    tiles, entries = fh.tile_lists(scene, (W, H), (W, H))
    listed = entries.reshape(-1, fh.ENTRY_TEXELS, 4)
    for ray, sphere in zip(*np.nonzero(meet), strict=True):
        x, row = ray % W, ray // W
        fx, fy = x + 0.5, H - row - 0.5  # the fragment's centre (GL rows from the bottom)
        q = np.flatnonzero(ids == sphere)
        assert len(q) == 1, f"sphere {sphere} met by ray {ray} has no quad"
        x0, y0, x1, y1 = window_of(quads["rect"][q[0]])
        assert x0 <= fx < x1 and y0 <= fy < y1
        inside = [
            i
            for i, rect in enumerate(tiles["rect"])
            if window_of(rect)[0] <= fx < window_of(rect)[2] and window_of(rect)[1] <= fy < window_of(rect)[3]
        ]
        assert len(inside) == 1
        first, count = tiles["list"][inside[0]]
        members = listed[first : first + count, 1, 0] & MASK
        assert sphere in members
        near = listed[first : first + count, 1, 1].view(np.float32)
        assert near[list(members).index(sphere)] <= t[ray, sphere]


@pytest.mark.parametrize("name", list(SCENES))
def test_lists_run_by_near_bound_then_id(name):
    tiles, entries = fh.tile_lists(SCENES[name](), (W, H), (W, H))
    listed = entries.reshape(-1, fh.ENTRY_TEXELS, 4)
    for first, count in tiles["list"]:
        near = listed[first : first + count, 1, 1].view(np.float32)
        ids = listed[first : first + count, 1, 0] & MASK
        keys = list(zip(near.tolist(), ids.tolist(), strict=True))
        assert keys == sorted(keys)


def test_a_sphere_behind_the_camera_has_no_quad_and_one_around_it_covers_everything():
    scene = SCENES["around the camera"]()
    quads = fh.instances(scene, (W, H), (W, H))
    ids = set((quads["key"] & MASK).tolist())
    assert 3 not in ids  # behind
    whole = quads["rect"][list(quads["key"] & MASK).index(0)]
    assert np.allclose(whole, [-1, -1, 1, 1])
