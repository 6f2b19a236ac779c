"""The GLSL tracer (renderer.gl.renderer) against the float64 reference and brute force.

- methods ``bih`` and ``bruteforce`` against the independent float64 reference, every
  mode, the heat counters, the arrays' dtypes;
- methods ``bvh`` and ``kdtree`` against brute force (primid ≥ 99.99 %) and the
  float64 reference (primid ≥ 99.9 %, colour PSNR ≥ 40 dB), scenarios 1–3, n = 64 and
  1024, recursion depth 1 and 5, 96 × 160; a BVH refitted after an incoherent motion
  (every sphere teleported) renders the same ids as brute force: slow perhaps, never wrong;
- animated scenes: every frame of a test animation of each kind, traced by
  ``bvh`` with refit and with selective rebuild and by ``twolevel``, gives the
  brute-force ids on ≥ 99.99 % of pixels.

Images against the reference are 160 × 272 (a quarter of the thesis's 640 × 1088 in each
side) so the float64 reference stays fast; the shader has no resolution-dependent code path.

Triangle meshes on the GPU: every one-pass method (bih, bruteforce,
bvh, kdtree, twolevel) against the float64 reference and the CPU brute force,
watertightness of the float32 test, every mode.

Expected values come from the float64 reference (renderer/oracle/reference.py) and the CPU brute
force over the same primitives (renderer.accel.cpu_trace.trace_tree with no tree), never
from the GPU code under test:

- primary ids of a scene of spheres (of different radii: the 32-byte slots), a plane, an
  icosphere, a box, a teapot and more meshes: ≥ 99.9 % of the pixels as the reference,
  ≥ 99.99 % as the CPU brute force, for every method (uniform blocks and textures), and
  twolevel with moving meshes and spheres (both of its trees hold both kinds);
- watertightness: closed meshes (icosphere, box, teapot) seen from many directions, with the
  camera's pixel-centre rays through the box's edges and vertices too: no pixel strictly
  inside the reference's silhouette (itself and its 8 neighbours hit the mesh) misses on the
  GPU — zero leaks; the pixels whose ids differ at all are counted and must be few
  (silhouette pixels, where float32 and float64 may disagree);
- colour (reflection, refraction through a closed glass mesh, shadows), normal (flat and
  smooth shading), depth, recursion and heat images against the reference with the
  tolerances of the sphere tests (tests/renderer/gl/test_renderer.py);
- a method whose GPU layout held spheres only would refuse such a frame with
  SceneError("meshes") naming the methods that trace meshes (none does today).

Every GPU name once: what is packed for a shader variant is what the variant reads.

The shader header declares a variant's textures, uniforms and record arrays from the
layout constants (renderer/gpu/gpu_layout.py, renderer/accel/*_layout.py) and the renderer
uploads exactly those. Here, for every method and mode, each uploaded texture or uniform
must be an *active* uniform of the compiled program, and each record array the variant
reads from a uniform block an active uniform *block* of that name (a texture otherwise):
a binding packed for nothing, or declared under a name the shader does not use, fails —
with the feature sets, the data formats (EQUAL_RADII, MATERIAL_TEXTURE), the compiled-in
counts, every record array in a block or none, and the RGBA8 image.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from renderer.accel.cpu_trace import trace_tree
from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.frame.shader_source import known_bindings, tracer_bindings
from renderer.geometry.meshes import box, icosphere, teapot, torus
from renderer.geometry.scene import Camera, Light, Material, Plane, Scene
from renderer.gl import GLRenderer
from renderer.gpu import gpu_layout
from renderer.gpu.gpu_layout import Variant
from renderer.modes import SINGLE_PASS_MODES
from renderer.oracle.reference import primary_rays, render_reference
from renderer.scenes.animation import museum
from renderer.scenes.scenarios import mesh_scene, scenario
from tests.helpers import psnr
from tests.renderer.gl.support import active

pytestmark = pytest.mark.long  # a hundred GL tests

W, H = 160, 272
CASES = [(sc, n) for sc in (1, 2, 3) for n in (64, 1024)]


@pytest.fixture(scope="module")
def reference_frames():
    cache = {}

    def get(sc: int, n: int):
        if (sc, n) not in cache:
            s = RenderSettings(width=W, height=H, max_recursion_depth=5, method="bruteforce")
            cache[(sc, n)] = render_reference(scenario(sc, n), s)
        return cache[(sc, n)]

    return get


@pytest.mark.parametrize("sc,n", CASES)
def test_gpu_matches_reference(gl_renderer, reference_frames, sc, n):
    ref = reference_frames(sc, n)
    scene = scenario(sc, n)
    frames = {}
    for method in ("bih", "bruteforce"):
        s = RenderSettings(width=W, height=H, max_recursion_depth=5, method=method, max_prims=8)
        gpu = gl_renderer.render(scene, s)
        frames[method] = gpu
        assert np.isfinite(gpu.image).all(), "NaN or inf in the colour image"
        same = gpu.primid == ref.primid
        assert same.mean() >= 0.999, f"{method}: primid agrees on {same.mean():.5f} of pixels"
        hit = same & (ref.primid >= 0)
        rel = np.abs(gpu.depth[hit] - ref.depth[hit]) / ref.depth[hit]
        assert rel.max() <= 1e-4, f"{method}: depth off by {rel.max():.2e} relative"
        assert np.isinf(gpu.depth[ref.primid < 0] if same.all() else gpu.depth[same & (ref.primid < 0)]).all()
        p = psnr(gpu.image_u8(), ref.image_u8())
        assert p >= 40.0, f"{method}: colour PSNR {p:.1f} dB < 40"
    agree = (frames["bih"].primid == frames["bruteforce"].primid).mean()
    assert agree >= 0.9999, f"BIH and brute force ids agree on {agree:.6f}"


@pytest.mark.parametrize("mode", ["depth", "primid", "normal", "recursion"])
def test_modes_match_reference(gl_renderer, mode):
    scene = scenario(3, 64)
    s = RenderSettings(width=W, height=H, max_recursion_depth=5, mode=mode)
    gpu = gl_renderer.render(scene, s)
    ref = render_reference(scene, s)
    assert np.isfinite(gpu.image).all()
    if mode == "recursion":
        # The deepest level is discrete: compare pixel colours exactly.
        same = (gpu.image_u8() == ref.image_u8()).all(axis=2)
        assert same.mean() >= 0.995, f"recursion levels agree on {same.mean():.4f}"
        levels = {tuple(c) for c in ref.image_u8().reshape(-1, 3)}
        assert len(levels) >= 3, "the scene should need several recursion levels"
    else:
        ok = gpu.primid == ref.primid
        diff = np.abs(gpu.image.astype(np.float64) - ref.image)[ok]
        assert ok.mean() >= 0.999 and np.quantile(diff, 0.999) <= 2e-3, f"{mode}: max diff {diff.max():.2e}"
        np.testing.assert_array_equal(gpu.array().shape[:2], (H, W))


def test_heat_counts_match_cpu_traversal(gl_renderer):
    """Fig. 4.3's counters from the shader equal the CPU traversal's on almost every pixel."""
    scene = scenario(1, 64)
    s = RenderSettings(width=W, height=H, mode="heat", max_prims=1)
    gpu = gl_renderer.render(scene, s).image_u8()
    ref = render_reference(scene, s).image_u8()
    same = (gpu == ref).all(axis=2)
    assert same.mean() >= 0.99, f"heat images agree on {same.mean():.4f}"
    assert (gpu[..., 2] > 0).mean() > 0.05, "rays inside the box must visit nodes"
    assert (gpu[..., 1] > 0).any(), "some rays pass through empty gaps"


def test_npy_arrays_follow_spec(gl_renderer):
    scene = scenario(2, 64)
    base = RenderSettings(width=32, height=48)
    color = gl_renderer.render(scene, base).array()
    depth = gl_renderer.render(scene, base.with_(mode="depth")).array()
    prim = gl_renderer.render(scene, base.with_(mode="primid")).array()
    assert color.dtype == np.uint8 and color.shape == (48, 32, 3)
    assert depth.dtype == np.float32 and depth.shape == (48, 32)
    assert prim.dtype == np.int32 and prim.shape == (48, 32)
    assert ((prim == -1) == np.isinf(depth)).all()
    assert (prim >= -1).all() and prim.max() <= scene.n_primitives - 1


# ---------------------------------------------------------------- methods bvh and kdtree

TREE_W, TREE_H = 96, 160  # 24 cases × 2 methods: smaller frames than the reference's above
_REF: dict = {}


def tree_reference(sc: int, n: int, depth: int):
    if (sc, n, depth) not in _REF:
        _REF[(sc, n, depth)] = render_reference(
            scenario(sc, n), RenderSettings(width=TREE_W, height=TREE_H, max_recursion_depth=depth, method="bruteforce")
        )
    return _REF[(sc, n, depth)]


@pytest.mark.parametrize("depth", [1, 5])
@pytest.mark.parametrize("sc,n", [(sc, n) for sc in (1, 2, 3) for n in (64, 1024)])
def test_gpu_bvh_kdtree_exact(gl_renderer, sc, n, depth):
    scene = scenario(sc, n)
    ref = tree_reference(sc, n, depth)
    base = RenderSettings(width=TREE_W, height=TREE_H, max_recursion_depth=depth, max_prims=4)
    bf = gl_renderer.render(scene, base.with_(method="bruteforce"))
    for method in ("bvh", "kdtree"):
        g = gl_renderer.render(scene, base.with_(method=method))
        assert np.isfinite(g.image).all()
        agree_bf = (g.primid == bf.primid).mean()
        assert agree_bf >= 0.9999, f"{method}: ids agree with brute force on {agree_bf:.6f}"
        agree_ref = (g.primid == ref.primid).mean()
        assert agree_ref >= 0.999, f"{method}: ids agree with the reference on {agree_ref:.5f}"
        p = psnr(g.image_u8(), ref.image_u8())
        assert p >= 40.0, f"{method}: colour PSNR {p:.1f} dB < 40"
        assert g.stats["method"] == method


def test_gpu_refit_after_incoherent_motion_is_exact(gl_renderer):
    """Refit keeps a tree valid whatever the motion: ids equal brute force frame after frame."""
    rng = np.random.default_rng(5)
    s0 = scenario(2, 512, seed=2)
    base = RenderSettings(width=TREE_W, height=TREE_H, max_recursion_depth=3, max_prims=4)
    for scheme in ("refit", "selective"):
        c = s0.sphere_centers
        for frame in range(3):
            scene = Scene(s0.camera, s0.lights, s0.materials, c, s0.sphere_radii, s0.sphere_materials, s0.planes)
            g = gl_renderer.render(scene, base.with_(method="bvh", update=scheme), key=("teleport", scheme))
            bf = gl_renderer.render(scene, base.with_(method="bruteforce"))
            agree = (g.primid == bf.primid).mean()
            assert agree >= 0.9999, f"{scheme}, frame {frame}: {agree:.6f}"
            if frame:
                assert g.stats["scheme"] == scheme
            c = rng.uniform(-20, 20, c.shape)  # every sphere teleports


# -------------------------------------------------------------------- animated scenes

FRAMES = [0.0, 0.4, 0.8, 1.2, 1.6, 2.0]


@pytest.mark.parametrize("kind", ["rigid", "deformable", "incoherent"])
def test_every_frame_matches_brute_force(gl_renderer, kind):
    anim = museum(64, kind, seed=3)
    base = RenderSettings(width=64, height=96, max_recursion_depth=3, max_prims=4)
    variants = [("bvh", "refit"), ("bvh", "selective"), ("twolevel", "selective")]
    for t in FRAMES:
        bf = gl_renderer.render(anim, base.with_(method="bruteforce", time=t))
        assert (bf.primid >= 0).mean() > 0.5
        for method, scheme in variants:
            g = gl_renderer.render(
                anim, base.with_(method=method, time=t, update=scheme), key=("test", kind, method, scheme)
            )
            agree = (g.primid == bf.primid).mean()
            assert agree >= 0.9999, f"{kind} t={t} {method}/{scheme}: ids agree on {agree:.6f}"
            assert np.isfinite(g.image).all()
            assert g.stats["time"] == t and "update" in g.timings and "pose" in g.timings
            scheme_used = (g.stats["bvh"] if method == "twolevel" else g.stats)["scheme"]
            assert scheme_used.startswith(scheme), scheme_used
        if kind != "incoherent" and t > 0:
            assert g.stats["kd_cached"], "the static kd-tree is built once"


MESH_W, MESH_H = 160, 120
GLASS = Material(
    color=(1.0, 1.0, 1.0),
    ambient=0.05,
    diffuse=0.05,
    specular=0.3,
    shininess=80.0,
    reflective=0.1,
    transmissive=0.8,
    ior=1.5,
)
MIRROR = Material(
    color=(0.9, 0.9, 0.9),
    ambient=0.05,
    diffuse=0.2,
    specular=0.5,
    shininess=40.0,
    reflective=0.6,
    transmissive=0.0,
    ior=1.0,
)
MATTE = Material(
    color=(0.8, 0.3, 0.2),
    ambient=0.1,
    diffuse=0.8,
    specular=0.2,
    shininess=20.0,
    reflective=0.0,
    transmissive=0.0,
    ior=1.0,
)


def placed(x: float, y: float, z: float, s: float = 1.0) -> list:
    return [[s, 0.0, 0.0, x], [0.0, s, 0.0, y], [0.0, 0.0, s, z], [0.0, 0.0, 0.0, 1.0]]


def mixed_scene(smooth: bool = True) -> Scene:
    """Spheres of three radii, a floor plane and five meshes (a smooth teapot, a glass
    icosphere, a mirror box, a torus, a flat icosphere), overlapping each other and the
    spheres, filling most of the view: every kind of primitive and id."""
    rng = np.random.default_rng(5)
    centers = rng.uniform([-18, -14, -12], [18, 14, 4], (24, 3))
    radii = rng.choice([1.0, 1.5, 2.5], 24)
    mats = rng.integers(0, 3, 24).astype(np.int32)
    meshes = (
        teapot(4, size=4.0, material=2, smooth=smooth, transform=placed(0.0, -20.0, 0.0)),
        icosphere(2, radius=6.0, center=(-10.0, -6.0, 8.0), material=1, smooth=smooth),
        box((6.0, -18.0, 2.0), (14.0, -8.0, 10.0), material=0),
        torus(5.0, 1.6, 24, 12, center=(9.0, 6.0, 4.0), material=2, smooth=smooth),
        icosphere(1, radius=2.5, center=(-2.0, 8.0, 12.0), material=2, smooth=False),
    )
    return Scene(
        Camera((0.0, 2.0, 42.0), (0.0, -4.0, 0.0), (0.0, 1.0, 0.0), 62.0),
        (Light((20.0, 40.0, 30.0), (1.0, 1.0, 1.0)), Light((-25.0, 10.0, 20.0), (0.4, 0.4, 0.5))),
        (MIRROR, GLASS, MATTE),
        centers,
        radii,
        mats,
        (Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 2),),
        meshes,
    )


@pytest.fixture(scope="module")
def scene() -> Scene:
    return mixed_scene()


@pytest.fixture(scope="module")
def cpu_ids(scene) -> np.ndarray:
    o, d = primary_rays(scene.camera, MESH_W, MESH_H)
    _, ids = trace_tree(None, scene, o, d)
    return np.asarray(ids).reshape(MESH_H, MESH_W)


@pytest.fixture(scope="module")
def reference(scene):
    cache = {}

    def get(mode: str, method: str = "bih", sc: Scene | None = None, depth: int = 5):
        key = (mode, method, id(sc), depth)
        if key not in cache:
            s = RenderSettings(
                width=MESH_W, height=MESH_H, mode=mode, method=method, max_recursion_depth=depth, max_prims=4
            )
            cache[key] = render_reference(scene if sc is None else sc, s)
        return cache[key]

    return get


@pytest.fixture(scope="module")
def textures_only(gl_renderer) -> GLRenderer:
    """The device's layout: every record array a texture (none in a uniform block)."""
    return GLRenderer(gl_renderer.ctx, uniform_blocks=False)


def settings(**kw) -> RenderSettings:
    return RenderSettings(**{"width": MESH_W, "height": MESH_H, "max_recursion_depth": 5, "max_prims": 4, **kw})


@pytest.fixture(scope="module")
def primid_frames(gl_renderer, textures_only, scene):
    """The scene's primid frame per method, with record arrays in uniform blocks where they fit
    (``blocks``) or in textures only, rendered once for the tests that read it."""
    cache = {}

    def get(method: str, blocks: bool = True):
        if (method, blocks) not in cache:
            r = gl_renderer if blocks else textures_only
            cache[method, blocks] = r.render(scene, settings(mode="primid", method=method))
        return cache[method, blocks]

    return get


def test_the_scene_has_every_kind_of_primitive_in_view(scene, cpu_ids):
    base = scene.triangle_id_base
    assert scene.n_spheres == 24 and len(scene.planes) == 1 and scene.n_triangles > 2000
    assert len(set(scene.sphere_radii.tolist())) == 3, "different radii: 32-byte sphere records and slots"
    assert (cpu_ids >= base).mean() > 0.15 and ((cpu_ids >= 0) & (cpu_ids < base - 1)).mean() > 0.03
    assert (cpu_ids == base - 1).mean() > 0.05 and (cpu_ids == -1).any()
    for m in range(len(scene.meshes)):  # every mesh is seen
        r = scene.mesh_triangle_range(m)
        assert ((cpu_ids >= base + r.start) & (cpu_ids < base + r.stop)).sum() > 20, m


ONE_PASS = ("bih", "bruteforce", "bvh", "kdtree", "twolevel")


@pytest.mark.parametrize("method,blocks", [*((m, b) for m in ONE_PASS for b in (True, False)), ("auto", True)])
def test_primary_ids_match_the_reference_and_cpu_brute_force(primid_frames, cpu_ids, reference, method, blocks):
    g = primid_frames(method, blocks)
    assert g.stats["method"] == ("bih" if method == "auto" else method)
    assert "TRIANGLES" in g.stats["shader_features"] and "SMOOTH_TRIANGLES" in g.stats["shader_features"]
    assert bool(g.stats["blocks"]) == blocks or (blocks and method == "bvh")  # (its nodes are 64 B: a texture)
    ref = reference("primid")
    agree_ref = (g.primid == ref.primid).mean()
    agree_cpu = (g.primid == cpu_ids).mean()
    assert agree_ref >= 0.999, f"{method}: ids agree with the reference on {agree_ref:.5f}"
    assert agree_cpu >= 0.9999, f"{method}: ids agree with the CPU brute force on {agree_cpu:.6f}"
    hit = (g.primid == ref.primid) & (ref.primid >= 0)
    rel = np.abs(g.depth[hit] - ref.depth[hit]) / ref.depth[hit]
    assert rel.max() <= 1e-4, f"{method}: depth off by {rel.max():.2e} relative"


def test_the_methods_agree_with_each_other(primid_frames):
    b = primid_frames("bruteforce").primid
    for method in ("bih", "bvh", "kdtree", "twolevel"):
        a = primid_frames(method).primid
        assert (a == b).mean() >= 0.9999, method


def test_twolevel_with_moving_meshes_and_spheres(gl_renderer, scene, cpu_ids, reference):
    """Both of twolevel's trees hold spheres and triangles: the first mesh and every third
    sphere in the BVH, the rest in the kd-tree."""
    from renderer.config.methods import METHODS
    from renderer.scenes.tree_update import TreeUpdate

    moving = np.zeros(scene.n_spheres + scene.n_triangles, bool)
    moving[: scene.n_spheres : 3] = True
    r = scene.mesh_triangle_range(0)
    moving[scene.n_spheres + r.start : scene.n_spheres + r.stop] = True
    prep = METHODS["twolevel"].prepare(scene, 4, 64, update=TreeUpdate(moving=moving))
    g = gl_renderer.render(scene, settings(mode="primid", method="twolevel"), prepared=prep)
    assert (g.primid == cpu_ids).mean() >= 0.9999
    assert (g.primid == reference("primid").primid).mean() >= 0.999


@pytest.mark.parametrize("method", ONE_PASS)
@pytest.mark.parametrize("mode", ["color", "normal", "depth", "recursion"])
def test_modes_match_the_reference(gl_renderer, scene, reference, method, mode):
    g = gl_renderer.render(scene, settings(mode=mode, method=method))
    ref = reference(mode)
    assert np.isfinite(g.image).all(), "NaN or inf in the image"
    if mode == "recursion":
        same = (g.image_u8() == ref.image_u8()).all(axis=2)
        assert same.mean() >= 0.995, f"recursion levels agree on {same.mean():.4f}"
        assert len({tuple(c) for c in ref.image_u8().reshape(-1, 3)}) >= 4, "rays through the glass: deep levels"
    elif mode == "color":
        p = psnr(g.image_u8(), ref.image_u8())
        assert p >= 40.0, f"{method}: colour PSNR {p:.1f} dB < 40"
    else:
        ok = g.primid == ref.primid
        diff = np.abs(g.image.astype(np.float64) - ref.image)[ok]
        assert ok.mean() >= 0.999 and np.quantile(diff, 0.999) <= 2e-3, f"{mode}: max diff {diff.max():.2e}"


@pytest.fixture(scope="module")
def teapot_normals():
    """The teapot scene, smooth or flat, and its reference normal frame (each made once: the
    test of one shading compares with the other's too)."""
    cache = {}

    def get(smooth: bool):
        if smooth not in cache:
            sc = mesh_scene("teapot", 2, smooth=smooth)
            cache[smooth] = sc, render_reference(sc, settings(mode="normal", method="bih"))
        return cache[smooth]

    return get


@pytest.mark.parametrize("smooth", [True, False])
def test_flat_and_smooth_normals_match_the_reference(gl_renderer, teapot_normals, smooth):
    """The normal image is the shading normal: the blend of vertex normals on a smooth mesh,
    the geometric normal on a flat one; the two differ (the blend is really used)."""
    sc, ref = teapot_normals(smooth)
    s = settings(mode="normal", method="bih")
    g = gl_renderer.render(sc, s)
    assert (g.primid == ref.primid).mean() >= 0.999
    ok = (g.primid == ref.primid) & (ref.primid >= sc.triangle_id_base)  # the teapot's pixels
    assert ok.sum() > 0.05 * MESH_W * MESH_H
    err = np.abs(g.normal[ok].astype(np.float64) - ref.normal[ok]).max(axis=1)
    assert np.quantile(err, 0.999) <= 1e-3, f"smooth={smooth}: normals off by {err.max():.2e}"
    _, other = teapot_normals(not smooth)
    both = ok & (other.primid == ref.primid)
    # flat and smooth differ by more than 1e-2 on most of the teapot (0.97 of its pixels)
    assert (np.abs(other.normal[both] - ref.normal[both]).max(axis=1) > 1e-2).mean() > 0.8


def test_refraction_through_a_closed_glass_mesh_matches_the_reference(gl_renderer):
    """The room: a glass icosphere (entering and leaving by the geometric normal), a teapot,
    walls wound inwards, seen from inside."""
    for smooth in (False, True):
        sc = mesh_scene("room", 2, smooth=smooth)
        s = settings(mode="color", method="bih")
        p = psnr(gl_renderer.render(sc, s).image_u8(), render_reference(sc, s).image_u8())
        assert p >= 40.0, f"smooth={smooth}: colour PSNR {p:.1f} dB < 40"


def test_heat_counts_match_the_cpu_traversal(gl_renderer, scene, reference):
    """Fig. 4.3's counters, a triangle test counting as a sphere test, against the reference's
    (the BIH's CPU traversal on the same records)."""
    g = gl_renderer.render(scene, settings(mode="heat", method="bih")).image_u8()
    ref = reference("heat").image_u8()
    same = (g == ref).all(axis=2)
    assert same.mean() >= 0.99, f"heat images agree on {same.mean():.4f}"
    assert (g[..., 0] > 0).mean() > 0.3


# ---- watertightness ---------------------------------------------------------------------------
def closed_meshes() -> dict[str, object]:
    return {
        "icosphere": icosphere(2, radius=3.0, center=(0.25, -0.5, 0.125)),
        "box": box((-2.0, -2.0, -2.0), (2.0, 2.0, 2.0)),
        "teapot": teapot(4, size=1.2, transform=placed(0.0, -1.5, 0.0)),
    }


def directions(count: int) -> np.ndarray:
    """Camera directions: the six axes and eight diagonals (the box's edges and vertices line
    up with pixel-centre rays there), then a Fibonacci sphere."""
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0.001], [0, -1, 0.001], [0, 0, 1], [0, 0, -1]], float)
    diag = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    k = np.arange(count) + 0.5
    phi = np.arccos(1 - 2 * k / count)
    theta = np.pi * (1 + 5**0.5) * k
    fib = np.stack([np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)], axis=1)
    out = np.concatenate([axes, diag, fib])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def leak_views():
    """The closed meshes' views of the test below and their reference primary ids, made once for
    every method (the reference's ids do not depend on the method: only its heat image does)."""
    cache = {}

    def get(kind: str, w: int, h: int) -> list[tuple[Scene, np.ndarray]]:
        if kind not in cache:
            mesh = closed_meshes()[kind]
            views = []
            for i, d in enumerate(directions(10)):
                pos = tuple(float(x) for x in 9.0 * d)
                up = (0.0, 0.0, 1.0) if abs(d[1]) > 0.9 else (0.0, 1.0, 0.0)
                sc = Scene(
                    Camera(pos, (0.0, 0.0, 0.0), up, 40.0 if i % 2 else 37.0),
                    (),
                    (MATTE,),
                    np.zeros((0, 3)),
                    np.zeros(0),
                    np.zeros(0, np.int32),
                    (),
                    (mesh,),
                )
                s = RenderSettings(width=w, height=h, mode="primid", method="bruteforce", max_prims=4)
                views.append((sc, render_reference(sc, s).primid))
            cache[kind] = views
        return cache[kind]

    return get


@pytest.mark.parametrize("kind", ["icosphere", "box", "teapot"])
@pytest.mark.parametrize("method", ONE_PASS)
def test_no_ray_leaks_through_a_closed_mesh(gl_renderer, leak_views, kind, method):
    w = h = 48
    leaks = differ = inside_total = 0
    for sc, ref in leak_views(kind, w, h):
        s = RenderSettings(width=w, height=h, mode="primid", method=method, max_prims=4)
        g = gl_renderer.render(sc, s).primid
        hit = ref >= 0
        pad = np.pad(hit, 1)
        inside = np.ones_like(hit)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                inside &= pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        leaks += int((inside & (g < 0)).sum())
        differ += int((hit != (g >= 0)).sum())
        inside_total += int(inside.sum())
        assert ((g < 0) | (g >= sc.triangle_id_base)).all()
    assert inside_total > 5000
    assert leaks == 0, f"{kind}/{method}: {leaks} rays strictly inside the silhouette went through the mesh"
    assert differ <= 0.002 * inside_total, f"{kind}/{method}: {differ} pixels disagree on hit or miss"


def test_zero_area_triangles_keep_their_ids_and_are_never_hit(gl_renderer):
    """A collinear triangle and one with a repeated corner (kept, so ids do not move) lie
    across the view in front of a box: flagged TRI_DEGENERATE in their records, never hit
    on the GPU, the box behind them seen as the reference sees it."""
    from renderer.geometry.scene import Mesh
    from renderer.gpu import gpu_layout

    sliver = Mesh(
        np.array([[-5.0, 0.0, 0.0], [0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 3.0, 0.0]]),
        [[0, 1, 2], [0, 3, 3], [0, 1, 3]],
    )  # collinear, repeated corner, a real one
    cube = box((-6.0, -6.0, -9.0), (6.0, 6.0, -7.0))
    sc = Scene(
        Camera((0.0, 0.0, 12.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0),
        (),
        (MATTE,),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        (),
        (sliver, cube),
    )
    assert sc.n_degenerate_triangles == 2
    rec = gpu_layout.triangle_records(sc).reshape(-1, 3, 4)
    np.testing.assert_array_equal((rec[:, 0, 3] & np.uint32(gpu_layout.TRI_DEGENERATE)) != 0, sc.triangle_degenerate)
    ref = render_reference(sc, RenderSettings(width=65, height=33, mode="primid", max_prims=2)).primid
    for method in ONE_PASS:
        s = RenderSettings(width=65, height=33, mode="primid", method=method, max_prims=2)
        g = gl_renderer.render(sc, s).primid
        assert not np.isin(g, [0, 1]).any(), method
        assert (g == 2).sum() > 20 and (g >= 3).any()
        # This odd-sized grid has rays exactly along the box's face diagonals (both triangles
        # hit at t equal in float64, not in float32: either may win) and along the real
        # triangle's open edge x = 0 (the reference's exact edge function is 0 there, float32's
        # may fall either side): those pixels may differ, 0.5 % of them here.
        assert (g == ref).mean() >= 0.99, method


FEATURES = ("NO_REFLECTION", "NO_TRANSMISSION", "NO_LIGHTS")
FEATURE_SETS = [
    tuple(f for f, on in zip(FEATURES, bits, strict=True) if on) for bits in itertools.product((0, 1), repeat=3)
]
# Data formats and compiled-in counts, each with some of the removals (features' order).
SHAPES = [
    ("EQUAL_RADII",),
    ("MATERIAL_TEXTURE",),
    ("NO_SPLIT", "PLANES_1", "LIGHTS_2", "EQUAL_RADII"),
    ("NO_LIGHTS", "PLANES_0", "MATERIAL_TEXTURE"),
    ("NO_REFLECTION", "PLANES_3", "LIGHTS_1"),
]


def check_variant(gl_renderer, variant: Variant) -> None:
    prog, _ = gl_renderer.program(
        variant.method,
        variant.mode,
        variant.depth,
        variant.features,
        variant.blocks,
        variant.image_only,
        variant.spheres,
    )
    declared = full = {b.name for b in tracer_bindings(variant)}
    if variant.image_only and variant.mode == "heat" and METHODS[variant.method].capabilities.tests_every_sphere:
        # Brute force's heat image is n sphere tests whatever the ray, and an image-only
        # variant writes nothing else: the compiler drops the ray and what makes it.
        declared = {
            n
            for n in declared
            if not n.startswith(
                (
                    "u_cam_",
                    "u_plane_",
                    "u_num_planes",
                    "u_half_",
                    "u_resolution",
                    "u_pass_",
                    "u_bf_",
                    "u_sphere_",
                    "u_tri",
                )
            )
        }
    assert declared <= active(prog), (variant, sorted(declared - active(prog)))
    assert active(prog) & known_bindings() <= full, variant
    for b in tracer_bindings(variant):
        if b.records:
            if b.name not in active(prog):
                continue
            kind = "UniformBlock" if b.name in variant.blocks else "Uniform"
            assert type(prog[b.name]).__name__ == kind, (variant, b.name, type(prog[b.name]))


# The triangles' data formats, for the methods that trace meshes on the GPU.
TRIANGLE_SHAPES = [
    ("TRIANGLES",),
    ("EQUAL_RADII", "TRIANGLES", "SMOOTH_TRIANGLES"),
    ("NO_SPLIT", "PLANES_1", "LIGHTS_1", "MATERIAL_TEXTURE", "TRIANGLES", "SMOOTH_TRIANGLES"),
]


@pytest.mark.parametrize("method", ONE_PASS)
@pytest.mark.parametrize("mode", SINGLE_PASS_MODES)
def test_every_declared_binding_of_every_variant_is_active(gl_renderer_released_after, method, mode):
    gl_renderer = gl_renderer_released_after  # ~60 variants a case, each compiled to be read once
    records = tuple(b.name for b in METHODS[method].bindings if b.records and b.needs is None)
    for depth, features in itertools.product((1, 2, 8), FEATURE_SETS + SHAPES):
        check_variant(gl_renderer, Variant(method, mode, depth, features))
    for depth, features, image in itertools.product((1, 3), SHAPES[:3], (False, True)):
        check_variant(gl_renderer, Variant(method, mode, depth, features, records, image))
        check_variant(gl_renderer, Variant(method, mode, depth, features, records[:1], image))
        if mode != "heat":  # the background variant reads none of the method's
            check_variant(gl_renderer, Variant(method, mode, depth, features, (), image, spheres=False))
    if not METHODS[method].capabilities.meshes_on_gpu:
        return
    for depth, features, image in itertools.product((1, 3), TRIANGLE_SHAPES, (False, True)):
        v = Variant(method, mode, depth, features, (), image)
        blocks = tuple(b.name for b in tracer_bindings(v) if b.records)  # every record array it reads
        check_variant(gl_renderer, Variant(method, mode, depth, features, (), image))
        check_variant(gl_renderer, Variant(method, mode, depth, features, blocks, image))
        if mode != "heat":
            check_variant(gl_renderer, Variant(method, mode, depth, features, (), image, spheres=False))


def test_record_arrays_in_blocks_are_the_renderers_choice(gl_renderer):
    """A record array that fits 64 KiB is read from a uniform block, a larger one from a
    texture; a renderer without blocks uses textures only; the device's data are textures."""
    from renderer.gl import GLRenderer

    small = gl_renderer.render(scenario(3, 1024), RenderSettings(width=8, height=8, format="npy"))
    assert set(small.stats["blocks"]) == {"u_bih_nodes", "u_bih_spheres"}
    big = gl_renderer.render(scenario(3, 8192), RenderSettings(width=8, height=8, format="npy"))
    assert big.stats["blocks"] == ["u_bih_nodes"], "8,192 sphere records are 128 KiB: a texture"
    bvh = gl_renderer.render(scenario(3, 4096), RenderSettings(width=8, height=8, method="bvh", format="npy"))
    assert bvh.stats["blocks"] == ["u_bvh_spheres"], "4 records per inner node: 4,095 × 64 B is a texture"
    tex = GLRenderer(gl_renderer.ctx, uniform_blocks=False).render(scenario(3, 64), RenderSettings(width=8, height=8))
    assert tex.stats["blocks"] == []


def test_a_misspelt_packed_name_is_an_error(gl_renderer, monkeypatch):
    """The renderer refuses a packed name no layout declares instead of skipping it."""
    real = gpu_layout.pack_primitives

    def misspelt(scene, max_width=gpu_layout.DEFAULT_TEXTURE_WIDTH):
        packed = real(scene, max_width)
        packed.uniforms["u_num_sphere"] = packed.uniforms.pop("u_num_spheres")
        return packed

    monkeypatch.setattr(gpu_layout, "pack_primitives", misspelt)
    with pytest.raises(KeyError, match="u_num_sphere"):
        gl_renderer.render(scenario(1, 8), RenderSettings(width=8, height=8, method="bruteforce"))
