"""Exactness of the shaped tracer: every frame is bit for bit what the base commit's shader renders.

The record ``base_images.json`` was generated from the shader, layouts and packers
of the base commit (``base_images.BASE_COMMIT``, extracted from git and run in a
subprocess by ``python -m tests.renderer.gl.base_images --write``), never from the code
under test. Its frames (``base_images.cases``): every one-pass method × every mode × scenes
with equal and unequal radii, a material that reflects and transmits, several lights and
planes, no lights, 20 materials, no spheres, planes only, an animated museum, at 1 and 4
samples per pixel, and every stability-catalogue case in colour. Here each is rendered now
and its float image, uint8 image, depth, primid and normal arrays must hash the same:

- with the renderer's own choices (uniform blocks where the data fit, float targets for
  ``npy`` frames);
- with textures only, wrapped into 128-texel rows (the device's path, and the wrapping);
- as ``png`` at one sample per pixel (the RGBA8 target, rounded in the shader): the
  same bytes as ``image_u8()`` of the float image.

A static scene's structure per method is built once (as ``render`` builds it) and traced by all
of its frames in the three tests (``render(..., prepared=)``); the museum is posed and built per
frame.
"""

from __future__ import annotations

import json
from collections import defaultdict

import pytest

from renderer.config.settings import RenderSettings
from renderer.frame.prepare import prepare_frame
from renderer.geometry.scene import Scene
from tests.renderer.gl import base_images as B

pytestmark = pytest.mark.long  # about a thousand frames

RECORD = json.loads(B.RECORD.read_text())["frames"]
# Heat counts traversal steps, so it follows the tree, not only the shader: the BVH's build
# bins on one axis without sorts, unlike the base commit's, and the two-level method uses it too, so
# their heat frames differ from the base commit's (every other array of theirs still is;
# the png test still checks their heat bytes against the float frame's).
TREE_CHANGED = ("bvh", "twolevel")


def _tree_dependent(key: str, kw: dict) -> bool:
    return kw["method"] in TREE_CHANGED and kw.get("mode") == "heat"


CASES = B.cases()
GROUPS: dict[str, list] = defaultdict(list)
for _key, _scene, _kw in CASES:
    GROUPS[_key.split("/")[0]].append((_key, _scene, _kw))


def test_the_record_is_the_base_commits_and_covers_every_case():
    assert json.loads(B.RECORD.read_text())["base_commit"] == B.BASE_COMMIT
    assert set(RECORD) == {k for k, _, _ in CASES}


@pytest.fixture(scope="module")
def textures_only(gl_renderer):
    """Another renderer on the same context (a second context would become the current one)."""
    from renderer.gl import GLRenderer

    return GLRenderer(gl_renderer.ctx, max_texture_width=128, uniform_blocks=False)


# A static scene's structure for a method, as the renderer's render() builds it (prepare_frame, at
# the renderer's texture width), made once and traced by every frame of it: the modes, the samples
# and the three tests below (the frames differ in what is traced, not in what is built).
_PREPARED: dict[tuple, object] = {}


def render(renderer, scene, settings: RenderSettings):
    if not isinstance(scene, Scene):  # the animated museum: posed and built per frame, as render() does
        return renderer.render(scene, settings)
    key = (id(scene), settings.method, settings.max_prims, settings.max_tree_depth, renderer.max_texture_width)
    if key not in _PREPARED:
        _PREPARED[key] = prepare_frame(scene, settings, max_width=renderer.max_texture_width).prepared
    return renderer.render(scene, settings, prepared=_PREPARED[key])


def _mismatches(
    renderer, group: str, fields=("image", "u8", "depth", "primid", "normal"), skip=None, **over
) -> list[str]:
    bad = []
    for key, scene, kw in GROUPS[group]:
        if _tree_dependent(key, kw) or (skip and skip(key, kw)):
            continue
        settings = RenderSettings(**{**kw, **over})
        got = B.hashes(render(renderer, scene, settings))
        want = RECORD[key]
        diff = [f for f in fields if got[f] != want[f]]
        if diff:
            bad.append(f"{key}: {', '.join(diff)}")
    return bad


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_frames_equal_the_base_shaders(gl_renderer, group):
    bad = _mismatches(gl_renderer, group)
    assert not bad, f"{len(bad)} of {len(GROUPS[group])} frames differ from the base commit's shader: {bad[:6]}"


@pytest.mark.parametrize("group", sorted(g for g in GROUPS if g != "catalogue"))
def test_frames_with_textures_only_equal_the_base_shaders(textures_only, group):
    # Brute force's one record array wraps alike at every n: its large scenes are left to
    # the test above (they take most of the time).
    bad = _mismatches(
        textures_only,
        group,
        skip=lambda key, kw: kw["method"] == "bruteforce" and group in ("s3_4096", "s2_1024", "s3_1024_radii"),
    )
    assert not bad, f"{len(bad)} frames differ (textures only, 128-texel rows): {bad[:6]}"


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_png_frames_have_the_base_shaders_bytes(gl_renderer, group):
    """png at one sample per pixel goes through the RGBA8 target: the bytes are image_u8's."""
    bad, n = [], 0
    for key, scene, kw in GROUPS[group]:
        if kw.get("samples_per_pixel", 1) != 1:
            continue
        res = render(gl_renderer, scene, RenderSettings(**{**kw, "format": "png"}))
        assert res.stats["target"] == "rgba8", key
        n += 1
        want = (
            B.hashes(gl_renderer.render(scene, RenderSettings(**kw)))["u8"]
            if _tree_dependent(key, kw)
            else RECORD[key]["u8"]
        )
        if B.hashes(res, arrays=False)["u8"] != want:
            bad.append(key)
    assert not bad, f"{len(bad)} of {n} png frames differ in their bytes: {bad[:6]}"
