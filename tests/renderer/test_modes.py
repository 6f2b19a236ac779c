"""The render modes' colours are written once (renderer/modes.py): the tracer is assembled
with them, and its other false-colour numbers are the same as the Python ones.

(The legend's side is tests/server/api/routes/test_meta.py, ``/api/info``, and tests/browser/test_layout.py.)
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from renderer.frame import shader_source
from renderer.limits import MAX_RECURSION_DEPTH
from renderer.modes import (
    HEAT_SCALE,
    PRIMID_FACTORS,
    RECURSION_COLOR_NAMES,
    RECURSION_COLORS,
    SINGLE_PASS_MODES,
    heat_image,
    primid_colors,
)

FLOAT = r"(-?\d+(?:\.\d*)?(?:e-?\d+)?)"
VEC3 = rf"vec3\({FLOAT}, {FLOAT}, {FLOAT}\)"


def glsl_recursion_colors(text: str) -> np.ndarray:
    """The colours of ``recursion_color`` in shader text, index = level (0: every other level)."""
    body = re.search(r"vec3 recursion_color\(int level\) \{\n(.*?)\n\}", text, re.S)
    assert body, "no recursion_color() in the shader"
    levels = {
        int(m[1]): tuple(map(float, m.groups()[1:]))
        for m in re.finditer(rf"if \(level == (\d+)\) return {VEC3};", body[1])
    }
    other = re.search(rf"return (?:vec3\({FLOAT}\)|{VEC3});\s*$", body[1])
    assert other, "recursion_color() has no colour for the other levels"
    miss = (float(other[1]),) * 3 if other[1] is not None else tuple(map(float, other.groups()[1:]))
    assert sorted(levels) == list(range(1, len(levels) + 1))
    return np.array([miss, *(levels[k] for k in sorted(levels))])


def test_every_level_has_a_color_and_a_name():
    assert RECURSION_COLORS.shape == (MAX_RECURSION_DEPTH + 1, 3)
    assert len(RECURSION_COLOR_NAMES) == len(RECURSION_COLORS)
    assert ((RECURSION_COLORS >= 0) & (RECURSION_COLORS <= 1)).all()
    assert len({tuple(c) for c in RECURSION_COLORS}) == len(RECURSION_COLORS), "two levels look the same"


def test_the_generated_function_holds_the_python_colors():
    np.testing.assert_array_equal(glsl_recursion_colors(shader_source.recursion_color_function()), RECURSION_COLORS)


def test_the_shader_file_has_no_colors_of_its_own():
    source = shader_source.read("raytrace.frag")
    assert source.count(shader_source.RECURSION_MARK) == 1
    assert not re.search(r"^\s*vec3 recursion_color\(", source, re.M), "the colours are the host's to write"


@pytest.mark.parametrize("mode", SINGLE_PASS_MODES)
def test_every_tracer_variant_is_assembled_with_them(mode):
    text = shader_source.tracer_source("bih", mode, 3)
    assert "//@RECURSION_COLORS@" not in text
    np.testing.assert_array_equal(glsl_recursion_colors(text), RECURSION_COLORS)
    if mode == "recursion":
        assert "image = recursion_color(deepest);" in text


def test_primid_and_heat_literals_are_the_python_numbers():
    source = shader_source.read("raytrace.frag")
    primid = re.search(rf"fract\(float\(primary_id\) \* {VEC3}\) \* 0\.8 \+ 0\.2", source)
    assert primid, "the primid mode's colour expression changed: update this test and renderer.modes"
    np.testing.assert_array_equal(np.array(primid.groups(), float), PRIMID_FACTORS)
    heat = re.search(
        rf"image = min\(vec3\({FLOAT} \* float\(g_counters\.z\), {FLOAT} \* float\(g_counters\.y\), "
        rf"{FLOAT} \* float\(g_counters\.x\)\), vec3\(1\.0\)\);",
        source,
    )
    assert heat, "the heat mode's colour expression changed: update this test and renderer.modes"
    # red: sphere tests (counter z), green: gaps (y), blue: node visits (x), as heat_image
    assert tuple(map(float, heat.groups())) == (HEAT_SCALE["tests"], HEAT_SCALE["gaps"], HEAT_SCALE["nodes"])
    np.testing.assert_array_equal(
        heat_image(np.array([1]), np.array([1]), np.array([1]))[0],
        [HEAT_SCALE["tests"], HEAT_SCALE["gaps"], HEAT_SCALE["nodes"]],
    )
    x = 7 * PRIMID_FACTORS
    np.testing.assert_allclose(primid_colors(np.array([7, -1])), [(x - np.floor(x)) * 0.8 + 0.2, [0.0, 0.0, 0.0]])
