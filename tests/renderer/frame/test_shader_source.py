"""Shader assembly (renderer.frame.shader_source): layout constants come from the Python layout
modules through the host header (one definition each), every chunk is whole syntax and is
switched by the header's FEATURE_* flags, and the two-level shader inlines the BVH and kd-tree
traversals once each. That the frames do not change by accident is ``tests/golden/``'s job
(the frame catalogue, and every variant compiled)."""

from __future__ import annotations

import re

import pytest

from renderer.accel import bvh_layout, kdtree_layout
from renderer.frame.shader_source import tracer_source as shader_source
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
    """The header defines FEATURE_TRIANGLES, FEATURE_SHAPES, FEATURE_LIGHTING, FEATURE_PBR and the
    surface formats' flags in every variant, 1 where the variant traces the kind (its data format, and
    not the background variant), carries light beyond the thesis's or has PBR material records; the
    traversal tests primitives through leaf_hit or the kinds' ranges alone, and no mark is left in the text."""
    surface_off = {"FEATURE_TEXTURES": 0, "FEATURE_VERTEX_COLORS": 0, "FEATURE_TANGENTS": 0, "FEATURE_PBR": 0}
    plain = shader_source(method, "color", 3, ("EQUAL_RADII",))
    assert _flags(plain) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0, **surface_off}
    both = shader_source(method, "color", 3, ("TRIANGLES", "SMOOTH_TRIANGLES", "SHAPES", "EMISSION"))
    assert _flags(both) == {"FEATURE_TRIANGLES": 1, "FEATURE_SHAPES": 1, "FEATURE_LIGHTING": 1, **surface_off}
    bg = shader_source(method, "color", 3, ("TRIANGLES", "SHAPES"), spheres=False)
    assert _flags(bg) == {"FEATURE_TRIANGLES": 0, "FEATURE_SHAPES": 0, "FEATURE_LIGHTING": 0, **surface_off}
    textured = ("TRIANGLES", "PBR", "TEXTURES", "VERTEX_COLORS", "TANGENTS")
    surface_on = {"FEATURE_TEXTURES": 1, "FEATURE_VERTEX_COLORS": 1, "FEATURE_TANGENTS": 1, "FEATURE_PBR": 1}
    assert _flags(shader_source(method, "color", 3, textured)) == {
        "FEATURE_TRIANGLES": 1,
        "FEATURE_SHAPES": 0,
        "FEATURE_LIGHTING": 0,
        **surface_on,
    }
    assert _flags(shader_source(method, "color", 3, textured, spheres=False))["FEATURE_TEXTURES"] == 0
    pbr = shader_source(method, "color", 3, ("PBR", "MATERIAL_TEXTURE"), spheres=False)
    assert _flags(pbr)["FEATURE_PBR"] == 1 and "#define pbr_metallic(m)" in pbr
    for src in (plain, both, bg):
        assert "//@" not in src
    if method == "bruteforce":
        assert "intersect_triangle_range(q, 0, u_num_triangles, h);" in both
    else:
        assert "leaf_hit(q, s, h);" in both and "test_sphere(q, s, h);" not in both.split("void leaf_hit(")[0]


def test_the_path_integrator_reads_the_material_through_the_bsdf_chunk():
    """The path loop holds no mark and no material texel: the surface record reads the material through
    its generated accessors, the loop calls bsdf_sample and next-event estimation calls bsdf_eval."""
    from renderer.frame.shader_source import read

    lighting = read("lighting.glsl")
    path = lighting[lighting.index("#if PATH") :]
    assert "//@" not in path, "the path integrator's primitive-kind parts are #if FEATURE_* blocks"
    assert "u_materials" not in path and "u_material_vecs" not in path and "MATERIAL_TEXELS" not in path
    src = shader_source("bvh", "color", 3, ("EQUAL_RADII", "PATH", "TRIANGLES", "SHAPES"))
    for call in ("surface_record(", "bsdf_sample(", "bsdf_eval(", "sample_light(", "material_roughness(mat)"):
        assert call in src, call
    main = src[src.index("void path_main()") :]
    main = main[: main.index("\n}\n")]
    assert main.count("\n") <= 130, "path_main is the loop; the BSDF and the light sampling live apart"


# ---- switches are defined 0 or 1 and tested with #if -------------------------------------------------
# GLSL reads a name no one defined as 0 inside #if, so a switch the host forgets selects the wrong code
# without an error; and an #ifdef on a switch defined 0 is true. Every switch is therefore defined in
# every variant and tested with #if NAME; the checks below run the preprocessor's conditionals over
# the text of every variant tests/golden/test_variants_compile.py compiles, and of every ray-engine pass.

DIRECTIVE = re.compile(r"^\s*#\s*(\w+)\s*(.*?)\s*(?://.*)?$")
TOKEN = re.compile(r"\d+|\w+|&&|\|\||==|!=|<=|>=|[-+*/%<>()!]")


def _expand(expr: str, macros: dict[str, str], where: str, depth: int = 0) -> str:
    """``expr`` with every name replaced by its object-like macro's body, recursively; a name that no
    ``#define`` in force defines fails the test (where GLSL would read 0)."""
    assert depth < 16, f"{where}: macro expansion too deep"
    out = []
    for tok in TOKEN.findall(expr):
        if tok == "defined":
            raise AssertionError(f"{where}: 'defined' in #if {expr!r}: switches are tested by value")
        if tok[0].isalpha() or tok[0] == "_":
            assert tok in macros, f"{where}: #if tests {tok!r}, which nothing defines (GLSL would read 0)"
            assert macros[tok], f"{where}: #if tests {tok!r}, defined without a value (define it 0 or 1)"
            out.append("(" + _expand(macros[tok], macros, where, depth + 1) + ")")
        else:
            out.append(tok)
    return " ".join(out)


def _value(expr: str, macros: dict[str, str], where: str) -> bool:
    text = _expand(expr, macros, where)
    text = text.replace("&&", " and ").replace("||", " or ")
    text = re.sub(r"!(?!=)", " not ", text).replace("/", "//")
    return bool(eval(text, {"__builtins__": {}}))  # integers and operators only (TOKEN)


def _conditionals(text: str, where: str) -> int:
    """Runs the text's ``#define``/``#undef``/``#if``/``#elif``/``#else``/``#endif`` as the GLSL
    preprocessor does (object-like macros; function-like ones are only names); fails on ``#ifdef``,
    ``#ifndef``, ``defined`` and on an ``#if`` over an undefined name. Returns the ``#if``\\ s evaluated."""
    macros: dict[str, str] = {}
    stack: list[tuple[bool, bool]] = []  # (this branch is active, some branch of this #if was taken)
    evaluated = 0
    for n, line in enumerate(text.splitlines(), 1):
        m = DIRECTIVE.match(line)
        if not m:
            continue
        word, rest = m.groups()
        at = f"{where}, line {n}"
        active = all(a for a, _ in stack)
        assert word not in ("ifdef", "ifndef"), f"{at}: {line.strip()!r}: test a switch with #if NAME"
        if word == "define" and active:
            name = re.match(r"\w+", rest).group()
            body = rest[len(name) :]
            macros[name] = "0" if body.startswith("(") else (body.strip() or "")
        elif word == "undef" and active:
            macros.pop(rest.split()[0], None)
        elif word == "if":
            on = active and _value(rest, macros, at)
            evaluated += active
            stack.append((on, on))
        elif word == "elif":
            outer = all(a for a, _ in stack[:-1])
            _, taken = stack.pop()
            on = outer and not taken and _value(rest, macros, at)
            evaluated += outer and not taken
            stack.append((on, taken or on))
        elif word == "else":
            _, taken = stack.pop()
            stack.append((not taken, True))
        elif word == "endif":
            stack.pop()
    assert not stack, f"{where}: an #if is not closed"
    return evaluated


def test_every_variant_defines_each_switch_it_tests():
    """Each variant the service can ask for (the compile catalogue) defines every name its #if lines
    test, and none is tested by #ifdef or defined(); the switches are exactly 0 or 1."""
    from renderer.frame.shader_source import tracer_flags, variant_source
    from tests.golden.test_variants_compile import variants

    checked = 0
    for v in variants():
        checked += _conditionals(variant_source(v), repr(v))
        assert set(tracer_flags(v).values()) <= {0, 1}
    assert checked > 1000


def _by_definedness(text: str) -> list[str]:
    """The preprocessor lines of ``text`` that test a name by whether it is defined."""
    lines = (line.strip() for line in text.splitlines())
    return [line for line in lines if re.match(r"#\s*(ifn?def\b|(el)?if\b.*\bdefined\b)", line)]


def test_no_shader_tests_a_switch_by_definedness():
    """No file of shaders/ and no shader text of the device client uses #ifdef, #ifndef or defined():
    the host defines every switch, 0 or 1 (a test by definedness would see a 0 as on)."""
    sources = [*SHADERS.glob("*.glsl"), *SHADERS.glob("*.frag"), *SHADERS.glob("*.vert")]
    sources += sorted((ROOT / "client_web" / "js").rglob("*.js"))
    found = {p.name: hits for p in sources if (hits := _by_definedness(p.read_text()))}
    assert not found


def test_every_ray_engine_pass_defines_each_switch_it_tests():
    """The ray-engine passes as renderer/gl/ray_engine.py builds them: each switch 0 or 1, every
    name an #if tests defined; a switch the host does not know is refused."""
    from renderer.frame.shader_source import PASS_SWITCHES, pass_source

    passes = [("rayengine_pass.frag", (p,)) for p in ("PASS_PRIMARY", "PASS_MASK", "PASS_SURFACE", "PASS_SHADE")]
    passes += [("rayengine_cones.frag", ("TILE 8", *s)) for s in ((), ("SHADOW",))]
    for name in ("rayengine_prim.vert", "rayengine_prim.frag"):
        passes += [(name, d) for d in ((), ("CULL_MATRIX",), ("HRE",), ("HRE", "ANY_HIT"), ("ANY_HIT",), ("COUNT",))]
    for name, defines in passes:
        src = pass_source(name, defines)
        assert _conditionals(src, f"{name} {defines}") > 0
        for switch in PASS_SWITCHES:
            assert f"#define {switch} {int(switch in defines)}\n" in src
    with pytest.raises(ValueError, match="PASS_SHADOW"):
        pass_source("rayengine_pass.frag", ("PASS_SHADOW",))


def test_the_device_clients_own_shaders_get_their_switch_defined():
    """The device client's resolve and accumulate shaders test GUIDES with #if; every program made of
    them goes through withGuides, which defines it 0 or 1."""
    js = (ROOT / "client_web" / "js" / "device" / "device_gl.js").read_text()
    for name in ("RESOLVE_FS", "ACCUMULATE_FS"):
        body = js[js.index(f"const {name} = `") :]
        body = body[: body.index("`;")]
        assert "#if GUIDES" in body
        uses = re.findall(rf"[\w.(]*\(?\b{name}\b[^)]*\)?", js.replace(f"const {name} =", ""))
        assert uses and all(u.startswith("withGuides(") for u in uses), uses
    assert "#define GUIDES ${on ? 1 : 0}" in js
