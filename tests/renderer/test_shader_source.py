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
# What may stand at a "//@" line: the three per-variant pieces and whole-file includes.
ALLOWED_MARKS = re.compile(r"//@(HEADER@|METHOD@|RECURSION_COLORS@|INCLUDE [\w.]+)$")


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
    mark but the allowed ones (no sections, no per-kind marks)."""
    text = path.read_text()
    assert _balanced(text), path.name
    for line in text.splitlines():
        if line.startswith("//@"):
            assert ALLOWED_MARKS.match(line), (path.name, line)


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
    surface_off = {"FEATURE_TEXTURES": 0, "FEATURE_VERTEX_COLORS": 0, "FEATURE_TANGENTS": 0}
    plain = shader_source(method, "color", 3, ("EQUAL_RADII",))
    assert _flags(plain) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0, **surface_off}
    both = shader_source(method, "color", 3, ("TRIANGLES", "SMOOTH_TRIANGLES", "SHAPES", "EMISSION"))
    assert _flags(both) == {"FEATURE_TRIANGLES": 1, "FEATURE_SHAPES": 1, "FEATURE_LIGHTING": 1, **surface_off}
    bg = shader_source(method, "color", 3, ("TRIANGLES", "SHAPES"), spheres=False)
    assert _flags(bg) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0, **surface_off}
    textured = ("TRIANGLES", "TEXTURES", "VERTEX_COLORS", "TANGENTS")
    surface_on = {"FEATURE_TEXTURES": 1, "FEATURE_VERTEX_COLORS": 1, "FEATURE_TANGENTS": 1}
    assert _flags(shader_source(method, "color", 3, textured)) == {
        "FEATURE_TRIANGLES": 1,
        "FEATURE_SHAPES": 0,
        "FEATURE_LIGHTING": 0,
        **surface_on,
    }
    assert _flags(shader_source(method, "color", 3, textured, spheres=False))["FEATURE_TEXTURES"] == 0
    for src in (plain, both, bg):
        assert "//@" not in src
    if method == "bruteforce":
        assert "intersect_triangle_range(q, 0, u_num_triangles, h);" in both
    else:
        assert "leaf_hit(q, s, h);" in both and "test_sphere(q, s, h);" not in both.split("void leaf_hit(")[0]


def test_the_path_integrator_reads_the_material_through_the_bsdf_chunk():
    """The path loop holds no mark and no material texel: the surface record reads the material through
    its generated accessors, the loop calls bsdf_sample and next-event estimation calls bsdf_eval."""
    from renderer.shader_source import read

    lighting = read("lighting.glsl")
    path = lighting[lighting.index("#ifdef PATH") :]
    assert "//@" not in path, "the path integrator's primitive-kind parts are #if FEATURE_* blocks"
    assert "u_materials" not in path and "u_material_vecs" not in path and "MATERIAL_TEXELS" not in path
    src = shader_source("bvh", "color", 3, ("EQUAL_RADII", "PATH", "TRIANGLES", "SHAPES"))
    for call in ("surface_record(", "bsdf_sample(", "bsdf_eval(", "sample_light(", "material_roughness(mat)"):
        assert call in src, call
    main = src[src.index("void path_main()") :]
    main = main[: main.index("\n}\n")]
    assert main.count("\n") <= 130, "path_main is the loop; the BSDF and the light sampling live apart"
