"""The generated scenes of the thesis (renderer.scenes.scenarios): reproducible, inside the cube,
round-tripping through SPEC's JSON; bad arguments name their field."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.geometry.scene import Scene, SceneError
from renderer.scenes.scenarios import scenario


def test_scenario_round_trips_and_is_inside_the_cube():
    s = scenario(3, 100, seed=7)
    again = Scene.from_json(s.to_json())
    np.testing.assert_array_equal(again.sphere_centers, s.sphere_centers)
    lo = s.sphere_centers - s.sphere_radii[:, None]
    hi = s.sphere_centers + s.sphere_radii[:, None]
    assert lo.min() >= -20 and hi.max() <= 20
    np.testing.assert_array_equal(scenario(2, 64, seed=3).sphere_centers, scenario(2, 64, seed=3).sphere_centers)
    assert not np.array_equal(scenario(2, 64, seed=3).sphere_centers, scenario(2, 64, seed=4).sphere_centers)
    assert (
        len(scenario(1, 4096).sphere_centers) == 4096
        and len(np.unique(scenario(1, 4096).sphere_centers, axis=0)) == 4096
    )


def test_scenario_arguments_are_validated():
    for kw, field in [
        ({"number": 4, "n": 8}, "scenario"),
        ({"number": 1, "n": -1}, "n"),
        ({"number": 1, "n": 8, "radius": 0.0}, "radius"),
        ({"number": 1, "n": 8, "seed": -2}, "seed"),
    ]:
        with pytest.raises(SceneError) as e:
            scenario(**kw)
        assert e.value.field == field


# ---- the demo scenes: registry, framing ---------------------------------------------------------
ASPECTS = (390 / 844, 1.0, 16 / 9)  # a portrait phone (Chromium's 390 × 844), a square, a landscape screen


def demo_scene(d):
    """The scene a registry entry's recipe makes (as POST /api/sessions makes it)."""
    from renderer.scenes.animation import museum
    from renderer.scenes.scenarios import mesh_scene

    r = d.recipe
    if "mesh_scene" in r:
        return mesh_scene(**r["mesh_scene"])
    if "museum" in r:
        return museum(r["museum"]["n"]).scene
    return scenario(r["scenario"], r["n"], r.get("seed", 0), r.get("radius", 1.0), r.get("sky", False))


def projected(camera, aspect: float, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised screen coordinates (−1 … 1 inside the frame) and depth of world ``points``, by a
    pinhole of the camera's fields (written here, not taken from the code under test)."""
    p, t, up = (np.array(v, dtype=float) for v in (camera.position, camera.target, camera.up))
    f = (t - p) / np.linalg.norm(t - p)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    q = points - p
    depth = q @ f
    half_h = np.tan(np.radians(camera.fov_y) / 2)
    return np.stack([(q @ r) / depth / (half_h * aspect), (q @ u) / depth / half_h], axis=1), depth


def shown_boxes(scene) -> np.ndarray:
    """Each object's box, as the scene holds it; a mesh whose box holds the camera (a room seen
    from inside) is where the camera is, not something it shows."""
    from renderer.geometry.shapes import bounds

    boxes = [np.stack([c - r, c + r]) for c, r in zip(scene.sphere_centers, scene.sphere_radii, strict=True)]
    eye = np.array(scene.camera.position)
    for m in scene.meshes:
        lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
        if not (np.all(lo < eye) and np.all(eye < hi)):
            boxes.append(np.stack([lo, hi]))
    boxes += list(bounds(scene.shapes))
    return np.array(boxes)


def corners_of(boxes: np.ndarray) -> np.ndarray:
    pick = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return np.stack([boxes[:, pick[:, a], a] for a in range(3)], axis=-1).reshape(-1, 3)


@pytest.mark.parametrize("aspect", ASPECTS, ids=("portrait", "square", "landscape"))
def test_every_demo_scene_is_framed_whole_and_not_a_speck(aspect):
    from renderer.scenes.scenarios import DEMO_SCENES, FRAME_MARGIN, MAX_FRAMING_FOV_Y, framed

    for d in DEMO_SCENES:
        scene = framed(demo_scene(d), aspect)
        xy, depth = projected(scene.camera, aspect, corners_of(shown_boxes(scene)))
        assert np.all(depth > 0), d.value
        assert np.abs(xy).max() <= 1.0 - FRAME_MARGIN + 1e-9, (d.value, np.abs(xy).max(axis=0))
        # it fills the frame along one side at least: not a speck in the middle
        assert (xy.max(axis=0) - xy.min(axis=0)).max() >= 2 * 0.6, (d.value, xy.min(axis=0), xy.max(axis=0))
        assert scene.camera.fov_y <= MAX_FRAMING_FOV_Y


@pytest.mark.parametrize("aspect", ASPECTS, ids=("portrait", "square", "landscape"))
def test_the_cornell_box_shows_its_red_and_green_walls_whole(aspect):
    from renderer.scenes.scenarios import framed, mesh_scene

    scene = framed(mesh_scene("cornell"), aspect)
    back = np.array([[x, y, -20.0] for x in (-20.0, 20.0) for y in (-20.0, 20.0)])  # the back wall's corners
    xy, depth = projected(scene.camera, aspect, back)
    assert np.all(depth > 0) and np.abs(xy).max() < 1.0


def test_a_room_seen_from_inside_stays_inside():
    from renderer.scenes.scenarios import framed, mesh_scene

    for aspect in ASPECTS:
        cam = framed(mesh_scene("room"), aspect).camera
        assert np.all(np.abs(cam.position) < 20.0), (aspect, cam)


def test_the_default_scene_is_the_thesis_grid_in_colour_under_the_sky():
    from renderer.materials.envmap import SKY_REF
    from renderer.scenes.scenarios import DEFAULT_DEMO, mesh_scene

    assert DEFAULT_DEMO.recipe == {"mesh_scene": {"kind": "spheres"}}
    s = mesh_scene("spheres")
    thesis = scenario(1, 512, seed=1)
    np.testing.assert_array_equal(s.sphere_centers, thesis.sphere_centers)  # the geometry stays exact
    np.testing.assert_array_equal(s.sphere_radii, thesis.sphere_radii)
    assert s.planes == thesis.planes
    assert s.environment_map is not None and s.environment_map.ref == SKY_REF
    floor = np.array(s.materials[s.planes[0].material].color)
    assert floor.max() - floor.min() < 0.1  # a neutral floor, not red
    opaque = {s.materials[m].color for m in np.unique(s.sphere_materials) if s.materials[m].transmissive == 0}
    assert len(opaque) >= 4 and all(tuple(floor) != c for c in opaque)


def test_the_registry_recommends_the_path_integrator_where_a_scene_is_made_for_it():
    from renderer.config.settings import SETTINGS, RenderSettings
    from renderer.scenes.scenarios import DEMO_SCENES, demo_for_recipe

    values = [d.value for d in DEMO_SCENES]
    assert len(set(values)) == len(values) and sum(d.default for d in DEMO_SCENES) == 1
    assert {1, 2, 3, "sky:2", "museum", "mesh:teapot", "mesh:mixed", "mesh:room", "mesh:cornell"} <= set(values)
    names = {s.name for s in SETTINGS}
    for d in DEMO_SCENES:
        assert set(d.settings) <= names, d.value
        RenderSettings(**d.settings)  # valid as they stand
    by = {d.value: d for d in DEMO_SCENES}
    assert by["mesh:materials"].settings.items() >= {"integrator": "path", "denoise": "oidn"}.items()
    for value in ("mesh:cornell", "mesh:table", "sky:2"):
        assert by[value].settings == {"integrator": "path", "denoise": "oidn"}, value
        assert "path" in by[value].label
    assert by[1].settings == {}
    assert demo_for_recipe(mesh_kind="cornell") is by["mesh:cornell"]
    assert demo_for_recipe(scenario_number=2, sky=True) is by["sky:2"]
    assert demo_for_recipe(scenario_number=2) is by[2] and demo_for_recipe(museum=True) is by["museum"]
    assert demo_for_recipe(scenario_number=1, sky=True) is None


def test_the_readme_lists_the_demo_scenes_of_the_registry():
    from pathlib import Path

    from renderer.scenes.scenarios import demo_scenes_markdown

    text = (Path(__file__).resolve().parents[3] / "README.md").read_text()
    start = text.index("<!-- demo-scenes")
    block = text[text.index("\n", start) + 1 : text.index("<!-- /demo-scenes -->")].strip()
    assert block == demo_scenes_markdown(), "README's demo scenes differ; paste:\n" + demo_scenes_markdown()


def test_the_materials_scene_puts_each_texture_on_an_object_with_uvs():
    import json

    from renderer.geometry.scene import Scene
    from renderer.materials.pbr import PbrMaterial
    from renderer.scenes.scenarios import materials_scene_parts, mesh_scene

    scene, parts = materials_scene_parts()
    assert all(isinstance(m, PbrMaterial) for m in scene.materials)
    assert scene.environment_map is not None and len(scene.lights) == 1  # the sky, and a sun for Whitted
    assert len(scene.textures) == 6 and all(256 <= t.width == t.height <= 512 for t in scene.textures)
    read = set()
    for name, k in parts.items():
        mesh = scene.meshes[k]
        material = scene.materials[mesh.material]
        assert isinstance(material, PbrMaterial)
        read |= set(material.textures())
        if material.textures():
            assert mesh.uvs is not None, name
        if material.normal_texture >= 0:
            assert mesh.tangents is not None, name
    assert read == set(range(len(scene.textures)))  # every texture is on something
    glass = scene.materials[scene.meshes[parts["glass"]].material]
    metal = scene.materials[scene.meshes[parts["metal"]].material]
    assert isinstance(glass, PbrMaterial) and glass.transmission == 1.0 and glass.attenuation_distance > 0
    assert isinstance(metal, PbrMaterial) and metal.metallic == 1.0 and metal.metallic_roughness_texture >= 0
    srgb = {
        scene.textures[i].srgb
        for m in scene.materials
        if isinstance(m, PbrMaterial)
        for i in [m.base_color_texture]
        if i >= 0
    }
    assert srgb == {True}
    again = Scene.from_json(json.loads(json.dumps(mesh_scene("materials").to_json())))
    assert [t.pixels.tobytes() for t in again.textures] == [t.pixels.tobytes() for t in scene.textures]


def test_a_scene_under_the_sky_keeps_its_textures():
    import numpy as np

    from renderer.materials.texture import Texture
    from renderer.scenes.scenarios import mesh_scene, with_sky

    base = mesh_scene("teapot")
    textured = Scene(
        base.camera,
        base.lights,
        base.materials,
        base.sphere_centers,
        base.sphere_radii,
        base.sphere_materials,
        base.planes,
        base.meshes,
        textures=(Texture(np.zeros((2, 2, 4), np.uint8)),),
    )
    assert len(with_sky(textured).textures) == 1
