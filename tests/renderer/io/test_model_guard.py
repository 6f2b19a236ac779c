"""Malformed model files are refused from their declared numbers before a parser allocates
what they ask for (renderer/io/model_guard.py through renderer.io.mesh_io.load_mesh): each case is
generated here, each refusal is SceneError ``file`` saying what is wrong and the limit."""

from __future__ import annotations

import json
import resource
import struct
import time

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.meshes import icosphere
from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import export_mesh, load_mesh
from renderer.io.model_guard import check_model

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()


def gltf_doc(
    accessors: list[dict],
    nodes: list[dict] | None = None,
    roots: list[int] | None = None,
    buffer_len: int = 0,
    views: list[dict] | None = None,
) -> dict:
    nodes = [{"mesh": 0}] if nodes is None else nodes
    doc = {
        "asset": {"version": "2.0"},
        "bufferViews": views or [],
        "accessors": accessors,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": nodes,
        "scenes": [{"nodes": [0] if roots is None else roots}],
        "scene": 0,
    }
    if buffer_len:
        doc["buffers"] = [{"byteLength": buffer_len}]
    return doc


def glb(doc: dict, binary: bytes = b"") -> bytes:
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    b = binary + b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j + (struct.pack("<I4s", len(b), b"BIN\0") + b if b else b"")
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def triangle_glb(nodes: list[dict], roots: list[int]) -> bytes:
    view = [{"buffer": 0, "byteLength": 36}]
    acc = [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}]
    return glb(gltf_doc(acc, nodes, roots, 36, view), TRIANGLE)


def refused(data: bytes, fmt: str, **kw) -> str:
    with pytest.raises(SceneError) as e:
        load_mesh(data, fmt, **kw)
    assert e.value.field == "file", str(e.value)
    return e.value.message


def test_a_tiny_gltf_claiming_30_million_vertices_is_refused_without_allocating_them():
    """250 bytes whose accessor (no bufferView) claims 30,000,000 VEC3: before, trimesh made the
    arrays of zeros (2.3 GB of peak memory, 7.5 s) before it refused the model."""
    doc = gltf_doc([{"componentType": 5126, "count": 30_000_000, "type": "VEC3"}])
    data = json.dumps(doc).encode()
    assert len(data) < 300
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.process_time()  # CPU seconds: the machine's load does not stretch them
    msg = refused(data, "gltf")
    assert time.process_time() - t0 < 1.0
    assert "accessors[0].count = 30,000,000" in msg and f"{limits.MAX_ACCESSOR_COUNT:,}" in msg
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 50 * 1024  # KiB: no 360 MB array
    # within the count cap, zeros the file does not hold are bounded too
    doc = gltf_doc([{"componentType": 5126, "count": 3_000_000, "type": "VEC3"}])
    assert "MAX_BUFFERLESS_BYTES" in refused(json.dumps(doc).encode(), "gltf")


def test_gltf_accessors_and_views_beyond_the_bytes_that_exist_are_refused(monkeypatch):
    view = [{"buffer": 0, "byteLength": 36}]
    acc = [{"bufferView": 0, "componentType": 5126, "count": 1000, "type": "VEC3"}]
    msg = refused(glb(gltf_doc(acc, buffer_len=36, views=view), TRIANGLE), "glb")
    assert "accessors[0] needs 1,000 × 12 bytes" in msg and "bufferViews[0], which has 36" in msg
    long_view = [{"buffer": 0, "byteLength": 36_000}]
    msg = refused(glb(gltf_doc(acc, buffer_len=36, views=long_view), TRIANGLE), "glb")
    assert "bufferViews[0] spans bytes 0 … 36,000 of buffers[0], which has 36" in msg
    msg = refused(glb(gltf_doc(acc, buffer_len=12_000, views=long_view), TRIANGLE), "glb")
    assert "buffers[0] declares 12,000 bytes, the GLB's BIN chunk holds 36" in msg
    # accessors (and views) aliasing the same bytes: the parser copies each, so their sum is bounded
    monkeypatch.setattr(limits, "MAX_MODEL_ARRAY_BYTES", 100)
    many = [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}] * 3
    msg = refused(glb(gltf_doc(many, buffer_len=36, views=view), TRIANGLE), "glb")
    assert "accessors add up to 108 bytes of arrays; at most 100 allowed (MAX_MODEL_ARRAY_BYTES)" in msg
    msg = refused(glb(gltf_doc(many[:1], buffer_len=36, views=view * 3), TRIANGLE), "glb")
    assert "bufferViews add up to 108 bytes; at most 100 allowed (MAX_MODEL_ARRAY_BYTES)" in msg


def test_a_glb_chain_of_100000_nodes_is_refused_in_well_under_a_second():
    """A chain of nodes over one triangle: trimesh's cost grows with the square of its depth
    (25,000 nodes 6.4 s, 100,000 80 s before)."""
    n = 100_000
    data = triangle_glb([{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}], [0])
    t0 = time.process_time()  # CPU seconds: the machine's load does not stretch them
    msg = refused(data, "glb")
    assert time.process_time() - t0 < 1.0  # ~0.1 s here; trimesh's own walk: 80 s
    assert f"{n:,} nodes; at most {limits.MAX_MODEL_NODES:,}" in msg
    # within the node cap, the depth is bounded
    n = limits.MAX_MODEL_NODE_DEPTH + 1
    data = triangle_glb([{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}], [0])
    assert "deeper than 256 levels (MAX_MODEL_NODE_DEPTH)" in refused(data, "glb")
    # one level less is a model
    n = limits.MAX_MODEL_NODE_DEPTH
    data = triangle_glb([{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}], [0])
    assert load_mesh(data, "glb").n_triangles == 1


def test_a_node_graph_that_is_not_a_tree_is_refused():
    cycle = [{"children": [1]}, {"children": [2], "mesh": 0}, {"children": [1]}]
    assert "child of more than one node" in refused(triangle_glb(cycle, [0]), "glb")
    loop = [{"mesh": 0}, {"children": [2]}, {"children": [1]}]
    assert "cycle (through nodes[1])" in refused(triangle_glb(loop, [0]), "glb")
    own = [{"children": [0], "mesh": 0}]
    assert "of itself" in refused(triangle_glb(own, [0]), "glb")
    # a diamond (shared children) would multiply instances exponentially with depth
    assert "child of more than one node" in refused(
        triangle_glb([{"children": [1, 2]}, {"children": [3]}, {"children": [3]}, {"mesh": 0}], [0]), "glb"
    )
    assert "not an index" in refused(triangle_glb([{"children": [7], "mesh": 0}], [0]), "glb")


def test_instances_count_against_the_triangle_cap_before_parsing():
    flat = [{"mesh": 0}] * 200
    assert "200 triangles; at most 100 allowed" in refused(
        triangle_glb(flat, list(range(200))), "glb", max_triangles=100
    )
    assert load_mesh(triangle_glb(flat, list(range(200))), "glb").n_triangles == 200


def test_a_binary_stl_whose_count_disagrees_with_its_length_is_refused_saying_so():
    """Before: trimesh fell back to its text path (ModuleNotFoundError for charset_normalizer
    where the package did not install it, 'holds no triangle mesh' where it did)."""
    stl = export_mesh(icosphere(1), "stl")
    assert load_mesh(stl, "stl").n_triangles == 80
    bad = stl[:80] + struct.pack("<I", 81) + stl[84:]
    msg = refused(bad, "stl")
    assert "header says 81 triangles, which take 84 + 50 × 81 = 4,134 bytes; the file has 4,084" in msg
    huge = stl[:80] + struct.pack("<I", 4_000_000) + b"\0" * 50 * 4_000_000
    assert f"4,000,000 triangles; at most {limits.MAX_TRIANGLES:,}" in refused(huge, "stl")
    assert "84-byte header" in refused(b"\0" * 40, "stl")


def test_an_ascii_stl_is_counted_by_its_facets():
    facet = b"facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
    stl = b"solid t\n" + facet * 5 + b"endsolid t\n"
    assert load_mesh(stl, "stl").n_triangles == 5
    assert "5 triangles; at most 4" in refused(stl, "stl", max_triangles=4)


PLY_HEAD = (
    b"ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    b"element face %d\nproperty list uchar int vertex_indices\nend_header\n"
)


def test_a_ply_declaring_more_faces_than_it_holds_is_refused():
    """Before: an ASCII PLY declaring 1,000 faces with one present was accepted (while
    'element face 0' was refused)."""
    ascii_ok = PLY_HEAD % (b"ascii", 1) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    assert load_mesh(ascii_ok, "ply").n_triangles == 1
    msg = refused(PLY_HEAD % (b"ascii", 1000) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ply")
    assert "element vertex 3, element face 1,000 (1,003 rows); the file holds 4" in msg
    data = np.array([0, 0, 0, 1, 0, 0, 0, 1, 0], "<f4").tobytes() + b"\x03" + np.array([0, 1, 2], "<i4").tobytes()
    assert load_mesh(PLY_HEAD % (b"binary_little_endian", 1) + data, "ply").n_triangles == 1
    msg = refused(PLY_HEAD % (b"binary_little_endian", 1000) + data, "ply")
    assert "at least 1,036 bytes of data; the file holds 49" in msg
    # counts beyond the caps are refused from the header alone
    msg = refused((PLY_HEAD % (b"binary_little_endian", 1)).replace(b"vertex 3", b"vertex 300000000") + data, "ply")
    assert "300,000,000 vertices; at most" in msg
    assert "2,000,000 triangles" in refused(PLY_HEAD % (b"ascii", 2_000_000), "ply")
    assert "not a PLY property" in refused(PLY_HEAD.replace(b"float z", b"quaternion z") % (b"ascii", 1), "ply")


@pytest.mark.parametrize(
    "face,why",
    [
        (b"f 0 1 2", "vertex index 0 (OBJ counts from 1"),
        (b"f 1 2 4", "vertex 4 of the 3 the file has"),
        (b"f 1/1 2/1 0/1", "vertex index 0"),
        (b"f -1 -2 -4", "vertex -4 counts back past the 3 vertices defined before it"),
        (b"f 1 2 x", "not a whole number"),
    ],
)
def test_an_obj_face_with_index_0_or_out_of_range_is_refused(face, why):
    """Before: 'f 0 1 2' was accepted (trimesh read index 0 as the last vertex)."""
    msg = refused(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n" + face + b"\n", "obj")
    assert why in msg and face.decode() in msg


def test_obj_negative_indices_count_from_the_vertices_before_the_face():
    obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4 -3 -1\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 4\n"
    assert load_mesh(obj, "obj").n_triangles == 3
    assert "counts back past the 3" in refused(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -4\nv 0 0 1\n", "obj")
    assert "4 triangles; at most 3" in refused(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4 1 2\n", "obj", max_triangles=3
    )


def test_valid_files_of_every_format_pass_the_check():
    model = icosphere(2)
    for fmt in ("obj", "ply", "stl", "glb"):
        check_model(export_mesh(model, fmt), fmt)


def test_a_text_model_that_is_not_utf8_loads():
    """trimesh decodes such text with charset-normalizer: the package must install it
    (pyproject.toml's dependencies), else the file is refused with ModuleNotFoundError."""
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parents[3] / "pyproject.toml").read_text())["project"]
    assert any(d.replace("_", "-").lower().startswith("charset-normalizer") for d in project["dependencies"])
    obj = "# modèle éprouvé, café\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".encode("latin-1")
    assert load_mesh(obj, "obj").n_triangles == 1


@pytest.mark.parametrize(
    "doc",
    [
        {"accessors": [{"componentType": [5126], "count": 3, "type": "VEC3"}]},
        {"accessors": [{"componentType": 5126, "count": -3, "type": "VEC3"}]},
        {"buffers": [{"byteLength": 3, "uri": "data:x;base64,@@@"}]},
        {"nodes": [{"children": "0"}]},
        {"meshes": [{"primitives": [{"attributes": {"POSITION": 5}}]}]},
        {"scenes": [{"nodes": [0]}], "scene": 3},
        [1, 2, 3],
    ],
)
def test_malformed_gltf_structures_are_refused_as_the_file(doc):
    assert refused(json.dumps(doc).encode(), "gltf").startswith("GLTF: ")
    assert refused(b"[" * 100_000 + b"]" * 100_000, "gltf").startswith("GLTF: ")


def test_a_ply_header_line_without_a_keyword_is_read_as_a_comment():
    """Blender 2.4 wrote 'Created by Blender3D …' without 'comment' before it; trimesh reads such a
    file, and the check takes the line as the comment it is. A malformed element line still fails."""
    blender = PLY_HEAD.replace(b"format %s 1.0\n", b"format %s 1.0\nCreated by Blender3D 247 - www.blender.org\n")
    assert load_mesh(blender % (b"ascii", 1) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ply").n_triangles == 1
    assert "not a PLY header line" in refused(
        PLY_HEAD.replace(b"element face %d", b"element face") % (b"ascii",) + b"0 0 0\n1 0 0\n0 1 0\n", "ply"
    )


@pytest.mark.parametrize(
    "fmt, data",
    [
        ("gltf", json.dumps({"asset": {"version": "1.0"}, "buffers": {"b": {"uri": "b.bin"}}}).encode()),
        ("gltf", json.dumps({"buffers": {"b": {"uri": "b.bin", "byteLength": 4}}, "meshes": {}}).encode()),
        ("glb", struct.pack("<4sIIII", b"glTF", 1, 20, 0, 0)),
    ],
)
def test_gltf_1_is_refused_saying_so(fmt, data):
    assert "glTF 1.0 is not supported; convert to glTF 2.0" in refused(data, fmt)


def test_draco_compressed_geometry_is_refused_naming_the_extension():
    doc = gltf_doc([{"componentType": 5126, "count": 3, "type": "VEC3"}])
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    assert "KHR_draco_mesh_compression, which is not read" in refused(glb(doc), "glb")
