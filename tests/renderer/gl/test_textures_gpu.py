"""Textures and vertex attributes on the GPU against the float64 reference: shaders/pbr_inputs.glsl
(through tests/renderer/gl/texture_probe.py) at the hit points the reference tracer finds for a
catalogue of views, each expected value computed in float64 from the hit (barycentrics → UV →
texel, renderer/oracle/reference.py), never by the GLSL under test."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from renderer.frame.shader_source import variant_source, vertex_source
from renderer.geometry.meshes import icosphere
from renderer.geometry.scene import Camera, Material, Scene, make_mesh
from renderer.gpu import texture_layout
from renderer.gpu.gpu_layout import Variant
from renderer.materials.pbr import PbrMaterial
from renderer.materials.texture import Texture
from renderer.oracle import reference
from tests.renderer.gl.texture_probe import probe


def _scene(meshes, materials, textures, camera) -> Scene:
    return Scene(
        camera, (), tuple(materials), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), meshes=tuple(meshes),
        textures=tuple(textures),
    )  # fmt: skip


def _hits(scene: Scene, width: int, height: int, jitter: np.ndarray | None = None):
    """The reference's primary hits on triangles: rows of (triangle id, point, outward normal, t, d)."""
    geometry = dataclasses.replace(scene, materials=tuple(Material() for _ in scene.materials))
    o, d = reference.primary_rays(scene.camera, width, height)
    t, ids = reference.trace_rays(geometry, o, d)
    hit = ids >= scene.triangle_id_base
    p = o[hit] + t[hit, None] * d[hit]
    tri = ids[hit] - scene.triangle_id_base
    c = scene.triangle_corners[tri]
    g = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    n = g / np.linalg.norm(g, axis=1, keepdims=True)
    return ids[hit], p, n, t[hit], d[hit]


def _expected_base(scene: Scene, prim, p, uv_set=0, matrix=(1.0, 0.0, 0.0, 1.0), offset=(0.0, 0.0), level=0.0):
    tri = prim - scene.triangle_id_base
    bary = reference.triangle_barycentrics(scene, tri, p)
    uv = reference.hit_texcoords(scene, tri, bary, uv_set)
    m = np.asarray(matrix).reshape(2, 2)
    st = uv @ m.T + np.asarray(offset)
    tex = scene.textures[0]
    return st, reference.texture_sample(texture_layout.mip_chain(tex.pixels, tex.srgb), tex, st, level)


def _away_from_texel_edges(st: np.ndarray, tex: Texture, margin: float = 0.02) -> np.ndarray:
    """Points whose UV lies at least ``margin`` texels from a texel's edge (nearest lookups there can
    go either way in float32)."""
    f = np.stack([st[:, 0] * tex.width, st[:, 1] * tex.height], axis=1)
    frac = f - np.floor(f)
    return ((frac > margin) & (frac < 1 - margin)).all(axis=1)


def _texture(seed: int, size=(8, 8), **kw) -> Texture:
    rng = np.random.default_rng(seed)
    return Texture(rng.integers(0, 256, (*size, 4), dtype=np.uint8), **kw)


QUAD = ([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], [[0, 3, 2], [0, 2, 1]])
TOP_DOWN = Camera((0.0, 3.0, 0.01), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)


@pytest.mark.parametrize(
    "wrap_s, wrap_t, srgb", [("repeat", "repeat", True), ("clamp", "mirror", False), ("mirror", "clamp", True)]
)
def test_a_textured_quad_nearest_at_level_0_equals_the_reference(gl_renderer, wrap_s, wrap_t, srgb):
    """UVs from −0.5 to 2.5 over a quad seen from above: every wrap mode's texel, exactly (sRGB decoded)."""
    tex = _texture(1, (8, 6), srgb=srgb, filter="nearest", wrap_s=wrap_s, wrap_t=wrap_t)
    quad = make_mesh(*QUAD, uvs=[[-0.5, -0.5], [2.5, -0.5], [2.5, 2.5], [-0.5, 2.5]])
    scene = _scene([quad], [PbrMaterial(base_color_texture=0, base_color=(1.0, 1.0, 1.0))], [tex], TOP_DOWN)
    prim, p, n, _, _ = _hits(scene, 48, 48)
    out = probe(gl_renderer.ctx, scene, prim, p, n, np.zeros(len(p)))
    st, expected = _expected_base(scene, prim, p)
    assert len(p) > 700
    np.testing.assert_allclose(out["uv"][:, :2], st, atol=2e-6)
    keep = _away_from_texel_edges(st, tex)
    assert keep.mean() > 0.8
    np.testing.assert_allclose(out["base"][keep], expected[keep], atol=2e-6)


def test_a_textured_sphere_mesh_bilinear_at_given_levels_equals_the_reference(gl_renderer):
    """An icosphere with spherical UVs, a bilinear sRGB texture, the level fixed through the footprint:
    the GPU's level (log2 footprint + Δ + ½ log2 w·h) and its trilinear mix equal the reference's."""
    tex = _texture(2, (16, 32), srgb=True, filter="linear")
    base = icosphere(2, radius=1.0)
    v = np.asarray(base.vertices)
    uvs = np.stack([np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi) + 0.5, np.arccos(np.clip(v[:, 1], -1, 1)) / np.pi], 1)
    sphere = make_mesh(base.vertices, base.triangles, normals=base.normals, uvs=uvs)
    cam = Camera((0.0, 0.5, 3.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0)
    scene = _scene([sphere], [PbrMaterial(base_color_texture=0, base_color=(0.5, 1.0, 0.25))], [tex], cam)
    prim, p, n, _, _ = _hits(scene, 40, 40)
    rng = np.random.default_rng(3)
    footprint = np.exp2(rng.uniform(-8.0, 0.0, len(p)))
    out = probe(gl_renderer.ctx, scene, prim, p, n, footprint)
    tri = prim - scene.triangle_id_base
    lod = texture_layout.triangle_lod_terms(scene.triangle_corners[tri], _corner_uvs(scene, tri))
    level = np.array(
        [texture_layout.level_for(f, d, tex.width, tex.height) for f, d in zip(footprint, lod, strict=True)]
    )
    st, expected = _expected_base(scene, prim, p, level=level)
    expected[:, :3] *= (0.5, 1.0, 0.25)
    assert (level > 0.5).sum() > 100 and (level < 0.5).sum() > 100  # both level 0 and mixed levels
    np.testing.assert_allclose(out["uv"][:, :2], st, atol=1e-5)
    np.testing.assert_allclose(out["base"], expected, atol=2e-3)


def _corner_uvs(scene: Scene, tri: np.ndarray, name: str = "uvs") -> np.ndarray:
    m = scene.meshes[0]
    return np.asarray(getattr(m, name))[np.asarray(m.triangles)[tri]]


def test_a_uv_transform_on_texcoord_1_and_the_other_slots(gl_renderer):
    """KHR_texture_transform on UV set 1 (rotation · scale, offset), nearest at level 0; metallic from
    blue, roughness from green, occlusion's red mixed by its strength, emissive × texture, transmission
    from red; vertex colours multiply the base colour."""
    tex = _texture(4, (8, 8), filter="nearest", wrap_s="repeat", wrap_t="repeat")
    a = math.radians(30.0)
    matrix = (1.5 * math.cos(a), -2.0 * math.sin(a), 1.5 * math.sin(a), 2.0 * math.cos(a))
    offset = (0.25, -0.125)
    colors = [[1.0, 0.5, 0.25, 1.0], [0.5, 1.0, 1.0, 0.5], [1.0, 1.0, 1.0, 1.0], [0.25, 0.25, 1.0, 1.0]]
    quad = make_mesh(*QUAD, uvs=[[9, 9], [9, 9], [9, 9], [9, 9]], uvs1=[[0, 0], [1, 0], [1, 1], [0, 1]], colors=colors)
    slots = {}
    for slot in ("base_color", "metallic_roughness", "emissive", "occlusion", "transmission"):
        slots.update({f"{slot}_texture": 0, f"{slot}_texcoord": 1, f"{slot}_uv_matrix": matrix})
        slots[f"{slot}_uv_offset"] = offset
    mat = PbrMaterial(
        metallic=0.5, roughness=0.75, emissive=(1.0, 0.5, 0.25), emissive_strength=2.0, occlusion_strength=0.5,
        transmission=0.5, **slots,
    )  # fmt: skip
    scene = _scene([quad], [mat], [tex], TOP_DOWN)
    prim, p, n, _, _ = _hits(scene, 40, 40)
    out = probe(gl_renderer.ctx, scene, prim, p, n, np.zeros(len(p)))
    st, texel = _expected_base(scene, prim, p, uv_set=1, matrix=matrix, offset=offset)
    keep = _away_from_texel_edges(st, tex)
    tri = prim - scene.triangle_id_base
    bary = reference.triangle_barycentrics(scene, tri, p)
    vc = np.einsum("nk,nkc->nc", bary, np.asarray(colors)[np.asarray(quad.triangles)[tri]])
    np.testing.assert_allclose(out["uv"][:, 2:], reference.hit_texcoords(scene, tri, bary, 1), atol=2e-6)
    np.testing.assert_allclose(out["base"][keep], (texel * vc)[keep], atol=2e-6)
    factors = np.stack(
        [0.5 * texel[:, 2], 0.75 * texel[:, 1], 1.0 + 0.5 * (texel[:, 0] - 1.0), 0.5 * texel[:, 0]], axis=1
    )
    np.testing.assert_allclose(out["factors"][keep], factors[keep], atol=2e-6)
    np.testing.assert_allclose(out["emissive"][keep, :3], (texel[:, :3] * (2.0, 1.0, 0.5))[keep], atol=5e-6)


def test_a_normal_map_bends_the_normal_in_the_generated_tangent_frame(gl_renderer):
    """A quad in y = 0 (normal +y), U along +x, V along +z (down the image: the bitangent, the image's up,
    is −z): a map texel (x, y, z) = (0.6, 0.3, 0.75) scaled by 0.5 gives normalize(0.3·x̂ − 0.15·(−ẑ)·… )
    — the expected normal is formed in float64 from the texel, the tangent +x and the bitangent −z."""
    px = np.array([[[204, 166, 223, 255]]], dtype=np.uint8)  # (2·c/255 − 1): 0.6, 0.302, 0.749
    tex = Texture(px, filter="nearest")
    quad = make_mesh(*QUAD, uvs=[[0, 0], [1, 0], [1, 1], [0, 1]])
    scene = _scene([quad], [PbrMaterial(normal_texture=0, normal_scale=0.5)], [tex], TOP_DOWN)
    prim, p, n, _, _ = _hits(scene, 16, 16)
    out = probe(gl_renderer.ctx, scene, prim, p, np.tile([0.0, 1.0, 0.0], (len(p), 1)), np.zeros(len(p)))
    m = 2.0 * px[0, 0, :3] / 255.0 - 1.0
    m[:2] *= 0.5
    e = m[0] * np.array([1.0, 0.0, 0.0]) + m[1] * np.array([0.0, 0.0, -1.0]) + m[2] * np.array([0.0, 1.0, 0.0])
    e /= np.linalg.norm(e)
    np.testing.assert_allclose(out["normal"][:, :3], np.tile(e, (len(p), 1)), atol=1e-5)


def _checker(n: int) -> Texture:
    """An n × n black-and-white checker of single texels (linear, nearest: the worst aliasing)."""
    i = np.add.outer(np.arange(n), np.arange(n)) % 2
    px = np.zeros((n, n, 4), np.uint8)
    px[..., :3] = (255 * i)[..., None]
    px[..., 3] = 255
    return Texture(px, filter="nearest")


def test_a_far_checker_floor_at_one_sample_does_not_alias_with_ray_cones(gl_renderer):
    """A checker floor running to the horizon, one ray per pixel, base colour through pbr_inputs with the
    ray cone's footprint (spread × t / |cos|, the primary cone of docs/SHADING.md): each pixel is compared
    with the float64 mean of the checker over the pixel (8 × 8 rays of the reference, level 0). With the
    cones the error is the blur of the mip filter; without (level 0) it is the aliasing itself."""
    tex = _checker(256)
    size = 200.0
    quad = make_mesh(
        [[-size, 0, -size], [size, 0, -size], [size, 0, size], [-size, 0, size]],
        [[0, 3, 2], [0, 2, 1]],
        uvs=[[0, 0], [8, 0], [8, 8], [0, 8]],
    )
    cam = Camera((0.0, 1.5, size - 1.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    scene = _scene([quad], [PbrMaterial(base_color_texture=0)], [tex], cam)
    w = h = 64
    prim, p, n, t, d = _hits(scene, w, h)
    spread = math.atan(2.0 * math.tan(math.radians(cam.fov_y) / 2.0) / h)
    footprint = spread * t / np.abs(np.einsum("ij,ij->i", d, n))
    with_cones = probe(gl_renderer.ctx, scene, prim, p, n, footprint)["base"][:, 0]
    at_level_0 = probe(gl_renderer.ctx, scene, prim, p, n, np.zeros(len(p)))["base"][:, 0]
    truth = _supersampled_checker(scene, w, h, 8)
    o, _ = reference.primary_rays(cam, w, h)
    pix = np.flatnonzero(reference.trace_rays(dataclasses.replace(scene, materials=(Material(),)), o, _)[1] >= 0)
    far = t > 20.0  # where a pixel covers many texels
    assert far.sum() > 200
    err_cones = np.sqrt(np.mean((with_cones[far] - truth[pix][far]) ** 2))
    err_level0 = np.sqrt(np.mean((at_level_0[far] - truth[pix][far]) ** 2))
    assert err_level0 > 0.3, "the view aliases at level 0"
    assert err_cones < 0.1 and err_cones < err_level0 / 4


def _supersampled_checker(scene: Scene, w: int, h: int, k: int) -> np.ndarray:
    """float64 (w·h,): the mean over k × k rays per pixel of the checker's value (level 0, nearest),
    0 where a ray misses."""
    cam = scene.camera
    o, d = reference.primary_rays(cam, w * k, h * k)
    geometry = dataclasses.replace(scene, materials=(Material(),))
    t, ids = reference.trace_rays(geometry, o, d)
    value = np.zeros(len(o))
    hit = ids >= 0
    p = o[hit] + t[hit, None] * d[hit]
    _, texel = _expected_base(scene, ids[hit], p)
    value[hit] = texel[:, 0]
    return value.reshape(h, k, w, k).mean(axis=(1, 3)).reshape(-1)


@pytest.mark.parametrize(
    "variant",
    [
        Variant("bvh", "color", 4, ("TRIANGLES", "SMOOTH_TRIANGLES", "TEXTURES", "VERTEX_COLORS", "TANGENTS")),
        Variant("bih", "recursion", 3, ("TRIANGLES", "TEXTURES")),
        Variant("bvh", "color", 6, ("TRIANGLES", "SHAPES", "TEXTURES", "PATH", "EMISSION")),
    ],
    ids=["whitted", "task-stack", "path"],
)
def test_textured_variants_compile_with_the_ray_cones_in_their_loops(gl_renderer, variant):
    """The Whitted loop (with its task stack) and the path loop track the cone where the scene is textured."""
    text = variant_source(variant)
    assert "g_cone_width = cone_footprint(" in text
    gl_renderer.ctx.program(vertex_shader=vertex_source(), fragment_shader=text).release()


# ---- the ray cones in the integrators' loops ----------------------------------------------------
# A room of quads seen from inside: a mirror floor (Phong, reflective 1), diffuse walls. The tracer's
# variants compile the cone code where the scene carries TEXTURES (its PBR materials read textures);
# here the room's Phong materials read none, so the test makes the scene carry it
# (texture_layout.uses_textures) and reads the loops' cone through the colour: the line that adds a
# hit's colour is replaced, in the compiled text alone (GLRenderer.fragment_text), by one that writes
# the cone at the hit of the ray level (Whitted) or path segment asked for.
WHITTED_AMBIENT = "color += k.weight * m.ambient * m.color;   // Phong's ambient term"
PATH_EMISSION = "if (r.front) L += emission_weight(h, ng, d, prev_p, prev_pdf) * beta * emission_at(s.mat);"


def _room() -> Scene:
    mirror = Material(color=(1, 1, 1), ambient=0.0, diffuse=0.0, specular=0.0, reflective=1.0)
    wall = Material(color=(0.5, 0.5, 0.5), ambient=0.0, diffuse=1.0, specular=0.0, reflective=0.0)
    s = 4.0

    def quad(a, b, c, d, mat):  # corners counter-clockwise seen from inside
        return make_mesh([a, b, c, d], [[0, 1, 2], [0, 2, 3]], material=mat)

    meshes = [
        quad([-s, 0, -s], [-s, 0, s], [s, 0, s], [s, 0, -s], 0),  # floor, normal +y
        quad([-s, 0, -s], [s, 0, -s], [s, 2 * s, -s], [-s, 2 * s, -s], 1),  # back wall, +z
        quad([-s, 2 * s, -s], [s, 2 * s, -s], [s, 2 * s, s], [-s, 2 * s, s], 1),  # ceiling, −y
        quad([-s, 0, s], [-s, 2 * s, s], [s, 2 * s, s], [s, 0, s], 1),  # front wall, −z
        quad([-s, 0, -s], [-s, 2 * s, -s], [-s, 2 * s, s], [-s, 0, s], 1),  # left wall, +x
        quad([s, 0, -s], [s, 0, s], [s, 2 * s, s], [s, 2 * s, -s], 1),  # right wall, −x
    ]
    cam = Camera((0.0, 3.0, 3.0), (0.0, 0.5, -2.0), (0.0, 1.0, 0.0), 60.0)
    return _scene(meshes, [mirror, wall], [], cam)


class _ConeRenderer:
    """A GLRenderer on the session's context whose fragment text is patched, ``old`` → ``new`` (a
    renderer of its own: its compiled programs are cached by the unpatched text)."""

    def __init__(self, gl_renderer, old: str, new: str):
        from renderer.gl import GLRenderer

        self.r, self.old, self.new = GLRenderer(gl_renderer.ctx), old, new

    def render(self, scene, settings):
        from unittest import mock

        def patched(src, features):
            assert self.old in src
            return src.replace(self.old, self.new)

        with mock.patch.object(self.r, "fragment_text", patched):
            return self.r.render(scene, settings)


def _mirror_paths(scene: Scene, w: int, h: int):
    """float64: per pixel (centre) the distance from the camera to the second hit via the mirror floor,
    and whether the first hit is the floor and the second a wall."""
    geometry = dataclasses.replace(scene, materials=(Material(), Material()))
    o, d = reference.primary_rays(scene.camera, w, h)
    t1, id1 = reference.trace_rays(geometry, o, d)
    p = o + t1[:, None] * d
    floor = (id1 >= 0) & (id1 - scene.triangle_id_base < 2)
    r = d * np.array([1.0, -1.0, 1.0])  # reflected off y = 0
    t2, id2 = reference.trace_rays(geometry, p, r, src=id1)
    return t1 + t2, floor & (id2 >= 0), t1, d


@pytest.fixture
def textured_variants(monkeypatch):
    monkeypatch.setattr(texture_layout, "uses_textures", lambda scene: True)


def test_whitted_cones_grow_with_the_distance_travelled_and_keep_the_spread_at_a_mirror(gl_renderer, textured_variants):
    """Level 1: the footprint is γ·t / |cos| with γ the pixel's angle; level 2 (after the mirror):
    γ·(t1 + t2) / |cos2| — the spread kept, the width grown along both segments."""
    from renderer.config.settings import RenderSettings

    scene = _room()
    w = h = 24
    out = {}
    for level in (1, 2):
        new = f"if (k.level == {level}) color = vec3(g_cone_width, k_dist + h.t, abs(dot(k.d, s.ng)));"
        settings = RenderSettings(
            width=w, height=h, format="npy", method="bvh", max_recursion_depth=2, specialize=False
        )
        res = _ConeRenderer(gl_renderer, WHITTED_AMBIENT, new).render(scene, settings)
        assert "TEXTURES" in res.stats["shader_features"]
        out[level] = res.image.reshape(-1, 3).astype(np.float64)
    gamma = math.atan(2.0 * math.tan(math.radians(60.0) / 2.0) / h)
    dist, mirrored, t1, d = _mirror_paths(scene, w, h)
    np.testing.assert_allclose(out[1][:, 1], t1, rtol=1e-4)
    np.testing.assert_allclose(out[1][:, 0], gamma * out[1][:, 1] / out[1][:, 2], rtol=1e-4)
    assert mirrored.sum() > 100
    m = out[2][mirrored]
    np.testing.assert_allclose(m[:, 1], dist[mirrored], rtol=1e-4)
    np.testing.assert_allclose(m[:, 0], gamma * m[:, 1] / m[:, 2], rtol=1e-4)


def test_path_cones_keep_the_spread_at_a_mirror_and_widen_it_after_a_diffuse_bounce(gl_renderer, textured_variants):
    """Segment 2 after the mirror: the spread is still the pixel's, the width γ × the path's length so far
    (pixel-jittered rays: near the centre's); segment 3, after a diffuse wall, has the wide
    spread (1 radian); the footprint is width / |cos| at each."""
    from renderer.config.settings import RenderSettings

    scene = _room()
    w = h = 24
    out = {}
    for seg in (2, 3):
        new = f"if (segments == {seg}) L = vec3(cone_w, cone_spread, g_cone_width * abs(dot(d, s.ng)));"
        settings = RenderSettings(
            width=w, height=h, format="npy", method="bvh", integrator="path", samples_per_pixel=1,
            max_recursion_depth=4, specialize=False,
        )  # fmt: skip
        res = _ConeRenderer(gl_renderer, PATH_EMISSION, new).render(scene, settings)
        out[seg] = res.image.reshape(-1, 3).astype(np.float64)
    gamma = math.atan(2.0 * math.tan(math.radians(60.0) / 2.0) / h)
    dist, mirrored, _, _ = _mirror_paths(scene, w, h)
    m = out[2][mirrored]
    np.testing.assert_allclose(m[:, 1], gamma, rtol=1e-4)  # (float32 atan)
    rel = np.abs(m[:, 0] / gamma - dist[mirrored]) / dist[mirrored]  # (a jittered ray: not the centre's path)
    assert np.median(rel) < 0.01 and rel.max() < 0.08
    np.testing.assert_allclose(m[:, 2], m[:, 0], rtol=1e-4)
    third = out[3][mirrored & (out[3][:, 1] > 0)]
    assert len(third) > 50
    np.testing.assert_allclose(third[:, 1], 1.0, rtol=1e-6)
