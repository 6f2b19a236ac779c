"""Every glTF, GLB, OBJ, PLY and STL file of assimp's own test corpus (Debian's
``assimp-testmodels``, installed by scripts/bootstrap.sh) through the guarded loader the service
uses (renderer.io.mesh_io.load_mesh, side files from each model's folder): each is answered — a mesh
with finite bounds, or SceneError ``file``/``format`` naming the problem — and never with another
exception, and none takes longer than the service's parse deadline in CPU seconds (a hang guard,
the service would refuse it). Nothing is skipped: a missing corpus fails the test."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import load_mesh, load_model
from renderer.io.model_guard import GLTF1
from renderer.materials.pbr import PbrMaterial
from server.config import ServerConfig

CORPUS = Path("/usr/share/assimp/models")
SUFFIXES = (".gltf", ".glb", ".obj", ".ply", ".stl")
FILES = sorted(str(p.relative_to(CORPUS)) for p in CORPUS.rglob("*") if p.suffix.lower() in SUFFIXES)
DEADLINE_S = float(ServerConfig.model_fields["model_timeout_s"].default)  # the service's parse deadline, s


def answer(rel: str) -> tuple[str, object, float]:
    """("mesh", MeshData) or ("refused", SceneError), and the CPU seconds it took."""
    start = time.process_time()
    try:
        out: tuple[str, object] = ("mesh", load_mesh(CORPUS / rel))
    except SceneError as e:
        out = ("refused", e)
    return out[0], out[1], time.process_time() - start


def test_the_corpus_is_installed():
    assert len(FILES) > 90, f"{CORPUS}: install Debian's assimp-testmodels (scripts/bootstrap.sh does)"


@pytest.mark.parametrize("rel", FILES)
def test_every_corpus_file_is_answered(rel):
    kind, out, cpu_s = answer(rel)
    assert cpu_s < DEADLINE_S, f"{rel}: {cpu_s:.1f} CPU s, past the service's {DEADLINE_S:g} s"
    if kind == "mesh":
        assert out.n_triangles > 0
        lo, hi = out.bounds()
        assert np.isfinite(lo).all() and np.isfinite(hi).all()
    else:
        assert out.field in ("file", "format") and len(out.message) > 20, out


@pytest.mark.parametrize("variant", ["glTF", "glTF-Binary", "glTF-Embedded"])
def test_the_sample_variants_load(variant):
    """The same textured box as a .gltf with its .bin and image beside it, a GLB with the image
    inside, and a .gltf of data URIs."""
    name = "BoxTextured.glb" if variant == "glTF-Binary" else "BoxTextured.gltf"
    m = load_mesh(CORPUS / "glTF2" / f"BoxTextured-{variant}" / name)
    assert m.n_triangles == 12
    assert ("CesiumLogoFlat.png" in m.images) == (variant == "glTF")


def test_gltf_1_and_blenders_ply_are_answered_as_such():
    for rel in ("glTF/TwoBoxes/TwoBoxes.gltf", "glTF/BoxTextured-glTF-Binary/BoxTextured.glb"):
        kind, out, _ = answer(rel)
        assert kind == "refused" and GLTF1 in out.message
    assert load_mesh(CORPUS / "PLY" / "Wuson.ply").n_triangles > 0
    kind, out, _ = answer("glTF2/draco/2CylinderEngine.gltf")
    assert kind == "refused" and "KHR_draco_mesh_compression" in out.message


def model(rel: str):
    return load_model(CORPUS / rel)


@pytest.mark.parametrize("variant", ["glTF", "glTF-Binary", "glTF-Embedded"])
def test_the_textured_box_arrives_with_its_texture(variant):
    """BoxTextured in its three forms: one PbrMaterial whose base colour is the 211 × 211 Cesium
    logo (sRGB, as the image beside it holds it), a dielectric (metallicFactor 0)."""
    from PIL import Image

    name = "BoxTextured.glb" if variant == "glTF-Binary" else "BoxTextured.gltf"
    m = model(f"glTF2/BoxTextured-{variant}/{name}")
    (material,) = m.materials
    (texture,) = m.textures
    assert isinstance(material, PbrMaterial) and material.metallic == 0.0
    assert material.base_color_texture == 0 and texture.srgb
    logo = np.asarray(Image.open(CORPUS / "glTF2/BoxTextured-glTF/CesiumLogoFlat.png").convert("RGBA"))
    np.testing.assert_array_equal(texture.pixels, logo)
    assert all("uvs" in p.attributes for p in m.parts)


def test_texture_transforms_and_a_second_uv_set_are_read():
    m = model("glTF2/textureTransform/TextureTransformTest.gltf")
    offsets = {mat.base_color_uv_offset for mat in m.materials}
    assert (0.5, 0.0) in offsets and (0.0, 0.5) in offsets and (0.5, 0.5) in offsets
    assert any(mat.base_color_uv_matrix != (1.0, 0.0, 0.0, 1.0) for mat in m.materials)  # rotation, scale
    box = model("glTF2/BoxTexcoords-glTF/boxTexcoords.gltf")
    (mat,) = box.materials
    assert (mat.base_color_texcoord, mat.metallic_roughness_texcoord) == (0, 1)
    assert [t.srgb for t in box.textures] == [True, False]  # one image, read as colour and as data
    assert {"uvs", "uvs1"} <= set(box.parts[0].attributes)


def test_a_multi_material_file_keeps_its_parts_apart():
    """2CylinderEngine: 34 materials, a mesh per part, meshes instanced by several nodes."""
    m = model("glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb")
    assert len(m.parts) > 50 and len({p.material for p in m.parts}) > 10
    assert m.n_unique_triangles < m.n_triangles  # instanced meshes are read once
    assert len({id(p.vertices) for p in m.parts}) < len(m.parts)
    assert load_mesh(CORPUS / "glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb").n_triangles == m.n_triangles
