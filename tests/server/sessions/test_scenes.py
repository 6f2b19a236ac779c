"""A session's scene source with meshes (server.sessions.scenes): stored, loaded bit for bit, and
streamed as exactly the scene JSON — without a server (no GL)."""

from __future__ import annotations

import io
import json

import numpy as np

from renderer.geometry.meshes import teapot
from renderer.geometry.scene import Camera, Mesh
from renderer.scenes.animation import AnimatedScene, Deformable, RigidGroup, museum, pose
from renderer.scenes.scenarios import mesh_scene
from server.sessions.scenes import (
    SHAPE_BYTES,
    SPHERE_BYTES,
    TRIANGLE_BYTES,
    SceneCache,
    load_source,
    scene_bytes,
    scene_info,
    scene_json_chunks,
    scene_source,
)


def scene_with_meshes():
    s = mesh_scene("mixed", detail=1)
    return s.with_geometry(
        s.sphere_centers, s.sphere_radii, s.sphere_materials, (*s.meshes, teapot(2, size=2.0, smooth=False))
    )


def test_the_npz_source_keeps_meshes_bit_for_bit_with_their_motions():
    anim = AnimatedScene(scene_with_meshes(), (RigidGroup(0, 0, mesh=1), Deformable(0, 9)))
    cam = Camera((1.0, 2.0, 50.0))
    back = load_source(scene_source(anim), cam)
    assert isinstance(back, AnimatedScene) and back.camera == cam
    for a, b in zip(anim.scene.meshes, back.scene.meshes, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.triangles, b.triangles)
        assert a.material == b.material and (a.normals is None) == (b.normals is None)
        if a.normals is not None:
            np.testing.assert_array_equal(a.normals, b.normals)
    assert [m.mesh for m in back.motions] == [1, None]
    assert scene_info(back) == scene_info(anim)
    assert scene_info(back)["n_moving_meshes"] == 1 and scene_info(back)["n_triangles"] == anim.scene.n_triangles


def test_the_streamed_json_is_exactly_the_scene_json():
    scene = scene_with_meshes()
    text = b"".join(scene_json_chunks(scene, spheres_per_chunk=7)).decode()
    assert text == json.dumps(scene.to_json(), separators=(",", ":"))
    anim = AnimatedScene(scene, (RigidGroup(0, 0, mesh=0),))
    got = json.loads(b"".join(scene_json_chunks(anim, spheres_per_chunk=3)))
    assert got == json.loads(json.dumps(anim.to_json()))
    no_spheres = scene.with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    assert b"".join(scene_json_chunks(no_spheres)).decode() == json.dumps(no_spheres.to_json(), separators=(",", ":"))


def test_the_cache_weighs_triangles():
    cache = SceneCache(max_bytes=10_000 * SPHERE_BYTES)
    scene = scene_with_meshes()  # ~1,000 triangles: weighs as ~4,000 spheres
    for i in range(4):
        cache.put((f"s{i}", "r"), scene)
    assert cache.get(("s0", "r")) is None and cache.get(("s3", "r")) is scene


def test_sources_keep_the_motions():
    """What the store keeps (and a restarted process reads) is the same animation."""
    anim = museum(20, "mixed", seed=4)
    again = load_source(scene_source(anim), anim.camera)
    assert again.motions == anim.motions
    np.testing.assert_array_equal(again.scene.sphere_centers, anim.scene.sphere_centers)
    t = 0.8
    np.testing.assert_array_equal(pose(again, t).scene.sphere_centers, pose(anim, t).scene.sphere_centers)


def test_the_environment_is_stored_and_streamed():
    """An uploaded image's texels are stored beside the scene (the sky by its name alone), an
    environment colour too; the streamed JSON names them as scene JSON does."""
    from renderer.geometry.scene import Scene
    from renderer.materials.envmap import SKY_REF, EnvironmentMap, image_ref
    from renderer.scenes.scenarios import scenario, with_sky

    texels = np.random.default_rng(0).random((4, 8, 3)).astype(np.float32)
    base = scenario(1, 8)
    lit = Scene(*(getattr(base, f) for f in ("camera", "lights", "materials", "sphere_centers")),
                base.sphere_radii, base.sphere_materials, base.planes, base.meshes, (0.0, 0.0, 0.0),
                EnvironmentMap(image_ref(texels), texels, 2.0, 10.0))  # fmt: skip
    sky, coloured = with_sky(base), Scene.from_json({**base.to_json(), "environment": {"color": [0.1, 0.2, 0.3]}})
    for scene in (lit, sky, coloured):
        source = scene_source(scene)
        back = load_source(source, scene.camera)
        assert back.to_json()["environment"] == scene.to_json()["environment"]
        assert json.loads(b"".join(scene_json_chunks(back))) == json.loads(json.dumps(scene.to_json()))
    np.testing.assert_array_equal(load_source(scene_source(lit), lit.camera).environment_map.texels, texels)
    for scene, stored in ((lit, True), (sky, False)):  # the source: a kind byte, then the npz
        with np.load(io.BytesIO(scene_source(scene)[1:])) as z:
            assert ("env_texels" in z.files) == stored
    assert sky.environment_map.ref == SKY_REF


def test_the_analytic_shapes_are_stored_bit_for_bit_streamed_and_counted():
    """A source keeps the shapes' float64 records (a restarted process reads the same scene), a
    motion over them, and a sphere scene's source holds no shape arrays at all."""
    table = mesh_scene("table")
    skewed = table.shapes.with_placement(table.shapes.params[:, 0:3] + 1.0 / 3.0)  # every bit of a float64 in use
    scene = table.with_geometry(table.sphere_centers, table.sphere_radii, table.sphere_materials, shapes=skewed)
    anim = AnimatedScene(scene, (Deformable(0, 2, over="shapes"),))
    back = load_source(scene_source(anim), scene.camera)
    assert isinstance(back, AnimatedScene) and back.motions == anim.motions
    for name in ("kind", "params", "material"):
        np.testing.assert_array_equal(getattr(back.scene.shapes, name), getattr(scene.shapes, name))
    info = scene_info(back)
    assert info == scene_info(anim) and info["n_shapes"] == scene.n_shapes and info["n_moving_shapes"] == 2
    np.testing.assert_array_equal(pose(back, 0.7).scene.shapes.params, pose(anim, 0.7).scene.shapes.params)
    text = b"".join(scene_json_chunks(scene)).decode()
    assert text == json.dumps(scene.to_json(), separators=(",", ":")) and '"tori":' in text
    plain = mesh_scene("teapot", detail=0)
    with np.load(io.BytesIO(scene_source(plain)[1:])) as z:
        assert not any(f.startswith("shape") for f in z.files)
    assert "n_shapes" not in scene_info(plain)
    # the cache weighs each shape as 4 spheres (two such scenes do not fit in one's bytes + 1)
    assert (
        scene_bytes(scene)
        == SHAPE_BYTES * scene.n_shapes + SPHERE_BYTES * scene.n_spheres
        == 4 * (SPHERE_BYTES * scene.n_shapes) + SPHERE_BYTES * scene.n_spheres
    )
    cache = SceneCache(max_bytes=scene_bytes(scene) + 1)
    cache.put(("a", "r"), scene)
    cache.put(("b", "r"), scene)
    assert cache.get(("a", "r")) is None and cache.get(("b", "r")) is scene


def lit_scene(seed: int, h: int = 64, w: int = 128, flat: bool = False):
    """A scenario under an uploaded image of ``h × w`` texels (seeded noise, or one value)."""
    from renderer.geometry.scene import Scene
    from renderer.materials.envmap import EnvironmentMap, image_ref
    from renderer.scenes.scenarios import scenario

    texels = np.random.default_rng(seed).random((h, w, 3)).astype(np.float32)
    if flat:
        texels[:] = 0.5
    base = scenario(1, 8)
    env = EnvironmentMap(image_ref(texels), texels)
    return Scene(*(getattr(base, f) for f in ("camera", "lights", "materials", "sphere_centers")),
                 base.sphere_radii, base.sphere_materials, base.planes, base.meshes, (0.0, 0.0, 0.0), env)  # fmt: skip


def test_the_cache_counts_an_image_in_bytes_and_evicts_by_them():
    """An image weighs its texels, its sampling tables and their packed upload copies (what it
    holds once drawn); three such scenes in a bound of two and a half: the oldest goes."""
    from renderer.gpu.gpu_layout import env_textures

    a, b, c = (lit_scene(i) for i in range(3))
    env = a.environment_map
    env_textures(env)  # drawn: texels, tables and packed copies all made
    texels, tables = env.texels.nbytes, sum(t.nbytes for t in env.sampling_tables)
    packed = sum(t.data.nbytes for t in env_textures(env))
    assert env.held_bytes >= texels + tables + packed - 4 * env.width  # (rows padded: a little less)
    assert scene_bytes(a) == env.held_bytes + SPHERE_BYTES * a.n_spheres
    cache = SceneCache(max_bytes=int(2.5 * scene_bytes(a)))
    for i, scene in enumerate((a, b, c)):
        cache.put((f"s{i}", "r"), scene)
    assert cache.get(("s0", "r")) is None and cache.get(("s1", "r")) is b and cache.get(("s2", "r")) is c
    assert cache.bytes_held == scene_bytes(b) + scene_bytes(c)
    cache.drop_session("s1")
    assert cache.bytes_held == scene_bytes(c)


def test_a_new_revision_of_a_session_frees_the_old_one():
    """Re-uploading an image to one session: the cache holds one revision, its bytes do not grow,
    and the old image (with its packed upload copies) is garbage once nothing else holds it."""
    import gc
    import weakref

    from renderer.gpu.gpu_layout import env_textures

    cache = SceneCache(max_bytes=1 << 40)
    first = lit_scene(0)
    env_textures(first.environment_map)
    gone = weakref.ref(first.environment_map)
    cache.put(("s", "rev1"), first)
    held = cache.bytes_held
    del first
    for i in range(1, 5):
        cache.put(("s", f"rev{i + 1}"), lit_scene(i))
        assert cache.bytes_held == held
    gc.collect()
    assert gone() is None
    assert cache.get(("s", "rev1")) is None and cache.get(("s", "rev5")) is not None


def test_the_image_is_stored_as_its_texels():
    """The source keeps an uploaded image's texels uncompressed (what the quota counts is what the
    service holds), the rest compressed; it loads back bit for bit."""
    scene = lit_scene(0, 256, 512, flat=True)  # compressed, a few kB
    source = scene_source(scene)
    texels = scene.environment_map.texels.nbytes
    assert texels <= len(source) < texels + 4096
    np.testing.assert_array_equal(load_source(source, scene.camera).environment_map.texels, 0.5)


def test_textures_and_vertex_attributes_are_stored_as_they_are_and_reported():
    """A textured scene's source keeps every texture's texels (uncompressed: the store's quota counts
    them) and sampler, and each mesh's UVs, colours and tangents, bit for bit; its info reports the
    GPU bytes of the texture array with its mip levels and of the attribute records."""
    from renderer.geometry.scene import Scene, make_mesh
    from renderer.gpu import texture_layout
    from renderer.materials.pbr import PbrMaterial
    from renderer.materials.texture import Texture

    rng = np.random.default_rng(0)
    tex = (
        Texture(rng.integers(0, 256, (64, 32, 4), dtype=np.uint8), srgb=True, wrap_s="mirror", name="a.png"),
        Texture(rng.integers(0, 256, (5, 7, 4), dtype=np.uint8), filter="nearest"),
    )
    v = [[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]]
    uv = rng.random((4, 2))
    a = make_mesh(v, [[0, 2, 1], [1, 2, 3]], uvs=uv, uvs1=uv[::-1], colors=rng.random((4, 4)), material=1)
    b = make_mesh(v, [[0, 2, 1]])
    c = make_mesh(v, [[0, 2, 1]], uvs=uv, tangents=[[1, 0, 0, -1]] * 4, material=1)
    cam = Camera((0.0, 3.0, 0.5), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    mats = (PbrMaterial(), PbrMaterial(base_color_texture=0, normal_texture=1))
    scene = Scene(
        cam, (), mats, np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), meshes=(a, b, c), textures=tex
    )  # fmt: skip
    source = scene_source(scene)
    assert len(source) > sum(t.nbytes for t in tex)  # the texels themselves, not a compressed image
    back = load_source(source, cam)
    assert len(back.textures) == 2
    for t0, t1 in zip(tex, back.textures, strict=True):
        sampler = ("srgb", "wrap_s", "wrap_t", "filter", "name")
        assert [getattr(t1, k) for k in sampler] == [getattr(t0, k) for k in sampler]
        np.testing.assert_array_equal(t1.pixels, t0.pixels)
    for m0, m1 in zip(scene.meshes, back.meshes, strict=True):
        assert set(m1.attributes) == set(m0.attributes)
        for name, values in m0.attributes.items():
            np.testing.assert_array_equal(m1.attributes[name], values)
    info = scene_info(scene)
    assert info["n_textures"] == 2
    assert info["texture_bytes"] == texture_layout.texture_array_bytes(64, 64, 2) == texture_layout.array_bytes(tex)
    assert info["attribute_bytes"] == (64 + 48 + 48) * 4  # UVs, colours (a), tangents (c) for all 4 triangles


def test_a_models_materials_textures_and_attributes_come_back_streamed_and_weighed():
    """A textured model's meshes (UVs, colours), its PbrMaterial and its texture come back from
    the stored source as they went in; the streamed scene JSON is the scene's own, and the cache
    weighs the texels and the attributes."""
    from renderer.geometry.scene import Scene
    from renderer.materials.pbr import PbrMaterial
    from renderer.materials.texture import Texture

    base = mesh_scene("teapot", 0)
    pixels = np.arange(3 * 5 * 4, dtype=np.uint8).reshape(3, 5, 4)
    texture = Texture(pixels, srgb=True, wrap_s="clamp", filter="nearest", name="skin.png")
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    uvs = np.array([[0, 0], [1, 0], [0, 1]], float)
    colors = np.array([[1, 0, 0, 1], [0, 1, 0, 0.5], [0, 0, 1, 1]], float)
    pbr = PbrMaterial(metallic=0.0, base_color_texture=0)
    textured = Scene(
        base.camera,
        base.lights,
        (*base.materials, pbr),
        base.sphere_centers,
        base.sphere_radii,
        base.sphere_materials,
        base.planes,
        (*base.meshes, Mesh(v, [[0, 1, 2]], len(base.materials), None, uvs=uvs, colors=colors)),
        textures=(texture,),
    )
    back = load_source(scene_source(textured), textured.camera)
    assert back.materials[-1] == pbr
    (t,) = back.textures
    np.testing.assert_array_equal(t.pixels, pixels)
    assert (t.srgb, t.wrap_s, t.wrap_t, t.filter, t.name) == (True, "clamp", "repeat", "nearest", "skin.png")
    np.testing.assert_array_equal(back.meshes[-1].uvs, uvs)
    np.testing.assert_array_equal(back.meshes[-1].colors, colors)
    assert all(m.uvs is None for m in back.meshes[:-1])
    # the cache weighs the texels and the attributes: 60 bytes, and 3 × (2 + 4) float64
    assert scene_bytes(back) - scene_bytes(base) == 60 + 3 * 6 * 8 + TRIANGLE_BYTES
    chunks = json.loads(b"".join(scene_json_chunks(back)))
    assert chunks == json.loads(json.dumps(back.to_json()))  # the streamed JSON is the scene's own
