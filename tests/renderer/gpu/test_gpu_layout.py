"""What the GPU reads (renderer.gpu.gpu_layout), checked without a GPU.

- ``wrap_rows``: element i at texel (i % w, i // w), widths a power of two and no wider
  than needed, ``max_width`` rounded down to a power of two, the same width for arrays of
  the same count (spheres and their materials share an index), one zero texel for an
  empty array, an error beyond max_width², the dtype codes;
- ``pack_primitives``: the sphere, material (3 texels each) and sphere-material textures,
  and the plane and light uniform arrays padded to the length the shader declares;
- ``camera_uniforms``: an orthonormal basis looking at the target, half extent
  tan(fov/2)·(W/H, 1).

The shader reads these layouts through the same module, so a test here that had to change
would also change the frames of ``tests/golden/frames.npz``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer.config.methods import METHODS
from renderer.geometry.scene import Camera, Light, Material, Plane, Scene
from renderer.gpu import gpu_layout
from renderer.gpu.gpu_layout import (
    MATERIAL_TEXELS,
    PackedTexture,
    Variant,
    camera_uniforms,
    glsl_header,
    pack_primitives,
    wrap_rows,
)
from renderer.limits import DEFAULT_TEXTURE_WIDTH, MAX_LIGHTS, MAX_PLANES, MAX_TREE_DEPTH
from renderer.scenes.scenarios import mesh_scene, scenario


def elements(count: int, comps: int = 4, dtype=np.float32) -> np.ndarray:
    """Distinct, non-zero rows: element i is (i + 1, i + 1.25, …), so padding (zeros) shows."""
    return (np.arange(count)[:, None] + 1 + 0.25 * np.arange(comps)[None, :]).astype(dtype)


def texel(tex: PackedTexture, i: int) -> np.ndarray:
    """Element i as the shader addresses it: texel (i % w, i / w), i.e. data[row = i // w, column = i % w]."""
    w, _ = tex.size
    return tex.data[i // w, i % w]


# ------------------------------------------------------------------------------- wrap_rows


@pytest.mark.parametrize(
    "count,max_width",
    [(c, w) for c in (1, 2, 3, 7, 8, 9, 63, 64, 65, 100, 1000) for w in (1, 4, 16, 64, 4096) if c <= w * w],
)
def test_element_i_is_texel_i_mod_w_i_div_w(count, max_width):
    e = elements(count)
    tex = wrap_rows(e, max_width)
    w, h = tex.size
    assert tex.data.shape == (h, w, 4) and tex.components == 4
    assert w * h >= count and h == -(-count // w)
    for i in range(count):
        np.testing.assert_array_equal(texel(tex, i), e[i])
    # the rest of the last row is zero padding
    assert (tex.data.reshape(-1, 4)[count:] == 0).all()


@pytest.mark.parametrize("count", [1, 2, 3, 5, 31, 32, 33, 4095, 4096, 4097, 100_000])
def test_width_is_the_smallest_power_of_two_that_holds_a_row(count):
    tex = wrap_rows(elements(count, 1), DEFAULT_TEXTURE_WIDTH)
    w, h = tex.size
    assert w & (w - 1) == 0, f"width {w} is not a power of two"
    smallest = 1
    while smallest < count:
        smallest *= 2
    assert w == min(DEFAULT_TEXTURE_WIDTH, smallest)
    if count <= DEFAULT_TEXTURE_WIDTH:
        assert h == 1 and (count == 0 or w < 2 * count), "one row, no wider than the next power of two"
    else:
        assert w == DEFAULT_TEXTURE_WIDTH and h == -(-count // w)


@pytest.mark.parametrize(
    "max_width,effective", [(1, 1), (2, 2), (3, 2), (100, 64), (128, 128), (4095, 2048), (4096, 4096), (5000, 4096)]
)
def test_max_width_is_rounded_down_to_a_power_of_two(max_width, effective):
    rows = min(effective, 4)  # enough elements for full rows, within effective²
    tex = wrap_rows(elements(effective * rows, 1), max_width)
    assert tex.size == (effective, rows)


def test_arrays_of_the_same_count_get_the_same_width():
    """Spheres (4 floats) and their materials (1 uint) share an index: same texel, same i."""
    for count in (1, 5, 64, 65, 3000):
        for max_width in (8, 64, 4096):
            if count > max_width**2:
                continue
            a = wrap_rows(elements(count, 4, np.float32), max_width)
            b = wrap_rows(elements(count, 1, np.uint32), max_width)
            c = wrap_rows(elements(count, 2, np.float32)[:, 0], max_width)  # 1-D
            assert a.size == b.size == c.size, (count, max_width)


@pytest.mark.parametrize(
    "shape,dtype", [((0, 4), np.float32), ((0,), np.uint32), ((0, 1), np.uint32)], ids=["rgba-f4", "1d-u4", "r-u4"]
)
def test_an_empty_array_is_a_single_zero_texel(shape, dtype):
    tex = wrap_rows(np.zeros(shape, dtype))  # textures cannot be empty
    comps = shape[1] if len(shape) > 1 else 1
    assert tex.size == (1, 1) and tex.data.shape == (1, 1, comps)
    assert (tex.data == 0).all() and tex.data.dtype == dtype


@pytest.mark.parametrize("max_width", [1, 16, 20, 64])
def test_more_than_max_width_squared_elements_is_an_error(max_width):
    side = 1 << (max_width.bit_length() - 1)  # what max_width is rounded down to
    full = wrap_rows(elements(side * side, 1), max_width)
    assert full.size == (side, side)
    with pytest.raises(ValueError, match=f"{side * side + 1} elements do not fit a {side}×{side} texture"):
        wrap_rows(elements(side * side + 1, 1), max_width)


def test_dtype_codes_and_one_dimensional_input():
    f = wrap_rows(np.array([1.5, 2.5], np.float32))
    u = wrap_rows(np.array([7, 8, 9], np.uint32))
    assert (f.dtype, f.data.dtype, f.components) == ("f4", np.float32, 1)
    assert (u.dtype, u.data.dtype, u.components) == ("u4", np.uint32, 1)
    assert f.data[0, :, 0].tolist() == [1.5, 2.5] and u.data[0, :, 0].tolist() == [7, 8, 9, 0]


# -------------------------------------------------------------------------- pack_primitives


def small_scene() -> Scene:
    mats = (
        Material(
            color=(0.1, 0.2, 0.3),
            ambient=0.4,
            diffuse=0.5,
            specular=0.6,
            shininess=7.0,
            reflective=0.8,
            transmissive=0.0,
            ior=1.0,
        ),
        Material(
            color=(0.9, 0.8, 0.7),
            ambient=0.05,
            diffuse=0.25,
            specular=0.125,
            shininess=64.0,
            reflective=0.0,
            transmissive=0.75,
            ior=1.5,
        ),
    )
    centers = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, -6.0], [0.0, 0.0, 1e6], [7.0, -8.0, 9.0], [0.5, 0.5, 0.5]])
    return Scene(
        Camera(),
        (Light((0.0, 40.0, 0.0), (1.0, 0.5, 0.25)), Light((3.0, 4.0, 5.0), (0.2, 0.2, 0.2))),
        mats,
        centers,
        np.array([1.0, 0.5, 2.0, 0.25, 3.0]),
        np.array([1, 0, 1, 1, 0]),
        (Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 1), Plane((0.0, 0.0, -50.0), (0.0, 0.0, 2.0), 0)),
    )


def test_pack_primitives_textures():
    scene = small_scene()
    packed = pack_primitives(scene, max_width=4)
    t = packed.textures
    assert set(t) == {"u_spheres", "u_sphere_mat", "u_materials"}
    assert (t["u_spheres"].dtype, t["u_sphere_mat"].dtype, t["u_materials"].dtype) == ("f4", "u4", "f4")
    assert t["u_spheres"].size == t["u_sphere_mat"].size == (4, 2)  # 5 spheres, rows of 4
    for i in range(scene.n_spheres):
        np.testing.assert_array_equal(
            texel(t["u_spheres"], i), np.float32([*scene.sphere_centers[i], scene.sphere_radii[i]])
        )
        assert texel(t["u_sphere_mat"], i).tolist() == [int(scene.sphere_materials[i])]
    assert MATERIAL_TEXELS == 3
    for k, m in enumerate(scene.materials):
        got = [texel(t["u_materials"], MATERIAL_TEXELS * k + j).tolist() for j in range(MATERIAL_TEXELS)]
        want = [
            [*m.color, m.ambient],
            [m.diffuse, m.specular, m.shininess, m.reflective],
            [m.transmissive, m.ior, 0.0, 0.0],
        ]
        np.testing.assert_array_equal(np.float32(got), np.float32(want))
    assert packed.nbytes == sum(x.data.nbytes for x in t.values())


def test_pack_primitives_uniforms_are_padded_to_the_shader_arrays():
    scene = small_scene()
    u = pack_primitives(scene).uniforms
    assert (u["u_num_spheres"], u["u_num_planes"], u["u_num_lights"]) == (5, 2, 2)
    for name in ("u_plane_point", "u_plane_normal", "u_plane_mat"):
        assert len(u[name]) == MAX_PLANES, name
    for name in ("u_light_pos", "u_light_color"):
        assert len(u[name]) == MAX_LIGHTS, name
    assert u["u_plane_point"] == [(0.0, -20.0, 0.0), (0.0, 0.0, -50.0)] + [(0.0, 0.0, 0.0)] * (MAX_PLANES - 2)
    # normals arrive unit length (the scene normalises them); the padding is a valid normal too
    assert u["u_plane_normal"] == [(0.0, 1.0, 0.0), (0.0, 0.0, 1.0)] + [(0.0, 1.0, 0.0)] * (MAX_PLANES - 2)
    assert u["u_plane_mat"] == [1, 0] + [0] * (MAX_PLANES - 2)
    assert u["u_light_pos"] == [(0.0, 40.0, 0.0), (3.0, 4.0, 5.0)] + [(0.0, 0.0, 0.0)] * (MAX_LIGHTS - 2)
    assert u["u_light_color"] == [(1.0, 0.5, 0.25), (0.2, 0.2, 0.2)] + [(0.0, 0.0, 0.0)] * (MAX_LIGHTS - 2)


def test_pack_primitives_of_a_scene_without_spheres_planes_or_lights():
    scene = Scene(Camera(), (), (Material(),), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    packed = pack_primitives(scene)
    spheres, mats = packed.textures["u_spheres"], packed.textures["u_sphere_mat"]
    assert spheres.size == mats.size and spheres.data.size > 0  # textures cannot be empty
    assert (spheres.data == 0).all() and (mats.data == 0).all()
    u = packed.uniforms
    assert (u["u_num_spheres"], u["u_num_planes"], u["u_num_lights"]) == (0, 0, 0)
    assert len(u["u_plane_point"]) == MAX_PLANES and len(u["u_light_pos"]) == MAX_LIGHTS


# ------------------------------------------------------------------------- camera_uniforms


@pytest.mark.parametrize(
    "position,target,up,fov",
    [
        ((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0),
        ((3.0, -7.0, 12.0), (-1.0, 2.0, 0.5), (0.0, 0.0, 1.0), 35.0),
        ((1e6, 1e6, 1e6), (1e6 + 1.0, 1e6 - 2.0, 1e6 + 0.5), (0.3, 1.0, -0.2), 110.0),
    ],
)
@pytest.mark.parametrize("width,height", [(320, 544), (640, 480), (1, 1)])
def test_camera_uniforms(position, target, up, fov, width, height):
    u = camera_uniforms(Camera(position=position, target=target, up=up, fov_y=fov), width, height)
    right, cup, forward = (np.array(u[k]) for k in ("u_cam_right", "u_cam_up", "u_cam_forward"))
    basis = np.stack([right, cup, forward])
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-12)  # orthonormal
    to_target = np.subtract(target, position)
    np.testing.assert_allclose(forward, to_target / np.linalg.norm(to_target), atol=1e-12)
    assert cup @ np.array(up) > 0, "the image's up is on the side of the camera's up"
    np.testing.assert_allclose(np.cross(right, cup), -forward, atol=1e-12)  # right-handed, looking down −z
    s = math.tan(math.radians(fov) / 2)
    assert u["u_half_extent"] == pytest.approx((s * width / height, s), rel=1e-15)
    assert u["u_resolution"] == (float(width), float(height))
    assert u["u_cam_pos"] == tuple(float(x) for x in position)
    assert u["u_target_distance"] == pytest.approx(float(np.linalg.norm(to_target)), rel=1e-12)


def test_glsl_header_states_the_tracers_constants():
    header = glsl_header().splitlines()
    assert header == [
        f"#define MAX_PLANES {MAX_PLANES}",
        f"#define MAX_LIGHTS {MAX_LIGHTS}",
        f"#define MATERIAL_TEXELS {MATERIAL_TEXELS}",
        # the material record's accessors, one per parameter the GPU reads (renderer/materials)
        "#define material_color(m) (MATERIAL_TEXEL(m, 0).xyz)",
        "#define material_ambient(m) (MATERIAL_TEXEL(m, 0).w)",
        "#define material_diffuse(m) (MATERIAL_TEXEL(m, 1).x)",
        "#define material_specular(m) (MATERIAL_TEXEL(m, 1).y)",
        "#define material_shininess(m) (MATERIAL_TEXEL(m, 1).z)",
        "#define material_reflective(m) (MATERIAL_TEXEL(m, 1).w)",
        "#define material_transmissive(m) (MATERIAL_TEXEL(m, 2).x)",
        "#define material_ior(m) (MATERIAL_TEXEL(m, 2).y)",
        "#define material_roughness(m) (MATERIAL_TEXEL(m, 2).z)",
    ]
    # Each traversal stack is one entry per tree level, stated by its method's layout.
    from renderer.accel import bih_layout, bvh_layout, kdtree_layout

    assert f"#define BIH_STACK_SIZE {MAX_TREE_DEPTH}" in bih_layout.glsl_defines().splitlines()
    assert f"#define BVH_STACK_SIZE {MAX_TREE_DEPTH}" in bvh_layout.glsl_defines().splitlines()
    assert f"#define KD_STACK_SIZE {MAX_TREE_DEPTH}" in kdtree_layout.glsl_defines().splitlines()


# ---------------------------------------------------------- records, blocks, variants


def test_sphere_records_are_centres_and_keys_in_the_given_order():
    """Equal radii: one 16-byte record (centre, id | material << 21 | last); otherwise two
    (centre and radius, then the key); the radius of equal ones is the uniform."""
    from renderer.gpu import gpu_layout as G

    scene = small_scene()  # unequal radii
    order = np.array([3, 0, 4, 1, 2])
    last = np.array([False, True, False, False, True])
    rec = G.sphere_records(scene, order, last)
    assert rec.shape == (10, 4) and rec.dtype == np.uint32
    u = G.unpack_sphere_records(rec, equal=False)
    assert u["id"].tolist() == order.tolist() and u["last"].tolist() == last.tolist()
    assert u["material"].tolist() == scene.sphere_materials[order].tolist()
    np.testing.assert_array_equal(u["centre"], scene.sphere_centers[order].astype(np.float32))
    np.testing.assert_array_equal(u["radius"], scene.sphere_radii[order].astype(np.float32))
    assert (rec[1::2, 1:] == 0).all()
    assert rec[1, 0] == (3 | (1 << G.SPHERE_MAT_SHIFT)) and rec[3, 0] == (0 | (1 << 21) | G.SPHERE_LAST)
    assert not G.equal_radii(scene) and pack_primitives(scene).uniforms["u_sphere_radius"] == 0.0

    same = Scene(
        scene.camera,
        scene.lights,
        scene.materials,
        scene.sphere_centers,
        np.full(5, 0.75),
        scene.sphere_materials,
        scene.planes,
    )
    assert G.equal_radii(same) and pack_primitives(same).uniforms["u_sphere_radius"] == 0.75
    rec = G.sphere_records(same, order, last)
    assert rec.shape == (5, 4)
    u = G.unpack_sphere_records(rec, equal=True)
    assert u["id"].tolist() == order.tolist() and u["last"].tolist() == last.tolist()
    np.testing.assert_array_equal(u["centre"], same.sphere_centers[order].astype(np.float32))
    assert G.SPHERE_ID_MASK + 1 >= G.MAX_SPHERES and G.SPHERE_MAT_MASK + 1 >= G.MAX_MATERIALS


def test_leaf_ends_flag_the_last_record_of_each_run():
    from renderer.gpu.gpu_layout import leaf_ends

    assert leaf_ends([0, 3, 4], [3, 1, 2], 6).tolist() == [False, False, True, True, False, True]
    assert leaf_ends([0, 2, 2], [2, 0, 1], 3).tolist() == [False, True, True]  # an empty leaf flags nothing
    assert leaf_ends([], [], 0).tolist() == []


def test_materials_as_uniform_vectors_and_the_empty_box():
    from renderer.gpu import gpu_layout as G

    scene = small_scene()
    u = pack_primitives(scene).uniforms
    vecs = np.float32(u["u_material_vecs"])
    assert vecs.shape == (MATERIAL_TEXELS * G.MAX_UNIFORM_MATERIALS, 4)
    tex = pack_primitives(scene).textures["u_materials"].data.reshape(-1, 4)
    np.testing.assert_array_equal(vecs[: len(scene.materials) * MATERIAL_TEXELS], tex[: len(scene.materials) * 3])
    assert not G.material_texture(scene)
    assert G.box_uniform([np.inf] * 3, [-np.inf] * 3) == ((1.0, 1.0, 1.0), (-1.0, -1.0, -1.0))
    assert G.box_uniform([0, 1, 2], [3, 4, 5]) == ((0.0, 1.0, 2.0), (3.0, 4.0, 5.0))


def test_a_record_array_is_declared_as_a_texture_or_a_uniform_block():
    from renderer.gpu.gpu_layout import Binding, declarations

    b = Binding("u_x", doc="records", records=True)
    tex = declarations([b])
    assert (
        "uniform highp usampler2D u_x;" in tex and "#define u_x_at(i) texelFetch(u_x, texel((i), u_x_shift), 0)" in tex
    )
    assert "#define LAYOUT_INIT() u_x_shift = row_shift(textureSize(u_x, 0));" in tex
    block = declarations([b], blocks=("u_x",))
    assert "layout(std140) uniform u_x { highp uvec4 u_x_rec[BLOCK_RECORDS]; };" in block
    assert "#define u_x_at(i) u_x_rec[i]" in block and "#define LAYOUT_INIT()\n" in block
    assert "usampler2D" not in block


def test_what_a_variant_reads_follows_its_data_formats_and_counts():
    from renderer.gpu import gpu_layout as G

    plain = Variant("bih", "color", 3)
    fixed = Variant("bih", "color", 3, ("PLANES_1", "LIGHTS_2", "EQUAL_RADII", "MATERIAL_TEXTURE"))
    for b, in_plain, in_fixed in (
        (G.NUM_PLANES, True, False),
        (G.NUM_LIGHTS, True, False),
        (G.SPHERE_RADIUS, False, True),
        (G.MATERIALS, False, True),
        (G.MATERIAL_VECS, True, False),
        (G.SPHERES, False, False),
        (G.SPHERE_MAT, False, False),
        (G.PLANE_POINT, True, True),
    ):
        assert (plain.reads_binding(b), fixed.reads_binding(b)) == (in_plain, in_fixed), b.name
    assert not Variant("bih", "depth", 1).reads_binding(G.MATERIAL_VECS)


@pytest.mark.parametrize(
    "position,target,fov",
    [
        ((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), 60.0),
        ((35.0, 28.0, 60.0), (0.0, -3.0, 0.0), 40.0),
        ((-90.0, 5.0, -10.0), (3.0, 1.0, 2.0), 90.0),
        ((0.0, 0.0, 45.0), (0.0, 0.0, 0.0), 120.0),
    ],
)
def test_no_primary_ray_outside_the_spheres_rectangle_meets_a_sphere(position, target, fov):
    """primary_rect bounds the pixels whose primary ray can meet a sphere (the background
    variant draws the rest); None when the camera is inside or beside the spheres' box."""
    from renderer.accel.bih_traverse import brute_force
    from renderer.gpu.gpu_layout import primary_rect
    from renderer.oracle.reference import primary_rays
    from renderer.scenes.scenarios import scenario

    base = scenario(3, 512)
    cam = Camera(position=position, target=target, up=(0.0, 1.0, 0.0), fov_y=fov)
    scene = base.with_camera(cam)
    w, h = 61, 47
    rect = primary_rect(scene, w, h)
    assert rect is not None
    o, d = primary_rays(cam, w, h)
    _, prim = brute_force(scene.sphere_centers, scene.sphere_radii, o, d)
    hit = (prim >= 0).reshape(h, w)[::-1]  # GL rows from the bottom
    x, y, rw, rh = rect
    inside = np.zeros_like(hit)
    inside[y : y + rh, x : x + rw] = True
    assert hit.any() and not (hit & ~inside).any()
    assert 0 <= x and x + rw <= w and 0 <= y and y + rh <= h
    assert primary_rect(scene.with_camera(Camera(position=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0))), w, h) is None
    empty = Scene(cam, (), (Material(),), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    assert primary_rect(empty, w, h) == (0, 0, 0, 0)


@pytest.mark.parametrize(
    "position,target",
    [
        ((0.0, 0.0, 100.0), (0.0, 0.0, 0.0)),
        ((30.0, 45.0, 70.0), (0.0, -5.0, 0.0)),
        ((0.0, -10.0, 80.0), (0.0, 10.0, 0.0)),
    ],
)
@pytest.mark.parametrize("planes", [False, True])
def test_frame_regions_partition_the_frame_and_skip_only_rays_that_meet_nothing(position, target, planes):
    """frame_regions tiles the frame; where it says background, no primary ray meets a sphere,
    and (planes=True: frames whose hits spawn rays) no plane either."""
    from renderer.accel.bih_traverse import brute_force
    from renderer.gpu.gpu_layout import frame_regions
    from renderer.oracle.reference import primary_rays
    from renderer.scenes.scenarios import scenario

    cam = Camera(position=position, target=target, up=(0.0, 1.0, 0.0), fov_y=60.0)
    scene = scenario(2, 256).with_camera(cam)
    scene = Scene(
        cam,
        scene.lights,
        scene.materials,
        scene.sphere_centers,
        scene.sphere_radii,
        scene.sphere_materials,
        (Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 0), Plane((0.0, 0.0, 500.0), (0.0, 0.1, 1.0), 0)),
    )  # behind the camera
    w, h = 57, 75
    regions = frame_regions(scene, w, h, planes)
    assert regions is not None
    cover = np.zeros((h, w), int)
    for x, y, rw, rh, _ in regions:
        cover[y : y + rh, x : x + rw] += 1
    assert (cover == 1).all(), "the regions tile the frame"
    o, d = primary_rays(cam, w, h)
    _, prim = brute_force(scene.sphere_centers, scene.sphere_radii, o, d)
    meets = prim >= 0
    if planes:
        for p in scene.planes:
            n = np.asarray(p.normal)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((np.asarray(p.point) - o) @ n) / (d @ n)
            meets |= t > 0
    meets = meets.reshape(h, w)[::-1]  # GL rows from the bottom
    for x, y, rw, rh, tracer in regions:
        if not tracer:
            assert not meets[y : y + rh, x : x + rw].any(), (x, y, rw, rh)
    if position == (0.0, 0.0, 100.0):  # the thesis's camera: sky above the horizon, spheres in the middle
        assert sum(rw * rh for _, _, rw, rh, t in regions if not t) > (0.25 if planes else 0.5) * w * h


ONE_PASS = [name for name, m in METHODS.items() if not m.capabilities.multi_pass]


@pytest.mark.parametrize("method", ONE_PASS)
def test_what_a_method_packs_is_what_its_shader_declares(method):
    packed = METHODS[method].prepare(scenario(3, 64), 8, 64).packed
    names = set(packed.textures) | set(packed.uniforms)
    assert names == {b.name for b in METHODS[method].bindings if b.needs is None}, "a sphere scene: no triangles"
    if METHODS[method].capabilities.meshes_on_gpu:  # a smooth mesh scene: the triangles' too
        packed = METHODS[method].prepare(mesh_scene("mixed", 1), 8, 64).packed
        names = set(packed.textures) | set(packed.uniforms)
        assert names == {b.name for b in METHODS[method].bindings if b.needs != "SHAPES"}
    # a scene with analytic shapes: their records and base id (brute force: their count too)
    shapes = Scene.from_json(
        {
            "materials": [{}],
            "spheres": [{"center": [0, 0, 0], "radius": 1}],
            "tori": [{"center": [3, 0, 0], "axis": [0, 1, 0], "major_radius": 1, "minor_radius": 0.2}],
        }
    )
    packed = METHODS[method].prepare(shapes, 8, 64).packed
    names = set(packed.textures) | set(packed.uniforms)
    assert names == {b.name for b in METHODS[method].bindings if b.needs in (None, "SHAPES")}
    prims = gpu_layout.pack_primitives(scenario(3, 64))
    # only a scene with emission, an environment colour, an environment image
    image = {b.name for b in gpu_layout.ENV_BINDINGS}
    lit = {gpu_layout.EMISSION.name, gpu_layout.ENVIRONMENT.name} | image
    assert set(prims.textures) | set(prims.uniforms) == {b.name for b in gpu_layout.SCENE_BINDINGS} - lit
    scene = scenario(3, 64).to_json()
    scene["materials"][0]["emission"] = [1.0, 2.0, 3.0]
    scene["environment"] = {"color": [0.5, 0.5, 0.5]}
    prims = gpu_layout.pack_primitives(Scene.from_json(scene))
    assert set(prims.textures) | set(prims.uniforms) == {b.name for b in gpu_layout.SCENE_BINDINGS} - image
    scene["environment"] = {"image": "sky"}
    prims = gpu_layout.pack_primitives(Scene.from_json(scene))
    want = {b.name for b in gpu_layout.SCENE_BINDINGS} - {gpu_layout.ENVIRONMENT.name}
    assert set(prims.textures) | set(prims.uniforms) == want
    # the image's texels and its CDFs (W·(H − 1) conditional, then H − 1 marginal), wrapped into rows
    env = Scene.from_json(scene).environment_map
    assert prims.textures[gpu_layout.ENV_MAP.name].data.reshape(-1, 3)[: 256 * 128].tolist() == (
        env.texels.reshape(-1, 3).tolist()
    )
    cdf = prims.textures[gpu_layout.ENV_CDF.name].data.reshape(-1)
    assert cdf[256 * 127 - 1] == 1.0 and cdf[256 * 127 + 126] == 1.0


def test_the_jittered_slices_start_at_the_centre_and_fill_the_cell():
    """Slice 0 of a Whitted accumulation is the cell centre (the pass uniforms of the plain frame);
    the R2 points of the first 64 slices fall in every sixteenth of the cell, 2 to 5 in each."""
    assert gpu_layout.subpixel_cell(0) == (0.5, 0.5)
    assert gpu_layout.pass_uniforms(4, (1, 2), gpu_layout.subpixel_cell(0)) == gpu_layout.pass_uniforms(4, (1, 2))
    assert gpu_layout.pass_uniforms(4, (1, 2))["u_pass_offset"] == (1.5, 2.5)
    points = np.array([gpu_layout.subpixel_cell(j) for j in range(64)])
    assert ((points >= 0) & (points < 1)).all()
    counts, _, _ = np.histogram2d(points[:, 0], points[:, 1], bins=4, range=[[0, 1], [0, 1]])
    assert counts.min() >= 2 and counts.max() <= 5, counts


def test_primary_rect_and_the_cost_coverage_hold_analytic_shapes():
    """A scene of shapes alone: the tracer's rectangle holds every pixel whose reference ray
    meets a shape (outside it the background variant draws), and the cost model sees them."""
    from renderer.config.settings import RenderSettings
    from renderer.frame.cost import coverage
    from renderer.oracle.reference import render_reference

    scene = Scene.from_json(
        {
            "camera": {"position": [0, 2, 8], "target": [1, 0, 0], "fov_y": 50},
            "materials": [{}],
            "cylinders": [{"base": [2, -1, 0], "axis": [0, 1, 0.3], "radius": 0.5, "height": 2}],
            "tori": [{"center": [-1, 0, 0], "axis": [0.3, 1, 0], "major_radius": 1, "minor_radius": 0.3}],
        }
    )
    w, h = 48, 32
    x, y, rw, rh = gpu_layout.primary_rect(scene, w, h)
    ids = render_reference(scene, RenderSettings(width=w, height=h, mode="primid")).primid[::-1]  # GL rows
    hit_rows, hit_cols = np.nonzero(ids >= 0)
    assert len(hit_rows) > 50 and rw * rh < w * h
    assert (hit_cols >= x).all() and (hit_cols < x + rw).all() and (hit_rows >= y).all() and (hit_rows < y + rh).all()
    assert 0.0 < coverage(scene, w, h) < 1.0
