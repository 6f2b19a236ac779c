"""PLY files with their vertex colours and texture coordinates (renderer.io.ply_model): uchar and
float colours, alpha, s/t and u/v, ascii and binary, the lenient header; then assimp's corpus."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import model_files
from renderer.io.model_archive import ModelFiles
from renderer.io.ply_model import load_ply_model

CORPUS = Path("/usr/share/assimp/models/PLY")
BIG = {"max_triangles": limits.MAX_TRIANGLES, "max_vertices": limits.MAX_MESH_VERTICES}


def srgb(c: float) -> float:
    """IEC 61966-2-1's decoding, written out here so the expected values are not the module's."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def load(data: bytes, **bounds: int):
    return load_ply_model(ModelFiles("m.ply", "ply", data), **{**BIG, **bounds})


def ascii_ply(properties: str, rows: list[str], faces: list[str], header_extra: str = "") -> bytes:
    head = (
        f"ply\nformat ascii 1.0\n{header_extra}element vertex {len(rows)}\n{properties}"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    return (head + "\n".join(rows + faces) + "\n").encode()


XYZ = "property float x\nproperty float y\nproperty float z\n"


def test_uchar_colours_are_srgb_decoded_and_alpha_kept():
    props = XYZ + "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
    m = load(ascii_ply(props, ["0 0 0 255 128 0 255", "1 0 0 0 0 255 51", "0 1 0 10 10 10 0"], ["3 0 1 2"]))
    (part,) = m.parts
    assert part.material == -1 and m.materials == ()
    np.testing.assert_allclose(
        part.attributes["colors"],
        [
            [1.0, srgb(128 / 255), 0.0, 1.0],
            [0.0, 0.0, 1.0, 0.2],
            [srgb(10 / 255)] * 3 + [0.0],
        ],
    )


def test_float_colours_clamped_and_s_t_flipped_to_v_down():
    props = XYZ + "property float red\nproperty float green\nproperty float blue\nproperty float s\nproperty float t\n"
    m = load(ascii_ply(props, ["0 0 0 1.5 0.5 -1 0 0", "1 0 0 0 0 1 1 0.25", "0 1 0 0 0 0 0.5 1"], ["3 0 1 2"]))
    (part,) = m.parts
    np.testing.assert_allclose(part.attributes["colors"][0], [1.0, srgb(0.5), 0.0, 1.0])
    np.testing.assert_allclose(part.attributes["uvs"], [[0, 1], [1, 0.75], [0.5, 0]])


def test_binary_colours_and_u_v_and_quads():
    head = (
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        b"property float x\nproperty float y\nproperty float z\n"
        b"property uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\n"
        b"property float u\nproperty float v\n"
        b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = [
        (0, 0, 0, 255, 0, 0, 0, 0),
        (1, 0, 0, 0, 255, 0, 1, 0),
        (1, 1, 0, 0, 0, 255, 1, 1),
        (0, 1, 0, 0, 0, 0, 0, 1),
    ]
    body = b"".join(struct.pack("<fffBBBff", *r) for r in rows) + struct.pack("<Biiii", 4, 0, 1, 2, 3)
    (part,) = load(head + body).parts
    assert part.n_triangles == 2
    np.testing.assert_allclose(part.attributes["colors"][:, :3], [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]])
    np.testing.assert_allclose(part.attributes["uvs"], [[0, 1], [1, 1], [1, 0], [0, 0]])


def test_blenders_header_line_without_keyword_is_read():
    m = load(ascii_ply(XYZ, ["0 0 0", "1 0 0", "0 1 0"], ["3 0 1 2"], "Created by Blender3D 247\n"))
    assert m.n_triangles == 1 and m.parts[0].attributes == {}


def test_bounds_and_a_file_without_faces():
    data = ascii_ply(XYZ, ["0 0 0", "1 0 0", "0 1 0", "1 1 0"], ["3 0 1 2", "3 1 3 2"])
    with pytest.raises(SceneError, match="at most 1 allowed"):
        load(data, max_triangles=1)
    with pytest.raises(SceneError, match="holds no triangle"):
        load(ascii_ply(XYZ, ["0 0 0"], []))


def test_the_corpus_colours_and_uvs():
    float_color = load_ply_model(model_files(CORPUS / "float-color.ply"), **BIG)  # red 0 green 0 blue 1 alpha 1
    np.testing.assert_allclose(float_color.parts[0].attributes["colors"], np.tile([0.0, 0.0, 1.0, 1.0], (3, 1)))
    cube_uv = load_ply_model(model_files(CORPUS / "cube_uv.ply"), **BIG)
    (part,) = cube_uv.parts
    assert part.n_triangles == 12 and part.normals is not None
    uvs = part.attributes["uvs"]
    first_st = [float(x) for x in (CORPUS / "cube_uv.ply").read_text().split("end_header")[1].split()[6:8]]
    np.testing.assert_allclose(uvs[0], [first_st[0], 1.0 - first_st[1]], atol=1e-7)
    wuson = load_ply_model(model_files(CORPUS / "Wuson.ply"), **BIG)  # Blender 2.4's header, s and t
    assert wuson.n_triangles == 3732 and wuson.parts[0].attributes["uvs"].shape == (11184, 2)
