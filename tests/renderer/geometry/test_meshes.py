"""Procedural meshes (renderer.geometry.meshes) and the teapot's data (renderer.geometry.teapot_data): closed,
wound outwards, the sizes and shapes they claim."""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer.geometry.meshes import (
    box,
    edge_report,
    icosphere,
    orient_outward,
    procedural,
    signed_volume,
    teapot,
    teapot_surface,
    torus,
    vertex_normals,
    weld,
)
from renderer.geometry.scene import SceneError


@pytest.mark.parametrize(
    "make,volume,rel",
    [
        (lambda: icosphere(4, radius=2.0), 4 / 3 * math.pi * 8, 3e-3),
        (lambda: torus(3.0, 1.0, 96, 48), 2 * math.pi**2 * 3.0 * 1.0, 5e-3),
        (lambda: box((-1, -2, -3), (1, 2, 3)), 2 * 4 * 6, 1e-15),
    ],
)
def test_closed_generators_are_closed_outward_and_have_their_volume(make, volume, rel):
    m = make()
    assert edge_report(m.triangles).closed
    assert signed_volume(m.vertices, m.triangles) == pytest.approx(volume, rel=rel)
    assert m.n_degenerate == 0


def test_icosphere_vertices_lie_on_the_sphere_and_counts_follow_the_subdivision():
    for s in range(4):
        m = icosphere(s, radius=3.0, center=(1.0, 2.0, 3.0))
        assert m.n_triangles == 20 * 4**s and len(m.vertices) == 10 * 4**s + 2
        np.testing.assert_allclose(np.linalg.norm(m.vertices - (1, 2, 3), axis=1), 3.0, rtol=1e-15)
        np.testing.assert_allclose(m.normals, (m.vertices - (1, 2, 3)) / 3.0, atol=1e-15)


def test_a_room_is_wound_inwards():
    room = box((-5, -5, -5), (5, 5, 5), inward=True)
    assert edge_report(room.triangles).closed and signed_volume(room.vertices, room.triangles) == -1000.0
    assert room.normals is None


def test_the_closed_teapot_is_three_watertight_pieces_and_the_open_one_is_newells_surface():
    v, t = teapot_surface(6, closed=True)
    report = edge_report(t)
    assert report.closed, report
    # three edge-connected pieces (pot, handle, spout), each of positive volume
    oriented = orient_outward(v, t)
    np.testing.assert_array_equal(oriented, t)  # already consistent and outward
    vo, to = teapot_surface(6, closed=False)
    open_report = edge_report(to)
    # the open surface: the gap ring's two loops (4 patches × 6 segments each) and the four
    # open tube ends (2 patches × 6 each)
    assert open_report.boundary == 2 * 24 + 4 * 12 and open_report.non_manifold == 0
    assert len(to) == len(t) - 2 * 24 - 4 * 12
    # y up, standing on y = 0, height 3.15, spout towards +x
    assert v[:, 1].min() == 0.0 and v[:, 1].max() == pytest.approx(3.15)
    assert v[:, 0].max() > 3.0 and v[:, 0].min() == pytest.approx(-3.0)
    # the pot's volume: between a cylinder of the body's smallest and largest radius
    assert math.pi * 1.4**2 * 2.4 < signed_volume(v, t) < math.pi * 2.0**2 * 3.15


def test_teapot_mesh_size_normals_and_transform():
    m = teapot(4, size=2.0, transform=[[1, 0, 0, 0], [0, 1, 0, -20], [0, 0, 1, 0], [0, 0, 0, 1]])
    assert m.vertices[:, 1].min() == -20.0 and m.vertices[:, 1].max() == pytest.approx(-20 + 6.3)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-12)
    flat = teapot(4, smooth=False)
    assert flat.normals is None and flat.n_triangles == m.n_triangles


def test_weld_merges_exact_duplicates_only_and_drops_collapsed_triangles():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-0.0, 0, 0], [1, 0, 1e-300], [5, 5, 5]])
    t = np.array([[0, 1, 2], [3, 4, 2], [0, 3, 1]])
    wv, wt = weld(v, t)
    # −0.0 = 0.0 is merged, 1e-300 apart is not; [0, 3, 1] collapses; (5, 5, 5) is unused
    assert len(wv) == 4 and len(wt) == 2
    np.testing.assert_array_equal(wv[wt[0]], v[[0, 1, 2]])
    np.testing.assert_array_equal(wv[wt[1]], v[[0, 4, 2]])


def test_vertex_normals_are_area_weighted_unit_vectors():
    m = box()
    n = vertex_normals(m.vertices, m.triangles)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    corner = np.flatnonzero((m.vertices == (1, 1, 1)).all(axis=1))[0]
    assert (n[corner] > 0).all()


def test_bad_parameters_name_the_field():
    for call, field in (
        (lambda: icosphere(99), "subdivisions"),
        (lambda: icosphere(1, radius=0), "radius"),
        (lambda: torus(1.0, 2.0), "minor"),
        (lambda: teapot(0), "segments"),
        (lambda: box((0, 0, 0), (1, 0, 1)), "hi"),
        (lambda: procedural("cow"), "kind"),
    ):
        with pytest.raises(SceneError) as e:
            call()
        assert e.value.field == field


# ---- texture coordinates and tangents --------------------------------------------------------
UV_MESHES = {
    "icosphere": lambda uvs: icosphere(3, radius=2.0, center=(1.0, 0.0, -1.0), uvs=uvs),
    "torus": lambda uvs: torus(3.0, 1.0, 24, 12, uvs=uvs),
    "box": lambda uvs: box((-1, -2, -3), (1, 2, 3), uvs=uvs),
    "room": lambda uvs: box((-1, -2, -3), (1, 2, 3), inward=True, uvs=uvs),
}


def _uv_derivatives(m) -> tuple[np.ndarray, np.ndarray]:
    """∂P/∂u and ∂P/∂v of each triangle, solved from its corners and UVs (written here)."""
    c, uv = m.corners, m.uvs[m.triangles]
    e1, e2, d1, d2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])[:, None]
    assert np.all(np.abs(det) > 1e-9), "a triangle with no UV area"
    return (e1 * d2[:, 1:] - e2 * d1[:, 1:]) / det, (e2 * d1[:, :1] - e1 * d2[:, :1]) / det


@pytest.mark.parametrize("kind", list(UV_MESHES))
def test_uvs_run_with_the_surface_and_keep_it_closed_by_position(kind):
    plain, m = UV_MESHES[kind](False), UV_MESHES[kind](True)
    assert plain.uvs is None and plain.tangents is None
    assert m.uvs is not None and m.tangents is not None
    # the same surface: same triangle count and volume; closed once equal positions are merged
    assert m.n_triangles == plain.n_triangles and m.n_degenerate == 0
    assert signed_volume(m.vertices, m.triangles) == pytest.approx(signed_volume(plain.vertices, plain.triangles))
    assert edge_report(weld(m.vertices, m.triangles)[1]).closed == edge_report(plain.triangles).closed
    uv = m.uvs[m.triangles]
    assert m.uvs.min() >= 0.0 and m.uvs.max() <= 1.5
    assert (uv.max(axis=1) - uv.min(axis=1)).max() <= 1.0  # no triangle spans the seam backwards
    # tangents: unit, along +U, the bitangent w·(n × t) up the image (towards −V)
    t, w = m.tangents[:, :3], m.tangents[:, 3]
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-12)
    du, dv = _uv_derivatives(m)
    c = m.corners
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    tt, ww = t[m.triangles[:, 0]], w[m.triangles[:, 0]]
    assert np.all(np.einsum("ij,ij->i", tt, du) > 0)
    assert np.all(np.einsum("ij,ij->i", np.cross(n, tt) * ww[:, None], -dv) > 0)


def test_the_sphere_is_mapped_by_longitude_and_latitude_and_the_box_face_by_face():
    m = icosphere(2, radius=1.0, uvs=True)
    front = int(np.argmax(m.vertices[:, 2]))  # (0, 0, 1): longitude 0 is the image's middle
    north = int(np.argmax(m.vertices[:, 1]))
    assert m.uvs[front].tolist() == pytest.approx([0.5, 0.5]) and m.uvs[north][1] == pytest.approx(0.0)
    b = box((0, 0, 0), (2, 1, 3), uvs=True)
    # the top face's triangles: every corner at y = 1; their vertices are that face's four
    top = np.unique(b.triangles[np.all(b.vertices[b.triangles][:, :, 1] == 1.0, axis=1)])
    assert len(top) == 4
    # on the top face U runs with +x and the image's top is the far side (−z)
    uv = {tuple(b.vertices[i][[0, 2]].tolist()): b.uvs[i].tolist() for i in top}
    assert uv == {(0.0, 0.0): [0.0, 0.0], (2.0, 0.0): [1.0, 0.0], (0.0, 3.0): [0.0, 1.0], (2.0, 3.0): [1.0, 1.0]}
