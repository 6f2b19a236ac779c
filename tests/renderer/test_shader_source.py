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
        # (as a sphere variant has it: the //@TRIANGLES and //@SHAPES marks removed, renderer.shader_source)
        from renderer.shader_source import with_shapes, with_triangles

        assert src.count(with_shapes(with_triangles(body, False), False)) == 1
    assert "//@INCLUDE" not in src and "//@TRIANGLES" not in src and "//@SHAPES" not in src


def test_triangle_marks_are_filled_only_for_variants_that_trace_triangles():
    """A sphere variant's text has no trace of the triangles (its marks are removed, line and
    all: tests/golden holds its hash); a TRIANGLES variant gets every mark's section, and
    the background variant of a mesh scene none (it has no traversal)."""
    from renderer.shader_source import TRIANGLES_MARK, read, triangle_sections, with_triangles

    sections = triangle_sections()
    for name in ("raytrace.frag", "method_bih.glsl", "method_bruteforce.glsl", "method_bvh.glsl", "method_kdtree.glsl"):
        marks = [
            line[len(TRIANGLES_MARK) :].strip() for line in read(name).splitlines() if line.startswith(TRIANGLES_MARK)
        ]
        assert marks and set(marks) <= set(sections), (name, marks)
        assert TRIANGLES_MARK not in with_triangles(read(name), False)
    for method in ("bih", "bruteforce", "bvh", "kdtree", "twolevel"):
        plain = shader_source(method, "color", 3, ("EQUAL_RADII",))
        assert "test_triangle" not in plain and "TRI_SLOT" not in plain and TRIANGLES_MARK not in plain
        tri = shader_source(method, "color", 3, ("EQUAL_RADII", "TRIANGLES", "SMOOTH_TRIANGLES"))
        assert "void test_triangle(" in tri and "g_shear = shear_of(q.d);" in tri and TRIANGLES_MARK not in tri
        bg = shader_source(method, "color", 3, ("EQUAL_RADII", "TRIANGLES"), spheres=False)
        assert "test_triangle" not in bg


def test_every_variant_defines_the_traced_primitive_kinds_as_0_or_1():
    """FEATURE_TRIANGLES and FEATURE_SHAPES are defined in every variant, 1 where it traces that kind
    (the background variant traces none), so code inside a function can test them with #if."""
    cases = [
        ((), True, 0, 0),
        (("TRIANGLES",), True, 1, 0),
        (("SHAPES",), True, 0, 1),
        (("TRIANGLES", "SHAPES"), True, 1, 1),
        (("TRIANGLES", "SHAPES"), False, 0, 0),
    ]
    for features, spheres, tri, shapes in cases:
        for extra in ((), ("PATH",)):
            src = shader_source("bvh", "color", 3, ("EQUAL_RADII", *extra, *features), spheres=spheres)
            defines = re.findall(r"^#define (FEATURE_\w+) (\d)$", src, flags=re.M)
            assert defines == [("FEATURE_TRIANGLES", str(tri)), ("FEATURE_SHAPES", str(shapes))], (features, extra)


def test_the_path_integrator_reads_the_material_through_the_bsdf_chunk():
    """The path loop holds no mark and no material texel: the surface record reads the material through
    its generated accessors, the loop calls bsdf_sample and next-event estimation calls bsdf_eval."""
    from renderer.shader_source import read

    lighting = read("lighting.glsl")
    path = lighting[lighting.index("#ifdef PATH") : lighting.index("//@SECTION main_begin")]
    assert "//@" not in path, "the path integrator's primitive-kind parts are #if FEATURE_* blocks"
    assert "u_materials" not in path and "u_material_vecs" not in path and "MATERIAL_TEXELS" not in path
    src = shader_source("bvh", "color", 3, ("EQUAL_RADII", "PATH", "TRIANGLES", "SHAPES"))
    for call in ("surface_record(", "bsdf_sample(", "bsdf_eval(", "sample_light(", "material_roughness(mat)"):
        assert call in src, call
    main = src[src.index("void path_main()") :]
    main = main[: main.index("\n}\n")]
    assert main.count("\n") <= 130, "path_main is the loop; the BSDF and the light sampling live apart"
