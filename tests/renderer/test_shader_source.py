"""Shader assembly (renderer.shader_source): layout constants come from the Python layout
modules through the host header (one definition each), and the two-level shader inlines
the BVH and kd-tree traversals once each. That the assembled texts do not change by
accident is ``tests/golden/``'s job."""

from __future__ import annotations

import re

import pytest

from renderer.accel import bvh_layout, kdtree_layout
from renderer.shader_source import tracer_source as shader_source
from tests.helpers import ROOT


@pytest.mark.parametrize("name,module", [("bvh", bvh_layout), ("kdtree", kdtree_layout)])
def test_shader_gets_layout_constants_from_python(name, module):
    """The one definition of each layout reaches the shader through the host header."""
    src = shader_source(name, "color", 1)
    for line in module.glsl_defines().splitlines():
        assert line in src
    method_src = (ROOT / "shaders" / f"method_{name}.glsl").read_text()
    for line in module.glsl_defines().splitlines():  # no second copy of the constants in the method file
        assert line.split()[1] not in re.findall(r"#define (\w+)", method_src)


def test_twolevel_shader_inlines_both_traversals():
    src = shader_source("twolevel", "color", 1)
    for name in ("method_bvh.glsl", "method_kdtree.glsl"):
        body = (ROOT / "shaders" / name).read_text()
        assert src.count(body) == 1
    assert "//@INCLUDE" not in src
