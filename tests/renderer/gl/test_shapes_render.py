"""Analytic shapes traced by the GPU methods (shaders/shapes_tracer.glsl): a scene of every kind
— a glass torus, a capped and an open (mirror) cylinder, a glass frustum, a disk and an annulus,
with spheres and a plane — by every one-pass method, against the float64 reference tracer
(renderer/oracle/reference.py) in the modes primid, depth, normal and colour; the methods against each
other; and the path integrator: a frame with finite pixels, and white furnaces.

Ids: silhouette pixels aside (a pixel whose 3 × 3 neighbourhood holds more than one id in the
reference: there a float32 ray may fall on either side of an edge), ≥ 99.99 % of pixels carry
the reference's id; the glass and mirror surfaces make the colour frames exercise the rays that
leave a shape (the shader must drop only that shape's root at the ray's origin)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_erosion, maximum_filter, minimum_filter

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.oracle.reference import render_reference
from tests.renderer.gl.support import path

ONE_PASS = [n for n, m in METHODS.items() if not m.capabilities.multi_pass]
W, H = 64, 48

MODES = ("primid", "depth", "normal", "color")


def settings(mode: str, method: str = "bruteforce") -> RenderSettings:
    return RenderSettings(width=W, height=H, mode=mode, method=method, max_recursion_depth=5)


@pytest.fixture(scope="module")
def scene(every_shape_scene) -> Scene:
    return every_shape_scene


@pytest.fixture(scope="module")
def reference(scene):
    return {mode: render_reference(scene, settings(mode)) for mode in MODES}


def silhouettes(primid: np.ndarray) -> np.ndarray:
    """Pixels whose 3 × 3 neighbourhood holds more than one id."""
    return maximum_filter(primid, size=3, mode="nearest") != minimum_filter(primid, size=3, mode="nearest")


def test_the_scene_holds_every_kind_and_the_reference_sees_each(scene, reference):
    assert set(scene.shapes.counts().values()) == {1, 2} and scene.n_shapes == 6
    seen = set(np.unique(reference["primid"].primid).tolist())
    assert set(range(scene.shape_id_base, scene.shape_id_base + scene.n_shapes)) <= seen
    assert {-1, 0, 1, 2} <= seen  # a miss, both spheres, the plane


@pytest.mark.parametrize("method", ONE_PASS)
def test_every_method_traces_every_kind_as_the_reference(gl_renderer, scene, reference, method):
    ref = reference["primid"]
    inner = ~silhouettes(ref.primid)
    for mode in MODES:
        got = gl_renderer.render(scene, settings(mode, method))
        same = got.primid == ref.primid
        assert same[inner].mean() >= 0.9999, (method, mode, same[inner].mean())
        assert same.mean() >= 0.99, (method, mode)
        hit = same & (ref.primid >= 0)
        rel = np.abs(got.depth[hit] - ref.depth[hit]) / ref.depth[hit]
        assert rel.max() <= 1e-4, (method, mode, rel.max())
        if mode == "normal":
            err = np.abs(got.normal - reference["normal"].normal).max(axis=2)[hit & inner]
            # (a cylinder's rim: the part hit and the part nearest the float64 point may differ)
            assert (err <= 1e-3).mean() >= 0.999, (method, err.max())
        if mode == "color":
            a = np.clip(got.image.astype(np.float64), 0.0, 1.0)
            b = np.clip(reference["color"].image.astype(np.float64), 0.0, 1.0)
            psnr = 10.0 * np.log10(1.0 / max(((a - b) ** 2).mean(), 1e-30))
            assert psnr >= 40.0, (method, psnr)


def test_the_methods_agree_with_each_other_on_ids(gl_renderer, scene):
    ids = {m: gl_renderer.render(scene, settings("primid", m)).primid for m in ONE_PASS}
    for m, got in ids.items():
        assert (got == ids["bruteforce"]).mean() >= 0.9999, m


def test_the_stats_count_the_shapes_and_the_tree_holds_them(gl_renderer, scene):
    got = gl_renderer.render(scene, settings("primid", "bih"))
    assert got.stats["shapes"] == 6 and got.stats["primitives"] == scene.n_spheres + scene.n_shapes


def test_a_path_traced_frame_of_every_kind_is_finite(gl_renderer, scene):
    r = gl_renderer.render(scene, path(width=32, height=24, spp=4, depth=6, method="bih"))
    assert np.isfinite(r.image).all() and (r.image >= 0).all()
    assert (r.image.max(axis=2) > 0).mean() > 0.5  # lit by the point light


ALBEDO = [0.5, 0.6, 0.7]
CONVEX = {
    "cylinders": [{"base": [0, -1, 0], "axis": [0, 1, 0], "radius": 1.0, "height": 2.0, "caps": True}],
    "cones": [{"base": [0, -1, 0], "axis": [0.2, 1, 0], "base_radius": 1.2, "top_radius": 0.3, "height": 2.0}],
    "disks": [{"center": [0, 0, 0], "normal": [0, 1, 1], "radius": 1.5}],
}
# Not convex (a shape sees itself): albedo 1, so every path that escapes brings exactly 1.
CONCAVE = {
    "tori": [{"center": [0, 0, 0], "axis": [0, 1, 0.5], "major_radius": 1.2, "minor_radius": 0.5}],
    "cylinders": [{"base": [0, -1, 0], "axis": [0, 1, 0.6], "radius": 1.0, "height": 1.5, "caps": False}],
    "disks": [{"center": [0, 0, 0], "normal": [0, 1, 1], "radius": 1.5, "inner_radius": 0.7}],
}


def furnace(key: str, item: dict, albedo) -> Scene:
    return Scene.from_json(
        {
            "camera": {"position": [0, 2, 5], "target": [0, 0, 0], "fov_y": 30},
            "lights": [],
            "materials": [{"color": list(albedo), "diffuse": 1.0, "reflective": 0.0, "ambient": 0.0}],
            "environment": {"color": [1.0, 1.0, 1.0]},
            key: [item],
        }
    )


@pytest.mark.parametrize("method", ["bih", "bruteforce"])
def test_white_furnaces_of_each_kind(gl_renderer, method):
    """A diffuse shape of albedo ρ inside radiance 1: ρ where it is convex (the estimate has no
    variance); albedo 1 gives 1 where it sees itself (tori, open tubes)."""
    cases = [(k, v[0], ALBEDO) for k, v in CONVEX.items()] + [(k, v[0], [1.0, 1.0, 1.0]) for k, v in CONCAVE.items()]
    for key, item, want in cases:
        r = gl_renderer.render(furnace(key, item, want), path(spp=4, method=method))
        px = binary_erosion(r.primid >= 0, iterations=2)
        assert px.sum() > 100, key
        np.testing.assert_allclose(r.image[px].mean(axis=0), want, rtol=0.01, err_msg=f"{method}: {key} {item}")
        assert np.isfinite(r.image).all()


def test_the_bih_heat_counts_shape_tests_as_its_cpu_mirror(gl_renderer, scene):
    """Heat mode: the shader's node and primitive counts over a tree with shapes are those of
    the CPU traversal (renderer/accel/bih_traverse.py) the reference uses."""
    st = RenderSettings(width=32, height=24, mode="heat", method="bih")
    got, ref = gl_renderer.render(scene, st), render_reference(scene, st)
    assert ref.image.max() > 0
    np.testing.assert_array_equal(got.image, ref.image)


@pytest.mark.parametrize("method", ["bih", "bruteforce"])
def test_the_shape_records_read_from_textures_as_from_uniform_blocks(gl_renderer, scene, reference, method):
    """Record arrays in textures (a device's storage; rows of 8 texels, so a shape's three
    records wrap), not uniform blocks: the same frame."""
    from renderer.gl.renderer import GLRenderer

    narrow = GLRenderer(gl_renderer.ctx, max_texture_width=8, uniform_blocks=False)
    got = narrow.render(scene, settings("color", method))
    blocked = gl_renderer.render(scene, settings("color", method))
    assert got.stats["blocks"] == [] and "u_shapes" in blocked.stats["blocks"]
    assert "SHAPES" in got.stats["shader_features"]
    np.testing.assert_array_equal(got.primid, blocked.primid)
    np.testing.assert_allclose(got.image, blocked.image, atol=1e-6)
