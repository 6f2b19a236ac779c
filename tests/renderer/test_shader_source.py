"""Shader assembly (renderer.shader_source): layout constants come from the Python layout
modules through the host header (one definition each), every chunk is whole syntax and is
switched by the header's FEATURE_* flags, and the two-level shader inlines the BVH and kd-tree
traversals once each. That the frames do not change by accident is ``tests/golden/``'s job
(the frame catalogue, and every variant compiled)."""

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
    assert src.count("void bvh_intersect(") == 1 and src.count("void kd_intersect(") == 1
    assert src.count("// ---- method_bvh.glsl ----") == 1 and src.count("// ---- method_kdtree.glsl ----") == 1
    assert "//@" not in src


SHADERS = ROOT / "shaders"
# What may stand at a "//@" line: the three per-variant pieces, whole-file includes, and the
# legacy marks inside lighting.glsl's path_main (their statements: path_legacy.glsl's sections).
ALLOWED_MARKS = re.compile(r"//@(HEADER@|METHOD@|RECURSION_COLORS@|INCLUDE [\w.]+)$")
LEGACY_MARKS = re.compile(r"//@(TRIANGLES|SHAPES) \w+$")


def _balanced(text: str) -> bool:
    """Whether the text's preprocessor conditionals and its braces and parentheses close inside it."""
    depth = 0
    for line in text.splitlines():
        word = line.strip().split(" ", 1)[0]
        if word in ("#if", "#ifdef", "#ifndef"):
            depth += 1
        elif word == "#endif":
            depth -= 1
        if depth < 0:
            return False
    code = re.sub(r"//[^\n]*", "", text)
    return depth == 0 and code.count("{") == code.count("}") and code.count("(") == code.count(")")


@pytest.mark.parametrize("path", sorted(SHADERS.glob("*.glsl")) + sorted(SHADERS.glob("*.frag")), ids=lambda p: p.name)
def test_every_chunk_is_whole_syntax(path):
    """Every shader file is whole: its conditionals and brackets close inside it, and it holds no
    mark but the allowed ones (the legacy marks in lighting.glsl only). The legacy sections of
    path_legacy.glsl are whole statements each."""
    from renderer.shader_source import sections_of

    text = path.read_text()
    assert _balanced(text), path.name
    for line in text.splitlines():
        if line.startswith("//@") and not line.startswith("//@SECTION "):
            legacy = path.name == "lighting.glsl" and LEGACY_MARKS.match(line)
            assert ALLOWED_MARKS.match(line) or legacy, (path.name, line)
    if path.name == "path_legacy.glsl":
        assert all(_balanced(s) for s in sections_of(path.name).values())
    else:
        assert "//@SECTION " not in text, path.name


def _flags(src: str) -> dict[str, int]:
    found = re.findall(r"^#define (FEATURE_\w+) (\d)$", src, re.M)
    assert len(found) == len(dict(found)), "each flag defined once"
    return {k: int(v) for k, v in found}


@pytest.mark.parametrize("method", ["bih", "bruteforce", "bvh", "kdtree", "twolevel"])
def test_feature_flags_are_always_defined_zero_or_one(method):
    """The header defines FEATURE_TRIANGLES, FEATURE_SHAPES and FEATURE_LIGHTING in every variant,
    1 where the variant traces the kind (its data format, and not the background variant) or
    carries light beyond the thesis's; the traversal tests primitives through leaf_hit or the
    kinds' ranges alone, and no mark is left in the text."""
    plain = shader_source(method, "color", 3, ("EQUAL_RADII",))
    assert _flags(plain) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0}
    both = shader_source(method, "color", 3, ("TRIANGLES", "SMOOTH_TRIANGLES", "SHAPES", "EMISSION"))
    assert _flags(both) == {"FEATURE_TRIANGLES": 1, "FEATURE_SHAPES": 1, "FEATURE_LIGHTING": 1}
    bg = shader_source(method, "color", 3, ("TRIANGLES", "SHAPES"), spheres=False)
    assert _flags(bg) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0}
    for src in (plain, both, bg):
        assert "//@" not in src
    if method == "bruteforce":
        assert "intersect_triangle_range(q, 0, u_num_triangles, h);" in both
    else:
        assert "leaf_hit(q, s, h);" in both and "test_sphere(q, s, h);" not in both.split("void leaf_hit(")[0]


def test_the_legacy_path_marks_get_their_statements_where_the_kind_is_traced():
    """path_main's marks: the triangles' geometric normal and the emitters' MIS weights where the
    variant traces triangles / shapes, nothing elsewhere."""
    tri = shader_source("bvh", "color", 4, ("TRIANGLES", "EMISSION", "PATH"))
    shapes = shader_source("bvh", "color", 4, ("SHAPES", "EMISSION", "PATH"))
    plain = shader_source("bvh", "color", 4, ("EMISSION", "PATH"))
    tri_mis, shape_mis = "u_emit_tri_area * max(cos_light", "u_emit_patch_area * max(-dot(d, ng)"
    assert "ng = s.ng;" in tri and tri_mis in tri and shape_mis not in tri
    assert "ng = s.ng;" not in shapes and shape_mis in shapes and tri_mis not in shapes
    assert "ng = s.ng;" not in plain and tri_mis not in plain and shape_mis not in plain
