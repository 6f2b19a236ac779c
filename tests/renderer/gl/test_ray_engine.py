"""The ray engine and the hierarchical ray engine.

- exactness: primid equal to the brute-force fragment tracer on ≥ 99.99 % of pixels and
  colour PSNR ≥ 50 dB, for the three scenarios at n = 64 and 1,024, recursion depth 1
  and 5; the same figures against the float64 reference;
- the GPU's cones against the GPU's own rays (the NumPy construction,
  renderer/accel/hre_cones.py, is tested in tests/renderer/accel/test_hre_cones.py);
- a culled (tile, sphere) pair never holds a hit that brute force finds (every live ray
  of the tile, every root t > 0, the vertex shader's own decision);
- tile sizes that do not divide the image, the stencil fallback, the other modes.

Images are small (n = 1,024 at 40 × 64) so the file stays well under two minutes on two
cores: every pass draws every primitive over the target, the ray engine's whole point.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel import hre_cones
from renderer.accel.ray_engine import HierarchicalRayEngine, RayEngine
from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.frame.shader_source import known_bindings
from renderer.geometry.scene import SceneError
from renderer.gl.ray_engine import FrameLog
from renderer.gpu import gpu_layout
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import scenario
from tests.helpers import psnr
from tests.renderer.accel.support import any_hit, check_contained
from tests.renderer.gl.support import active

ENGINES = ("rayengine", "hre")


def size_for(n: int) -> tuple[int, int]:
    return (96, 160) if n <= 64 else (40, 64)


# ------------------------------------------------------------------------ exactness


@pytest.mark.parametrize("depth", [1, 5])
@pytest.mark.parametrize("n", [64, 1024])
@pytest.mark.parametrize("sc", [1, 2, 3])
def test_exact_against_bruteforce_and_reference(gl_renderer, sc, n, depth):
    w, h = size_for(n)
    scene = scenario(sc, n)
    base = RenderSettings(width=w, height=h, max_recursion_depth=depth, method="bruteforce")
    bf = gl_renderer.render(scene, base)
    ref = render_reference(scene, base)
    for method in ENGINES:
        got = gl_renderer.render(scene, base.with_(method=method))
        assert got.stats["method"] == method
        assert np.isfinite(got.image).all()
        for what, other, min_agree in (("brute force", bf, 0.9999), ("float64 reference", ref, 0.999)):
            same = (got.primid == other.primid).mean()
            p = psnr(got.image_u8(), other.image_u8())
            assert same >= min_agree, f"{method} vs {what}: primid agrees on {same:.6f}"
            assert p >= 50.0 if what == "brute force" else p >= 40.0, f"{method} vs {what}: PSNR {p:.1f} dB"
        hit = got.primid >= 0
        assert ((got.primid == -1) == np.isinf(got.depth)).all()
        same = hit & (got.primid == bf.primid)
        np.testing.assert_allclose(got.depth[same], bf.depth[same], rtol=1e-6)


def test_reference_agreement_of_bruteforce_is_the_bar(gl_renderer):
    """The engines are held to what the fragment tracer itself reaches against float64."""
    scene = scenario(3, 64)
    s = RenderSettings(width=96, height=160, max_recursion_depth=5, method="hre")
    got = gl_renderer.render(scene, s)
    ref = render_reference(scene, s)
    assert (got.primid == ref.primid).mean() >= 0.9999
    assert psnr(got.image_u8(), ref.image_u8()) >= 50.0


# ------------------------------------------------------------------------ cones (GPU)


def _trace(gl_renderer, method, scene, settings, log=None):
    """One whole frame of a ray-engine ``method`` object (not the registry's: a test may set
    its knobs), traced through the renderer's passes at once."""
    return gl_renderer.ray_engine.begin(method, scene, settings, log=log).run()


@pytest.fixture(scope="module")
def hre_log(gl_renderer):
    """One hre frame that keeps its rays and cones: scenario 3, 64 spheres, depth 4, tiles of 8."""
    eng = HierarchicalRayEngine()
    scene = scenario(3, 64)
    log = FrameLog(keep=True)
    s = RenderSettings(width=48, height=80, method="hre", max_recursion_depth=4, tile_size=8)
    res = _trace(gl_renderer, eng, scene, s, log=log)
    return scene, log, res


def _record_rays(rec, scene):
    """(origins, dirs, live, dist) of a record's rays, as texel arrays."""
    if rec["kind"] == "radiance":
        o, d = rec["ray_o"][..., :3], rec["ray_d"][..., :3]
        live = rec["ray_d"][..., 3] > 0
        dist = np.full(live.shape, np.inf)
    else:
        s0, s1 = rec["surf0"], rec["surf1"]
        o = s0[..., :3].astype(np.float64)
        lp = np.asarray(scene.lights[rec["light"]].position, dtype=np.float64)
        v = lp - o
        dist = np.linalg.norm(v, axis=-1)
        d = v / np.where(dist > 0, dist, 1.0)[..., None]
        cos = np.einsum("...i,...i->...", s1[..., 3:4] * s1[..., :3], d)
        live = (s0[..., 3] >= 0) & (cos > 0)
    return o.astype(np.float64), d.astype(np.float64), live, dist


def test_gpu_cones_hold_their_rays(hre_log):
    scene, log, res = hre_log
    kinds = {r["kind"] for r in log.records}
    assert kinds == {"radiance", "shadow"}
    assert len(log.records) >= 6
    ts = 8
    for rec in log.records:
        o, d, live, _ = _record_rays(rec, scene)
        tiles = lambda a: hre_cones.tiles_of(a if a.ndim == 3 else a[..., None], ts)
        cones = rec["cones"].astype(np.float64)
        to, td, tl = tiles(o), tiles(d), tiles(live)[..., 0]
        # the shadow rays' directions are recomputed here in float64: allow their rounding
        if rec["kind"] == "shadow":
            cones = cones.copy()
            cones[:, 7] += 1e-4
            cones[:, 3] = np.where(cones[:, 3] >= 0, cones[:, 3] + 1e-5, cones[:, 3])
        check_contained(to, td, tl, cones, scale_points=(0.0, 0.5, 5.0, 50.0, 500.0))
        assert ((cones[:, 3] == hre_cones.NO_RAYS) == ~tl.any(axis=1)).all()


def test_culled_tiles_hold_no_hit(gl_renderer, hre_log):
    """For every pass of the frame: the vertex shader's culled (tile, sphere) pairs hold no
    ray that meets the sphere at any t > 0 (brute force over every live ray of the tile)."""
    scene, log, _ = hre_log
    culled_total = 0
    for rec in log.records:
        verts = rec["verts"]
        if verts is None or len(verts) == 0:
            continue
        drawn = gl_renderer.ray_engine.cull_matrix(scene, verts)
        o, d, live, _ = _record_rays(rec, scene)
        ts = 8
        for ti, tile in enumerate(verts):
            x0, y0 = int(tile[0]), int(tile[1])
            sl = (slice(y0, y0 + ts), slice(x0, x0 + ts))
            lv = live[sl]
            if not lv.any():
                continue
            ro, rd = o[sl][lv], d[sl][lv]
            for s in np.flatnonzero(~drawn[ti, : scene.n_spheres]):
                culled_total += 1
                hits = any_hit(ro, rd, scene.sphere_centers[s], scene.sphere_radii[s])
                assert not hits.any(), f"{rec['kind']} pass, tile {ti}: culled sphere {s} is hit"
        assert drawn[:, scene.n_spheres :].all(), "planes are never culled"
    assert culled_total > 1000, "the test should see many culled pairs"


# ------------------------------------------------------------------------ settings and modes


def test_tile_sizes_that_do_not_divide_the_image_are_padded(gl_renderer):
    scene = scenario(2, 64)
    s = RenderSettings(width=49, height=81, method="hre", max_recursion_depth=3)
    bf = gl_renderer.render(scene, s.with_(method="bruteforce"))
    for ts in (8, 12, 32):
        got = gl_renderer.render(scene, s.with_(tile_size=ts))
        assert got.image.shape == (81, 49, 3) and got.stats["tile_size"] == ts
        assert (got.primid == bf.primid).mean() >= 0.9999 and psnr(got.image_u8(), bf.image_u8()) >= 50.0


def test_fewer_stencil_bits_fall_back_exactly(gl_renderer):
    scene = scenario(3, 64)
    s = RenderSettings(width=48, height=80, method="rayengine", max_recursion_depth=5)
    full = gl_renderer.render(scene, s)
    eng = RayEngine()
    eng.stencil_bits = 2
    few = _trace(gl_renderer, eng, scene, s)
    assert few.stats["stencil_fallback_levels"] == 3 and full.stats["stencil_fallback_levels"] == 0
    np.testing.assert_array_equal(few.primid, full.primid)
    assert psnr(few.image_u8(), full.image_u8()) >= 60.0


@pytest.mark.parametrize("mode", ["depth", "primid", "normal", "recursion"])
def test_modes_match_bruteforce(gl_renderer, mode):
    scene = scenario(3, 64)
    s = RenderSettings(width=48, height=80, max_recursion_depth=5, mode=mode, method="bruteforce")
    bf = gl_renderer.render(scene, s)
    for method in ENGINES:
        got = gl_renderer.render(scene, s.with_(method=method))
        same = (got.image_u8() == bf.image_u8()).all(axis=2).mean()
        assert same >= 0.999, f"{method} {mode}: {same:.4f} of pixels agree"
        np.testing.assert_array_equal(got.array().shape, bf.array().shape)


def test_heat_counts_primitives_drawn(gl_renderer):
    scene = scenario(2, 64)
    s = RenderSettings(width=48, height=80, mode="heat")
    re_ = gl_renderer.render(scene, s.with_(method="rayengine")).image
    hre = gl_renderer.render(scene, s.with_(method="hre")).image
    assert np.allclose(re_[..., 0], 1.0) and np.allclose(re_[..., 1:], 0.0)  # 64 spheres · 0.05 > 1
    assert (hre[..., 0] < 1.0).mean() > 0.5, "most tiles should draw fewer than 20 spheres"


def test_cones_mode(gl_renderer):
    scene = scenario(1, 64)
    s = RenderSettings(width=48, height=80, mode="cones", method="hre")
    images = {g: gl_renderer.render(scene, s.with_(max_recursion_depth=g)).image for g in (1, 2, 4)}
    assert images[1].shape == (80, 48, 3)
    lit = images[1][..., 0] > 0
    assert lit.all(), "every tile of the primary generation holds rays"
    assert images[1].min() > 0.8, "primary rays: narrow cones (bright)"
    assert images[4].mean() < images[1].mean()
    with pytest.raises(SceneError):
        gl_renderer.render(scene, s.with_(method="rayengine"))


def test_supersampling_and_min_weight_as_the_fragment_tracer(gl_renderer):
    scene = scenario(3, 64)
    for extra in ({"samples_per_pixel": 4}, {"min_weight": 0.2}):
        s = RenderSettings(width=24, height=40, max_recursion_depth=5, method="bruteforce", **extra)
        bf = gl_renderer.render(scene, s)
        for method in ENGINES:
            got = gl_renderer.render(scene, s.with_(method=method))
            assert got.image.shape == bf.image.shape
            np.testing.assert_array_equal(got.primid, bf.primid)
            assert psnr(got.image_u8(), bf.image_u8()) >= 50.0, f"{method} {extra}"


MULTI_PASS = [name for name, m in METHODS.items() if m.capabilities.multi_pass]


@pytest.mark.parametrize("method", MULTI_PASS)
@pytest.mark.parametrize("mode", ["color", "depth", "primid", "normal", "recursion", "heat", "cones"])
@pytest.mark.parametrize("depth", [1, 3])
def test_ray_engine_frames_upload_only_what_their_passes_read(gl_renderer, method, mode, depth):
    if mode not in METHODS[method].capabilities.modes:
        return
    passes = gl_renderer.ray_engine
    gl_renderer.render(
        scenario(3, 64), RenderSettings(width=32, height=32, method=method, mode=mode, max_recursion_depth=depth)
    )
    used = set().union(*(active(passes.programs.progs[k]) for k in passes.programs.used))
    declared = {b.name for b in gpu_layout.RAY_ENGINE_BINDINGS}
    assert used & known_bindings() <= declared
    bound = passes.last_bound
    assert bound <= used, (method, mode, depth, sorted(bound - used))
    # Only the cones of the primary layer need no scene data at all.
    assert bool(bound) == (mode != "cones" or depth > 1)
