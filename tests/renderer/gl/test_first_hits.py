"""Rasterised first hits (renderer/frame/first_hits.py), a quad per sphere (``raster``) or per tile and
its list (``tiles``): the same ids, distances and images as the traversal, bit for bit, and the
float64 reference's ids — including where a quad's bound is hardest (a sphere around or beside the
camera, behind it, far away, tiny, coincident spheres, a plane cutting spheres)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from renderer import limits
from renderer.config.settings import RenderSettings
from renderer.frame.prepare import prepare_frame
from renderer.geometry.scene import Camera, Material, Plane, Scene
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import scenario

MAT = (Material(color=(1.0, 0.5, 0.2)), Material(color=(0.2, 0.5, 1.0)))


def spheres(camera: Camera, centres, radii, planes=()) -> Scene:
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    return Scene(camera, (), MAT, c, np.asarray(radii, dtype=np.float64), np.arange(len(c)) % 2, tuple(planes))


CAM = Camera((0.0, 0.0, 10.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0)
SCENES = {
    "scenario 1, 64": lambda: scenario(1, 64),
    "scenario 2, 256, no plane": lambda: dataclasses.replace(scenario(2, 256), planes=()),
    "scenario 3, 128": lambda: scenario(3, 128),
    # the camera inside a sphere (only far roots), one reaching past its plane, one wholly behind it
    "around and beside the camera": lambda: spheres(
        CAM, [[0, 0, 10], [3, 0, 10.5], [0, 0, 30], [1, 1, 0]], [2.0, 1.0, 1.0, 1.5]
    ),
    # tiny and far: quads of one fragment or less
    "tiny and far": lambda: spheres(
        CAM,
        [[0.01 * i, 0.013 * i, -1000.0] for i in range(-20, 21)] + [[0.3, 0.2, 5.0]],
        [0.004] * 41 + [1e-3],
    ),
    # coincident spheres: equal t, the lower id wins
    "coincident": lambda: spheres(CAM, [[0, 0, 0], [0, 0, 0], [0.5, 0, 0], [0.5, 0, 0]], [1.0, 1.0, 1.2, 1.2]),
    # a plane through the spheres' middle, and one the camera looks along
    "planes cutting": lambda: spheres(
        CAM,
        [[-1, 0, 0], [1, 0.2, -1], [0, -1, 2]],
        [1.0, 1.5, 0.7],
        planes=(Plane((0, 0, 0), (0, 1, 0), 0), Plane((0, 0, -3), (0, 0, 1), 1)),
    ),
    # far from the origin: float32 spacing ~0.06 at 1e6
    "far from the origin": lambda: spheres(
        Camera((1e6, 1e6, 1e6 + 20), (1e6, 1e6, 1e6), (0, 1, 0), 40.0),
        [[1e6, 1e6, 1e6], [1e6 + 3, 1e6, 1e6 - 2]],
        [2.0, 1.0],
    ),
}
MODES = ("depth", "primid", "normal")


def frame(gl_renderer, scene: Scene, how: str, mode: str, **kw) -> tuple:
    st = RenderSettings(width=96, height=72, mode=mode, format="npy", method="bih", first_hits=how, **kw)
    res = gl_renderer.render(scene, st)
    return res, st


HOWS = ("raster", "tiles")


@pytest.mark.parametrize("how", HOWS)
@pytest.mark.parametrize("name", list(SCENES))
def test_raster_is_the_traversal_bit_for_bit(gl_renderer, name, how):
    scene = SCENES[name]()
    for mode in MODES:
        traced, _ = frame(gl_renderer, scene, "trace", mode)
        raster, _ = frame(gl_renderer, scene, how, mode)
        assert traced.stats["first_hits"] == "trace" and raster.stats["first_hits"] == how
        for field in ("primid", "depth", "normal", "image"):
            a, b = getattr(traced, field), getattr(raster, field)
            assert np.array_equal(a, b, equal_nan=True), f"{name}, {mode}: {field} differs"


@pytest.mark.parametrize("how", HOWS)
@pytest.mark.parametrize("name", list(SCENES))
def test_raster_ids_are_the_float64_references(gl_renderer, name, how):
    scene = SCENES[name]()
    raster, st = frame(gl_renderer, scene, how, "depth")
    ref = render_reference(scene, st)
    same = raster.primid == ref.primid
    # Where they differ, two surfaces are at one t within float32 (the reference's own tie).
    hit = same & (ref.primid >= 0)
    assert same.mean() >= 0.999, f"{name}: {np.count_nonzero(~same)} ids differ"
    rel = np.abs(raster.depth[hit] - ref.depth[hit]) / np.maximum(ref.depth[hit], 1e-30)
    assert rel.max(initial=0.0) < 1e-4


@pytest.mark.parametrize("how", HOWS)
def test_coincident_spheres_go_to_the_lower_id(gl_renderer, how):
    scene = SCENES["coincident"]()
    raster, _ = frame(gl_renderer, scene, how, "primid")
    ids = set(np.unique(raster.primid).tolist())
    assert ids <= {-1, 0, 2} and 0 in ids and 2 in ids


@pytest.mark.parametrize("how", HOWS)
def test_png_frames_and_bands(gl_renderer, how):
    """The RGBA8 target (png at one sample) and a frame traced in bands give the same bytes."""
    scene = scenario(1, 64)
    st = RenderSettings(width=96, height=72, mode="depth", format="png", method="bih")
    a = gl_renderer.render(scene, st.with_(first_hits="trace")).image_u8()
    b = gl_renderer.render(scene, st.with_(first_hits=how)).image_u8()
    assert np.array_equal(a, b)
    started = gl_renderer.start(prepare_frame(scene, st.with_(first_hits=how)), band_rows=7)
    c = started.run()
    assert c.stats["slices"] > 1 and np.array_equal(c.image_u8(), a)


def test_auto_chooses_by_the_cost_model(gl_renderer):
    """A few spheres: rasterised (the model puts both ways far below a traversal's per-pixel cost);
    past FIRST_HITS_AUTO_MAX_SPHERES, or planes and no spheres: the traversal; nothing at all: a clear."""
    sparse = dataclasses.replace(scenario(1, 64), planes=())
    st = RenderSettings(width=640, height=1088, mode="depth", method="bih", format="npy")
    auto = gl_renderer.render(sparse, st)
    assert auto.stats["first_hits"] in ("raster", "tiles")
    assert np.array_equal(auto.primid, gl_renderer.render(sparse, st.with_(first_hits="trace")).primid)
    many = scenario(2, limits.FIRST_HITS_AUTO_MAX_SPHERES + 1)
    assert gl_renderer.render(many, st.with_(width=32, height=32)).stats["first_hits"] == "trace"
    nothing = dataclasses.replace(scenario(1, 0), planes=())  # one clear: black, ids −1
    empty = gl_renderer.render(nothing, st.with_(width=32, height=32))
    assert empty.stats["first_hits"] == "raster" and (empty.primid == -1).all() and not empty.image.any()
    plane_only = scenario(1, 0)
    assert gl_renderer.render(plane_only, st.with_(width=32, height=32)).stats["first_hits"] == "trace"
    # colour frames and meshes always trace
    assert "first_hits" not in gl_renderer.render(sparse, st.with_(mode="color", width=32, height=32)).stats


def test_scenes_with_shapes_trace(gl_renderer):
    """Meshes and analytic shapes have no quads: asking for rasterised first hits traces them."""
    scene = Scene.from_json(
        {
            **spheres(CAM, [[4.0, 3.0, 0.0]], [1.0]).to_json(),
            "tori": [{"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 3, "minor_radius": 1, "material": 0}],
        }
    )
    st = RenderSettings(width=48, height=36, mode="primid", method="bih", first_hits="raster")
    res = gl_renderer.render(scene, st)
    assert res.stats["first_hits"] == "trace"
    assert (res.primid == scene.shape_id_base).any()


def test_tiles_past_the_pair_limit_trace(gl_renderer, monkeypatch):
    """Lists longer than MAX_TILE_PAIRS are not made: the frame traces (the same pixels)."""
    scene = SCENES["scenario 1, 64"]()
    st = RenderSettings(width=96, height=72, mode="primid", method="bih", first_hits="tiles", format="npy")
    assert gl_renderer.render(scene, st).stats["first_hits"] == "tiles"
    monkeypatch.setattr(limits, "MAX_TILE_PAIRS", 10)
    res = gl_renderer.render(scene, st)
    assert res.stats["first_hits"] == "trace"
    assert np.array_equal(res.primid, gl_renderer.render(scene, st.with_(first_hits="trace")).primid)


def covering_spheres(n: int) -> Scene:
    """``n`` spheres at one place, each covering the whole frame (every quad the whole window)."""
    return spheres(CAM, [[0.0, 0.0, 0.0]] * n, [9.0] * n)


@pytest.mark.parametrize("how", HOWS)
def test_overlapping_quads_are_drawn_in_chunks_one_a_slice(gl_renderer, how):
    """With a slice budget, a band's quads are drawn in chunks of about the budget, one a slice — the
    spheres that all cover the frame make many slices, not one draw of all of them — and the chunks
    add up to the traversal's pixels bit for bit (the coincident spheres' ties to the lower id)."""
    from renderer.frame import cost

    n, w, h = 64, 64, 48
    scene = covering_spheres(n)
    st = RenderSettings(width=w, height=h, mode="primid", method="bih", format="npy", first_hits=how)
    ns = cost.RASTER_NS_FRAGMENT if how == "raster" else cost.TILES_NS_PAIR / 256
    budget_ms = n * w * h * ns / 8 / 1e6  # the frame's estimated quads' work in eight
    res = gl_renderer.start(prepare_frame(scene, st), slice_ms=budget_ms).run()
    ref = gl_renderer.render(scene, st.with_(first_hits="trace"))
    assert res.stats["first_hits"] == how
    assert res.stats["slices"] >= 8
    assert np.array_equal(res.primid, ref.primid) and np.array_equal(res.depth, ref.depth)
