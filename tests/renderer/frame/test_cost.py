"""What a frame will cost, estimated before it is traced (renderer.frame.cost): the estimate grows
with what the frame traces, its bound is above it, and the largest accepted settings fit the
limit they were asked for. (How the service admits and schedules by it is tested in
``tests/server/test_scheduler.py``.)"""

from __future__ import annotations

import pytest

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.frame.cost import DEFAULT_MODEL, coverage, estimate, largest_accepted
from renderer.geometry.scene import Camera
from renderer.scenes.scenarios import scenario


@pytest.fixture(scope="module")
def frame():
    scene = scenario(3, 256, seed=1)
    return scene, METHODS["bih"].prepare(scene, 4, 64).stats


def cost(frame, **kw):
    scene, stats = frame
    return estimate("bih", stats, scene, RenderSettings(**{"width": 64, "height": 64, **kw}))


def test_the_estimate_grows_with_pixels_samples_and_depth(frame):
    base = cost(frame)
    assert base.pixels == 64 * 64 and base.passes >= 1 and 0.0 < base.coverage <= 1.0
    assert base.bound_ms == pytest.approx(base.ms * DEFAULT_MODEL.upper) and base.bound_ms > base.ms > 0
    assert cost(frame, width=128).ms > base.ms
    assert cost(frame, samples_per_pixel=4).ms > base.ms
    assert cost(frame, max_recursion_depth=1).rays_per_pixel < base.rays_per_pixel
    assert not base.degenerate
    assert set(base.to_json()) == set(base.__dict__)


def test_coverage_is_the_share_of_the_image_that_sees_the_scenes_box(frame):
    scene, _ = frame
    assert 0.0 < coverage(scene, 64, 64) < 1.0
    inside = scene.with_camera(Camera(position=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0)))
    assert coverage(inside, 64, 64) == 1.0
    cam = scene.camera
    far = scene.with_camera(Camera(tuple(10.0 * p for p in cam.position), cam.target, cam.up, cam.fov_y))
    assert 0.0 < coverage(far, 64, 64) < coverage(scene, 64, 64)


def test_the_largest_accepted_settings_fit_the_limit(frame):
    scene, stats = frame
    settings = RenderSettings(width=256, height=256, samples_per_pixel=16, max_recursion_depth=8)
    limit = estimate("bih", stats, scene, settings.with_(width=128)).bound_ms
    best = largest_accepted("bih", stats, scene, settings, limit)
    assert 128 <= best["width"] < 256  # each setting alone, the others as requested
    for name in ("height", "samples_per_pixel", "max_recursion_depth"):
        if best[name] is not None:
            assert estimate("bih", stats, scene, settings.with_(**{name: best[name]})).bound_ms <= limit
    assert estimate("bih", stats, scene, settings.with_(width=best["width"])).bound_ms <= limit
    assert estimate("bih", stats, scene, settings.with_(width=best["width"] + 1)).bound_ms > limit
    assert largest_accepted("bih", stats, scene, settings, 1e6) == {
        "width": 256,
        "height": 256,
        "samples_per_pixel": 16,
        "max_recursion_depth": 8,
    }


def test_a_path_sample_traces_the_fitted_segments_saturating_with_depth(frame):
    from renderer.frame.cost import PATH_SEGMENTS_LIMIT, path_segments, request_work

    seg = [path_segments(d) for d in range(1, 17)]
    assert seg[0] == 1.0  # the camera's segment only
    assert all(b > a for a, b in zip(seg, seg[1:], strict=False))  # more with depth …
    assert all(s <= min(PATH_SEGMENTS_LIMIT, 2 * d - 1) for d, s in enumerate(seg, 1))  # … but bounded
    assert seg[15] < 1.1 * seg[7]  # saturated by depth 8: the roulette ends the paths
    # The frame's rays and the work cap count them per sample.
    assert cost(frame, integrator="path", samples_per_pixel=32, max_recursion_depth=8).rays_per_pixel == (
        pytest.approx(32 * path_segments(8))
    )
    assert request_work(64, 64, 8, 32, path=True) == pytest.approx(64 * 64 * 32 * path_segments(8))
    assert request_work(64, 64, 8, 4, path=False) == 64 * 64 * 8 * 4


def test_the_cost_follows_what_the_build_reported_not_the_methods_name():
    """A structure's SAH terms (a two-level method's per level) or none (every ray tests every
    primitive): a method added to the registry is costed by what its build reports."""
    from renderer.frame.cost import structures

    scene = scenario(3, 256, seed=1)
    stats = {name: METHODS[name].prepare(scene, 4, 64).stats for name in ("bih", "bruteforce", "twolevel")}
    assert structures(stats["bih"]) == [stats["bih"]] and structures(stats["bruteforce"]) == []
    assert structures(stats["twolevel"]) == [stats["twolevel"]["kd"], stats["twolevel"]["bvh"]]
    settings = RenderSettings(width=32, height=32)
    for name, st in stats.items():
        costs = {
            estimate(other, st, scene, settings).to_json()["ms"] for other in ("bih", "bruteforce", "twolevel", "new")
        }
        assert len(costs) == 1, (name, costs)
    assert estimate("bih", stats["bih"], scene, settings).ms < estimate("bih", stats["bruteforce"], scene, settings).ms
