"""A model's folder as a zip, and its side files (renderer/io/model_archive.py through
renderer.io.mesh_io.load_mesh): the folders users send load, and every hostile archive is refused
from its central directory — before anything is inflated — with SceneError ``file`` naming the
entry and the bound. The archives are made here with ``zipfile``, their numbers patched where
an honest writer would not write them."""

from __future__ import annotations

import base64
import io
import json
import stat
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.meshes import box, icosphere
from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import export_mesh, load_mesh, model_files
from renderer.io.model_archive import open_archive

BOX_TRIANGLES = 12


def make_zip(files: dict[str, bytes], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", method) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def png_header(width: int, height: int) -> bytes:
    """A PNG's signature and IHDR chunk only: what a decoder reads before allocating its pixels."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))


def jpeg_header(width: int, height: int) -> bytes:
    """A JPEG's start, an APP0 segment and a baseline frame header (SOF0) declaring the size."""
    app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\0\x01\x01\0\0\x01\0\x01\0\0"
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    return b"\xff\xd8" + app0 + sof + b"\xff\xd9"


def box_gltf(uri: str, image_uri: str | None = None) -> tuple[bytes, bytes]:
    """A glTF of a box whose buffer is the side file ``uri`` (and an image ``image_uri``)."""
    b = box()
    v = np.asarray(b.vertices, np.float32)
    t = np.asarray(b.triangles, np.uint32)
    binary = v.tobytes() + t.tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": uri, "byteLength": len(binary)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": v.nbytes},
            {"buffer": 0, "byteOffset": v.nbytes, "byteLength": t.nbytes},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(v),
                "type": "VEC3",
                "min": v.min(0).tolist(),
                "max": v.max(0).tolist(),
            },
            {"bufferView": 1, "componentType": 5125, "count": t.size, "type": "SCALAR"},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    if image_uri is not None:
        doc["images"] = [{"uri": image_uri}]
    return json.dumps(doc).encode(), binary


def refused(data: bytes, fmt: str = "zip", **kw) -> str:
    with pytest.raises(SceneError) as e:
        load_mesh(data, fmt, **kw)
    assert e.value.field == "file"
    return e.value.message


# ---- folders as users zip them ------------------------------------------------------------------
def test_a_gltf_with_its_bin_and_image_in_a_subfolder_loads_from_the_zip():
    gltf, binary = box_gltf("buffers/box%20data.bin", "textures\\Logo.PNG")
    data = make_zip(
        {
            "Box/": b"",
            "Box/scene.gltf": gltf,
            "Box/buffers/box data.bin": binary,
            "Box/textures/logo.png": png_header(64, 64),  # the case differs from the reference
            "__MACOSX/Box/._scene.gltf": b"\0\x05\x16\x07 resource fork",  # macOS's copy: skipped
            "Box/.DS_Store": b"\0\0\0\1Bud1",
        }
    )
    m = load_mesh(data, "zip")
    assert m.n_triangles == BOX_TRIANGLES
    assert m.images == ("Box/textures/logo.png",)  # kept by name for the materials, not decoded
    files = model_files(data, "zip")
    assert (files.name, files.format) == ("scene.gltf", "gltf")
    assert files.side.get("textures\\Logo.PNG") == png_header(64, 64)
    assert files.side.read(m.images[0]) == png_header(64, 64)


def test_an_obj_with_its_mtl_and_a_reference_to_a_sibling_folder_inside_the_zip():
    obj = b"mtllib ../materials/box.mtl\n" + export_mesh(box(), "obj")
    data = make_zip({"model/box.obj": obj, "materials/box.mtl": b"newmtl clay\nKd 0.8 0.8 0.8\n"})
    assert load_mesh(data, "zip").n_triangles == BOX_TRIANGLES
    assert model_files(data, "zip").side.get("../materials/box.mtl").startswith(b"newmtl")


@pytest.mark.parametrize("fmt", ["ply", "stl", "glb"])
def test_every_model_format_loads_from_a_zip(fmt):
    data = make_zip({f"ball.{fmt}": export_mesh(icosphere(1), fmt), "readme.txt": b"made by hand"})
    assert load_mesh(data, "zip").n_triangles == 80


def test_a_path_reads_side_files_from_its_folder_and_a_zip_path_works(tmp_path: Path):
    gltf, binary = box_gltf("box.bin")
    (tmp_path / "box.gltf").write_bytes(gltf)
    (tmp_path / "box.bin").write_bytes(binary)
    assert load_mesh(tmp_path / "box.gltf").n_triangles == BOX_TRIANGLES
    (tmp_path / "box.zip").write_bytes(make_zip({"box.gltf": gltf, "box.bin": binary}))
    assert load_mesh(tmp_path / "box.zip").n_triangles == BOX_TRIANGLES


def test_a_gltf_sent_alone_names_its_side_file_and_the_zip():
    gltf, _ = box_gltf("box.bin")
    message = refused(gltf, "gltf")
    assert "'box.bin'" in message and "format=zip" in message


def test_a_missing_side_file_in_the_zip_is_named():
    gltf, _ = box_gltf("box.bin")
    message = refused(make_zip({"box.gltf": gltf}))
    assert "buffers[0]" in message and "'box.bin'" in message


def test_a_reference_outside_the_archive_is_refused():
    gltf, binary = box_gltf("../../etc/box.bin")
    message = refused(make_zip({"m/box.gltf": gltf, "box.bin": binary}))
    assert "outside the model's folder" in message


def test_a_reference_outside_the_folder_of_a_path_reads_nothing(tmp_path: Path):
    gltf, binary = box_gltf("../secret.bin")
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "box.gltf").write_bytes(gltf)
    (tmp_path / "secret.bin").write_bytes(binary)
    with pytest.raises(SceneError, match="outside the model's folder"):
        load_mesh(tmp_path / "m" / "box.gltf")


# ---- hostile archives ---------------------------------------------------------------------------
def _patch_declared_size(data: bytes, name: bytes, size: int) -> bytes:
    """The zip with ``name``'s uncompressed size set to ``size`` in its local header and its
    central-directory entry (what a bomb declares, or hides)."""
    out = bytearray(data)
    at = 0
    while (at := out.find(b"PK\x03\x04", at)) >= 0:
        n = struct.unpack_from("<H", out, at + 26)[0]
        if bytes(out[at + 30 : at + 30 + n]) == name:
            struct.pack_into("<I", out, at + 22, size)
        at += 4
    at = 0
    while (at := out.find(b"PK\x01\x02", at)) >= 0:
        n = struct.unpack_from("<H", out, at + 28)[0]
        if bytes(out[at + 46 : at + 46 + n]) == name:
            struct.pack_into("<I", out, at + 24, size)
        at += 4
    return bytes(out)


def test_a_ratio_bomb_is_refused_before_inflating():
    data = make_zip({"bomb.obj": b"\0" * (4 << 20)})  # 4 MiB of zeros in ~4 KB
    assert len(data) < 10_000
    message = refused(data)
    assert "'bomb.obj'" in message and "MAX_ARCHIVE_RATIO" in message and "zip bomb" in message


def test_an_entry_declaring_more_than_the_entry_bound_is_refused():
    data = _patch_declared_size(make_zip({"big.obj": export_mesh(box(), "obj")}), b"big.obj", 1 << 31)
    message = refused(data)
    assert "'big.obj'" in message and "MAX_ARCHIVE_ENTRY_BYTES" in message


def test_the_entries_together_are_bounded(monkeypatch):
    monkeypatch.setattr(limits, "MAX_ARCHIVE_BYTES", 10_000)
    data = make_zip({"box.obj": export_mesh(box(), "obj"), "a.png": bytes(6000), "b.png": bytes(6000)})
    assert "MAX_ARCHIVE_BYTES" in refused(data)


def test_an_entry_hiding_its_size_inflates_no_further_than_it_declares():
    data = _patch_declared_size(make_zip({"box.obj": export_mesh(icosphere(3), "obj")}), b"box.obj", 100)
    message = refused(data)
    assert "'box.obj'" in message


@pytest.mark.parametrize(
    "name, why",
    [
        ("/etc/box.obj", "absolute name"),
        ("C:\\models\\box.obj", "absolute name"),
        ("../box.obj", "parent folder"),
        ("models\\..\\..\\box.obj", "parent folder"),
    ],
)
def test_unsafe_names_are_refused(name, why):
    message = refused(make_zip({name: export_mesh(box(), "obj")}))
    assert why in message and repr(name) in message


def test_a_symbolic_link_is_refused():
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("box.obj", export_mesh(box(), "obj"))
        link = zipfile.ZipInfo("box.bin")
        link.create_system = 3
        link.external_attr = (stat.S_IFLNK | 0o777) << 16
        z.writestr(link, "/etc/passwd")
    assert "symbolic link" in refused(out.getvalue())


def test_too_many_entries_are_refused_from_the_end_record():
    files = {f"t/{i}.txt": b"" for i in range(limits.MAX_ARCHIVE_ENTRIES + 1)}
    files["box.obj"] = export_mesh(box(), "obj")
    message = refused(make_zip(files, zipfile.ZIP_STORED))
    assert f"{limits.MAX_ARCHIVE_ENTRIES + 2:,} entries" in message and "MAX_ARCHIVE_ENTRIES" in message


def test_an_end_record_that_understates_the_entries_is_not_believed(monkeypatch):
    """zipfile reads the central directory by its size, making an object per header: a count of 1
    in the end record must not let 2,000 headers be parsed — refused before zipfile opens it."""
    files = {f"{i}.txt": b"" for i in range(2000)}
    files["box.obj"] = export_mesh(box(), "obj")
    data = bytearray(make_zip(files, zipfile.ZIP_STORED))
    end = data.rfind(b"PK\x05\x06")
    struct.pack_into("<HH", data, end + 8, 1, 1)

    def parsed(*args, **kwargs):
        raise AssertionError("the central directory was parsed")

    monkeypatch.setattr(zipfile, "ZipFile", parsed)
    assert "2,001 entries" in refused(bytes(data))


@pytest.mark.parametrize("inner_name", ["more.zip", "more.bin"])
def test_an_archive_inside_the_archive_is_refused(inner_name):
    inner = make_zip({"box.obj": export_mesh(box(), "obj")})
    message = refused(make_zip({"box.obj": export_mesh(box(), "obj"), inner_name: inner}))
    assert "archive inside the archive" in message and inner_name in message


def test_an_encrypted_entry_and_another_compression_method_are_refused():
    data = bytearray(make_zip({"box.obj": export_mesh(box(), "obj")}))
    central = data.find(b"PK\x01\x02")
    struct.pack_into("<H", data, central + 8, 1)  # general purpose flag: encrypted
    assert "encrypted" in refused(bytes(data))
    assert "compression method 12" in refused(make_zip({"box.obj": export_mesh(box(), "obj")}, zipfile.ZIP_BZIP2))


def test_no_model_or_several_models_are_refused_naming_them():
    assert "no model file" in refused(make_zip({"readme.txt": b"hello"}))
    message = refused(make_zip({"a.obj": export_mesh(box(), "obj"), "b.stl": export_mesh(box(), "stl")}))
    assert "2 model files" in message and "'a.obj'" in message and "'b.stl'" in message


def test_not_a_zip_is_refused():
    assert "not a zip archive" in refused(b"PK\x03\x04 but nothing else")
    with pytest.raises(SceneError, match="not a zip"):
        open_archive(export_mesh(box(), "obj"))


# ---- images inside models: declared pixels checked before decoding ------------------------------
@pytest.mark.parametrize("header", [png_header(100_000, 100_000), jpeg_header(60_000, 60_000)])
def test_an_image_bomb_in_the_zip_is_refused_from_its_header(header):
    message = refused(make_zip({"box.obj": export_mesh(box(), "obj"), "textures/skin.dat": header}))
    assert "'textures/skin.dat'" in message and "MAX_MODEL_IMAGE_SIDE" in message


def test_an_image_within_the_bounds_passes():
    side = limits.MAX_MODEL_IMAGE_SIDE
    data = make_zip({"box.obj": export_mesh(box(), "obj"), "a.png": png_header(side, side), "b.jpg": jpeg_header(8, 8)})
    assert load_mesh(data, "zip").images == ("a.png", "b.jpg")


def test_an_image_bomb_embedded_in_a_glb_or_a_data_uri_is_refused():
    import trimesh

    bomb = png_header(9000, 9000)
    scene = trimesh.Scene(trimesh.Trimesh(np.asarray(box().vertices), np.asarray(box().triangles), process=False))
    doc_bytes = scene.export(file_type="glb")
    # the GLB with the image appended to its BIN chunk and named by an images[] entry
    json_len = struct.unpack_from("<I", doc_bytes, 12)[0]
    doc = json.loads(doc_bytes[20 : 20 + json_len])
    bin_at = 20 + json_len
    bin_len = struct.unpack_from("<I", doc_bytes, bin_at)[0]
    binary = doc_bytes[bin_at + 8 : bin_at + 8 + bin_len] + bomb
    binary += b"\0" * (-len(binary) % 4)
    doc["buffers"][0]["byteLength"] = len(binary)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": bin_len, "byteLength": len(bomb)})
    doc["images"] = [{"bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png"}]
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    glb = struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body
    assert "images[0]" in refused(glb, "glb") and "9,000 × 9,000" in refused(glb, "glb")
    gltf, binary = box_gltf("data:application/octet-stream;base64,", None)
    doc = json.loads(gltf)
    doc["buffers"][0]["uri"] += base64.b64encode(binary).decode()
    doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(bomb).decode()}]
    assert "images[0]" in refused(json.dumps(doc).encode(), "gltf")
