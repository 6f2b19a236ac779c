"""Model files through trimesh (renderer.io.mesh_io): each format round-trips a small generated
model, in memory and from a path; bad files are refused naming the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from renderer.geometry.meshes import box, edge_report, icosphere, signed_volume, torus
from renderer.geometry.scene import Scene, SceneError
from renderer.io.mesh_io import (
    MODEL_FORMATS,
    export_mesh,
    fit_transform,
    load_mesh,
    mesh_json,
    model_scene,
    models_scene_json,
    write_scene_json,
)
from renderer.materials.pbr import PbrMaterial

# float32 in STL, PLY and GLB; OBJ's text keeps 8 significant digits
TOLERANCE = {"obj": 1e-7, "ply": 1e-6, "stl": 1e-6, "glb": 1e-6}


def corners_sorted(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Triangles as sets of corner positions, order- and start-independent (each triangle's
    corners rotated to start at its smallest, then the triangles sorted)."""
    c = v[t]
    key = np.round(c, 4)  # ordering by rounded values: float32 storage must not reorder
    rolled, keys = [], []
    for tri, kt in zip(c, key, strict=True):
        k = min(range(3), key=lambda i: tuple(kt[i]))
        rolled.append(np.roll(tri, -k, axis=0).ravel())
        keys.append(np.roll(kt, -k, axis=0).ravel())
    rolled, keys = np.array(rolled), np.array(keys)
    return rolled[np.lexsort(keys.T[::-1])]


@pytest.mark.parametrize("fmt", ["obj", "ply", "stl", "glb"])
@pytest.mark.parametrize("smooth", [True, False])
def test_each_format_round_trips_a_generated_model(fmt, smooth, tmp_path):
    model = torus(2.0, 0.5, 12, 6, center=(0.5, -1.0, 2.0), smooth=smooth)
    data = export_mesh(model, fmt)
    for source in (data, tmp_path / f"model.{fmt}"):
        if not isinstance(source, bytes):
            source.write_bytes(data)
        got = load_mesh(source, fmt if isinstance(source, bytes) else None)
        assert got.n_triangles == model.n_triangles and len(got.vertices) == len(model.vertices)
        np.testing.assert_allclose(
            corners_sorted(got.vertices, got.triangles),
            corners_sorted(model.vertices, model.triangles),
            atol=TOLERANCE[fmt] * 3,
        )
        # the winding (outward) survives: the same signed volume
        assert edge_report(got.triangles).closed
        assert (
            signed_volume(got.vertices, got.triangles)
            == pytest.approx(signed_volume(model.vertices, model.triangles), rel=1e-5)
            and signed_volume(model.vertices, model.triangles) > 5
        )
        if smooth and fmt != "stl":  # STL has no vertex normals
            assert got.normals is not None
            order = np.lexsort(np.round(got.vertices, 4).T[::-1])
            ref = np.lexsort(np.round(model.vertices, 4).T[::-1])
            np.testing.assert_allclose(got.normals[order], model.normals[ref], atol=1e-6)
        else:
            assert got.normals is None


def test_stl_corners_are_merged_into_shared_vertices():
    """STL stores every triangle's corners apart; equal positions become one vertex, so the
    mesh is indexed and closed (watertight for the tracer)."""
    model = icosphere(2)
    got = load_mesh(export_mesh(model, "stl"), "stl")
    assert len(got.vertices) == len(model.vertices) and edge_report(got.triangles).closed


def test_a_gltf_scene_of_several_meshes_becomes_one_mesh_placed_by_its_nodes():
    import trimesh

    a, b = box(), icosphere(1, radius=0.5)
    scene = trimesh.Scene()
    scene.add_geometry(
        trimesh.Trimesh(a.vertices, a.triangles, process=False),
        node_name="a",
        transform=trimesh.transformations.translation_matrix([10.0, 0.0, 0.0]),
    )
    scene.add_geometry(trimesh.Trimesh(b.vertices, b.triangles, process=False), node_name="b")
    got = load_mesh(scene.export(file_type="glb"), "glb")
    assert got.n_triangles == a.n_triangles + b.n_triangles
    assert got.vertices[:, 0].max() == pytest.approx(11.0) and got.vertices[:, 0].min() == pytest.approx(-0.5)


def test_polygons_are_split_and_degenerate_faces_kept():
    obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nf 1 2 3 4\nf 1 2 5\n"
    got = load_mesh(obj, "obj")
    assert got.n_triangles == 3
    mesh = got.to_mesh()
    assert mesh.n_degenerate == 1
    c = mesh.corners[~mesh.degenerate]
    assert (np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])[:, 2] > 0).all(), "counter-clockwise stays so"


@pytest.mark.parametrize(
    "data,fmt,field",
    [
        (b"not a model", "ply", "file"),
        (b"\x00" * 84, "stl", "file"),
        (b"glTF garbage", "glb", "file"),
        (b"v 0 0 0\n", "obj", "file"),  # no face
        (b"v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", "obj", "file"),
        (b"v 0 0 0\n", "dxf", "format"),
        (b"v 0 0 0\n", None, "format"),
    ],
)
def test_bad_files_are_refused_naming_the_field(data, fmt, field):
    with pytest.raises(SceneError) as e:
        load_mesh(data, fmt)
    assert e.value.field == field, str(e.value)


def test_a_gltf_cannot_read_other_files_when_given_as_bytes(tmp_path):
    secret = tmp_path / "buffer.bin"
    secret.write_bytes(np.zeros(9, np.float32).tobytes())
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": str(secret), "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    with pytest.raises(SceneError) as e:
        load_mesh(json.dumps(doc).encode(), "gltf")
    assert e.value.field == "file"


def test_caps_on_triangles_and_vertices():
    data = export_mesh(icosphere(2), "ply")
    with pytest.raises(SceneError, match="at most 100 allowed"):
        load_mesh(data, "ply", max_triangles=100)
    with pytest.raises(SceneError, match="vertices; at most 100 per mesh"):
        load_mesh(data, "ply", max_vertices=100)


def test_the_command_line_functions_make_a_scene_of_a_model(tmp_path):
    path = tmp_path / "ball.obj"
    path.write_bytes(export_mesh(icosphere(2, radius=3.0, center=(100.0, 50.0, 0.0)), "obj"))
    scene = model_scene(path, size=20.0)
    mesh = scene.meshes[0]
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    assert (hi - lo).max() == pytest.approx(20.0) and lo[1] == pytest.approx(-20.0)
    assert abs((lo + hi)[0] / 2) < 1e-9 and len(scene.planes) == 1 and mesh.smooth
    out = tmp_path / "scene.json"
    write_scene_json(scene, out)
    again = Scene.from_json(json.loads(out.read_text()))
    np.testing.assert_array_equal(again.triangle_corners, scene.triangle_corners)
    m = mesh_json(path, material=0, smooth=False)
    assert set(m) == {"vertices", "triangles", "material"} and len(m["triangles"]) == 320
    t = fit_transform(load_mesh(path), size=2.0, floor=None)
    assert t[3] == [0.0, 0.0, 0.0, 1.0]
    assert MODEL_FORMATS == ("obj", "ply", "stl", "glb", "gltf")


def textured_gltf_folder(folder: Path) -> Path:
    """A .gltf with its .bin and a PNG beside it: one triangle whose material reads the image."""
    from tests.renderer.gltf_files import Gltf, png, triangle

    g = Gltf()
    uv = g.accessor([[0, 0], [1, 0], [0, 1]])
    g.add("images", {"uri": "skin.png"})
    g.add("textures", {"source": 0})
    material = g.add("materials", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0}})
    g.add("nodes", {"mesh": g.mesh(triangle(g, TEXCOORD_0=uv) | {"material": material})})
    g.scene(0)
    folder.mkdir()
    (folder / "model.bin").write_bytes(bytes(g.binary))
    (folder / "skin.png").write_bytes(png(np.full((4, 2, 4), 200, np.uint8)))
    (folder / "model.gltf").write_bytes(g.gltf("model.bin"))
    return folder / "model.gltf"


def test_the_command_lines_scenes_keep_a_models_materials_and_textures(tmp_path):
    """render MODEL's scene and scene --mesh's JSON: the model's PbrMaterial after the floor's and
    the model's own, its texture, its UVs; a second model's indices follow the first's."""
    path = textured_gltf_folder(tmp_path / "a")
    scene = model_scene(path)
    assert scene.materials[2] == PbrMaterial(metallic=0.0, base_color_texture=0)
    assert len(scene.textures) == 1 and scene.meshes[0].material == 2 and scene.meshes[0].uvs is not None
    doc = models_scene_json([path, path])
    back = Scene.from_json(doc)
    assert [m.material for m in back.meshes] == [2, 3] and len(back.textures) == 2
    assert back.materials[3].base_color_texture == 1
