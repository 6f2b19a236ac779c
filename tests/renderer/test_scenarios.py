"""The generated scenes of the thesis (renderer.scenarios): reproducible, inside the cube,
round-tripping through SPEC's JSON; bad arguments name their field."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.scenarios import scenario
from renderer.scene import Scene, SceneError


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
