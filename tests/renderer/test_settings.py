"""Render settings (renderer.settings): JSON in and out, and every bad value names its field.

Frame and tree settings, the animation's (time, update scheme, threshold), the knobs
that trade speed for accuracy (supersampling, weight cut-off, specialisation, method)
and the hierarchical ray engine's tile size.
"""

from __future__ import annotations

import pytest

from renderer.scene import SceneError
from renderer.settings import RenderSettings


def test_settings_validation_and_json():
    s = RenderSettings.from_json({"width": 320, "height": 544, "mode": "heat"})
    assert RenderSettings.from_json(s.to_json()) == s
    for kw, field in [
        ({"width": 0}, "width"),
        ({"height": 4097}, "height"),
        ({"mode": "x"}, "mode"),
        ({"format": "gif"}, "format"),
        ({"max_tree_depth": 65}, "max_tree_depth"),
        ({"max_recursion_depth": 9}, "max_recursion_depth"),
        ({"width": True}, "width"),
    ]:
        with pytest.raises(SceneError) as e:
            RenderSettings(**kw)
        assert e.value.field == field
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"widht": 3})
    assert e.value.field == "widht"


# animation


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"time": -1.0}, "time"),
        ({"time": float("nan")}, "time"),
        ({"time": 2e6}, "time"),
        ({"update": "sometimes"}, "update"),
        ({"update_threshold": -0.1}, "update_threshold"),
    ],
)
def test_bad_settings_name_the_field(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# knobs


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"samples_per_pixel": 3}, "samples_per_pixel"),
        ({"width": 4096, "samples_per_pixel": 4}, "samples_per_pixel"),
        ({"min_weight": -0.1}, "min_weight"),
        ({"min_weight": float("nan")}, "min_weight"),
        ({"specialize": "yes"}, "specialize"),
        ({"method": "kd"}, "method"),
    ],
)
def test_knob_validation(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# hierarchical ray engine


@pytest.mark.parametrize("bad", [0, 1, -3, 65, 2.5, True, "16"])
def test_bad_tile_size_is_a_clear_error(bad):
    with pytest.raises(SceneError) as e:
        RenderSettings(width=16, height=16, method="hre", tile_size=bad)
    assert e.value.field == "tile_size"


# one declaration per setting (renderer.settings.SETTINGS)


def test_render_settings_are_the_declared_engine_settings():
    """RenderSettings' fields, order and defaults are the table's; quality is the service's (the encoder's)."""
    from dataclasses import fields

    from renderer.settings import SETTINGS

    engine = [s for s in SETTINGS if s.engine]
    assert [(f.name, f.default) for f in fields(RenderSettings)] == [(s.name, s.default) for s in engine]
    assert RenderSettings.names() == tuple(s.name for s in engine)
    assert [s.name for s in SETTINGS if not s.engine] == ["quality", "refine_samples", "refine_time_ms", "refine_noise"]
    assert RenderSettings().to_json() == {s.name: s.default for s in engine}
    for s in SETTINGS:
        s.check(s.default)  # every default is one of its values
        assert s.label and s.doc and s.methods() and s.metadata()["modes"]


def test_each_setting_names_the_methods_that_read_it():
    """A setting read per method points at Capabilities.settings (the registry line says which)."""
    from renderer.methods import capabilities
    from renderer.settings import METHOD_NAMES, setting

    assert setting("max_prims").methods() == [
        m for m in METHOD_NAMES if "max_prims" in capabilities(m, 1 << 30).settings
    ]
    assert "bih" in setting("max_prims").methods() and "kdtree" not in setting("max_prims").methods()
    assert setting("tile_size").methods() == ["hre"]
    assert setting("update_threshold").methods() == setting("update").methods()
    assert setting("width").methods() == list(METHOD_NAMES)


def test_a_setting_added_to_the_declaration_is_validated():
    """One entry in the table is a RenderSettings field with its default, bounds and messages."""
    from renderer.settings import SETTINGS, SettingSpec, build_render_settings

    extra = SettingSpec("gain", "number", 1.0, "brightness factor of the image", "Gain", bounds=(0.0, 4.0))
    choice = SettingSpec("tonemap", "string", "none", "tone mapping", "Tone mapping", choices=("none", "reinhard"))
    Settings = build_render_settings((*SETTINGS, extra, choice))
    s = Settings(gain=2.5)
    assert (s.gain, s.tonemap, s.width) == (2.5, "none", 640)
    assert Settings.from_json(s.to_json()) == s
    for kw, message in [
        ({"gain": 5.0}, "must be a number in [0, 4], got 5.0"),
        ({"gain": True}, "must be a number in [0, 4], got True"),
        ({"tonemap": "aces"}, "unknown tonemap 'aces'; one of none, reinhard"),
    ]:
        with pytest.raises(SceneError) as e:
            Settings(**kw)
        assert (e.value.field, e.value.message) == (next(iter(kw)), message)
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"gain": 2.0})  # the table as it is has no such setting
    assert e.value.field == "gain"
    with pytest.raises(ValueError):
        SettingSpec("bad", "string", "x", "a string without choices", "Bad")
