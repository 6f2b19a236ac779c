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
    for kw, field in [({"width": 0}, "width"), ({"height": 4097}, "height"), ({"mode": "x"}, "mode"),
                      ({"format": "gif"}, "format"), ({"max_tree_depth": 65}, "max_tree_depth"),
                      ({"max_recursion_depth": 9}, "max_recursion_depth"), ({"width": True}, "width")]:
        with pytest.raises(SceneError) as e:
            RenderSettings(**kw)
        assert e.value.field == field
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"widht": 3})
    assert e.value.field == "widht"


# animation (issue #9)

@pytest.mark.parametrize("kw,field", [({"time": -1.0}, "time"), ({"time": float("nan")}, "time"),
                                      ({"time": 2e6}, "time"), ({"update": "sometimes"}, "update"),
                                      ({"update_threshold": -0.1}, "update_threshold")])
def test_bad_settings_name_the_field(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# knobs (issue 5)

@pytest.mark.parametrize("kw,field", [({"samples_per_pixel": 3}, "samples_per_pixel"),
                                      ({"width": 4096, "samples_per_pixel": 4}, "samples_per_pixel"),
                                      ({"min_weight": -0.1}, "min_weight"), ({"min_weight": float("nan")}, "min_weight"),
                                      ({"specialize": "yes"}, "specialize"), ({"method": "kd"}, "method")])
def test_knob_validation(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# hierarchical ray engine (issue #8)

@pytest.mark.parametrize("bad", [0, 1, -3, 65, 2.5, True, "16"])
def test_bad_tile_size_is_a_clear_error(bad):
    with pytest.raises(SceneError) as e:
        RenderSettings(width=16, height=16, method="hre", tile_size=bad)
    assert e.value.field == "tile_size"
