"""Shader text, and only text: the one assembler for the tracer and every ray-engine pass.

The tracer of a variant is ``raytrace.frag`` made of whole chunks, every variant the same list
in the same order, only three pieces chosen per variant:

- at ``//@HEADER@``, the header (:func:`tracer_header`): layout constants, the variant's
  defines and its bindings' declarations, generated from :mod:`renderer.gpu.gpu_layout` and the
  method's layout module. Every switch is defined in every variant, to 0 or 1
  (:func:`tracer_flags`: method, mode, features, the groups read, ``FEATURE_TRIANGLES`` …),
  and the chunks test it with ``#if NAME``, never ``#ifdef`` (the ray-engine passes' switches
  likewise, :func:`pass_defines`); a number stays a number (``N_LIGHTS``);
- at ``//@METHOD@``, the method's traversal (``shaders/<capabilities.shader>``), which tests
  primitives through the leaf interface of ``shaders/leaf.glsl``;
- at ``//@RECURSION_COLORS@``, the recursion mode's colours (:func:`recursion_color_function`).

``//@INCLUDE <file>`` lines include a file whole, in every variant (``triangles.glsl``,
``shapes.glsl``, ``shapes_tracer.glsl``, ``leaf.glsl``, ``lighting.glsl``; a method built from
other methods' files); ``bsdf_phong.glsl`` and ``lighting.glsl`` in the variants that carry light
beyond the thesis's (``FEATURE_LIGHTING``). A ray-engine pass is ``#version``, the same layout constants,
the pass's defines, ``rayengine_common.glsl`` and the pass's own file. The same text serves
moderngl and the browser (WebGL2, ``GET /api/shader``); nothing here touches OpenGL.
"""

from __future__ import annotations

from functools import cache

from ..config.methods import METHODS
from ..gpu import gpu_layout, texture_layout
from ..gpu.gpu_layout import Binding, Variant
from ..modes import MODES, RECURSION_COLORS
from ..resources import shader_dir
from . import first_hits
from .features import LIGHTING, SURFACE_FORMATS, SWITCHES

SHADER_DIR = shader_dir()  # the package's shaders/ (installed) or the checkout's top-level shaders/
HEADER_MARK = "//@HEADER@"
METHOD_MARK = "//@METHOD@"
RECURSION_MARK = "//@RECURSION_COLORS@\n"  # the whole line becomes recursion_color_function()
INCLUDE_MARK = "//@INCLUDE "  # a line "//@INCLUDE triangles.glsl" includes that file whole
MAX_INCLUDE_DEPTH = 4  # raytrace.frag → method_twolevel.glsl → method_bvh.glsl: a cycle is an error
COUNT_PREFIXES = ("PLANES_", "LIGHTS_")  # the count features (renderer.frame.features), compiled in as values
RUN_TIME_COUNT = -1  # N_PLANES / N_LIGHTS of a variant that reads the count from a uniform
# The ray-engine passes' switches (renderer/gl/ray_engine.py), each defined 0 or 1 in every pass:
# which full-screen pass (PASS_*), the cone pass of shadow rays (SHADOW), the primitive pass's
# culling (HRE), its shadow rays (ANY_HIT), heat mode's count (COUNT), the tests' cull matrix.
PASS_SWITCHES = (
    "PASS_PRIMARY",
    "PASS_MASK",
    "PASS_SURFACE",
    "PASS_SHADE",
    "SHADOW",
    "HRE",
    "ANY_HIT",
    "COUNT",
    "CULL_MATRIX",
)


@cache
def read(name: str) -> str:
    """The text of ``shaders/<name>`` (read once per process)."""
    return (SHADER_DIR / name).read_text()


def method_shader(method: str) -> str:
    """The file name of a single-pass method's traversal (ValueError for others)."""
    m = METHODS.get(method)
    if m is None or m.capabilities.shader is None:
        raise ValueError(f"method {method!r} has no one-pass traversal shader")
    return m.capabilities.shader


def tracer_bindings(variant: Variant) -> list[Binding]:
    """The textures, uniforms and record arrays the variant's shader declares and reads: the
    scene's and the camera's it needs (:meth:`Variant.reads_binding`), then its method's."""
    method = METHODS[variant.method].bindings if variant.spheres else ()
    return [b for b in (*gpu_layout.TRACER_BINDINGS, *method) if variant.reads_binding(b)]


@cache
def known_bindings() -> frozenset[str]:
    """Every binding name a layout declares: the tracer's and every method's."""
    return frozenset(b.name for b in (*gpu_layout.TRACER_BINDINGS, *(b for m in METHODS.values() for b in m.bindings)))


def tracer_flags(variant: Variant) -> dict[str, int]:
    """Every switch of the tracer's text, each defined in every variant, 0 or 1 (the chunks test
    them with ``#if NAME``, never ``#ifdef``: an ``#if`` on a name the host forgot reads 0 in
    GLSL, so a missing switch would silently select the wrong code): ``METHOD_<name>`` for every
    method and ``MODE_<name>`` for every mode, the one the variant traces 1; each of
    :data:`renderer.frame.features.SWITCHES` (removals, data formats, light), 1 where the variant carries
    it; ``READS_<GROUP>`` for each binding group (:meth:`Variant.reads`); the ``FEATURE_*`` flags
    (:func:`feature_flags`) and the host's choices (one RGBA8 image, the background variant,
    rasterised first hits)."""
    unknown = [f for f in variant.features if f not in SWITCHES and not f.startswith(COUNT_PREFIXES)]
    if unknown:
        raise ValueError(f"unknown feature defines {unknown}; one of renderer.frame.features.FEATURE_DEFINES")
    flags = {f"METHOD_{m.upper()}": int(m == variant.method) for m in METHODS}
    flags |= {f"MODE_{m.upper()}": int(m == variant.mode) for m in MODES}
    flags |= {name: int(name in variant.features) for name in SWITCHES}
    flags |= {f"READS_{g.upper()}": int(variant.reads(g)) for g in gpu_layout.GROUPS}
    flags |= {name: int(on) for name, on in feature_flags(variant).items()}
    flags |= {
        "IMAGE_ONLY": int(variant.image_only),
        "BACKGROUND": int(not variant.spheres),
        "FIRST_HITS": int(bool(variant.first_hits)),
        "FIRST_HITS_SPHERES": int(variant.first_hits == "spheres"),
        "FIRST_HITS_TILES": int(variant.first_hits == "tiles"),
    }
    return flags


def tracer_values(variant: Variant) -> dict[str, int]:
    """The tracer's compiled-in numbers: ``MAX_RECURSION_DEPTH``, and ``N_PLANES`` / ``N_LIGHTS``,
    the counts of a specialised variant (``PLANES_k`` / ``LIGHTS_k``) or ``-1`` where the generic
    loop reads them from uniforms; the tile lists' layout where first hits come in tiles."""
    values = {"MAX_RECURSION_DEPTH": int(variant.depth), "N_PLANES": RUN_TIME_COUNT, "N_LIGHTS": RUN_TIME_COUNT}
    for f in variant.features:
        for prefix, name in (("PLANES_", "N_PLANES"), ("LIGHTS_", "N_LIGHTS")):
            if f.startswith(prefix):
                values[name] = int(f[len(prefix) :])
    if variant.first_hits == "tiles":  # the tile lists' layout (renderer/frame/first_hits.py)
        values["TILE_ENTRY_TEXELS"] = first_hits.ENTRY_TEXELS
    return values


def tracer_header(variant: Variant) -> str:
    """Layout constants, the variant's switches (:func:`tracer_flags`) and numbers
    (:func:`tracer_values`), and its bindings' declarations."""
    unknown = set(variant.blocks) - {b.name for b in tracer_bindings(variant) if b.records}
    if unknown:
        raise ValueError(f"blocks {sorted(unknown)} are not record arrays the {variant.method} variant reads")
    kinds = ""  # the constants of the kinds and the integrator the variant carries
    if "TRIANGLES" in variant.features:
        kinds = gpu_layout.triangle_constants()
    if "SHAPES" in variant.features:
        kinds += gpu_layout.shape_constants()
    if "PBR" in variant.features:
        kinds += gpu_layout.pbr_constants()
    if "TEXTURES" in variant.features and "TRIANGLES" in variant.features:
        kinds += texture_layout.texture_glsl_constants()
    if variant.path:
        kinds += gpu_layout.path_constants()
    defines = {**tracer_flags(variant), **tracer_values(variant)}
    return (
        gpu_layout.glsl_header()
        + gpu_layout.tracer_constants()
        + kinds
        + METHODS[variant.method].glsl_defines()
        + "".join(f"#define {name} {value}\n" for name, value in defines.items())
        + gpu_layout.declarations(tracer_bindings(variant), tuple(variant.blocks))
    )


def tracer_source(
    method: str,
    mode: str,
    max_recursion_depth: int,
    extra_defines: tuple[str, ...] = (),
    blocks: tuple[str, ...] = (),
    image_only: bool = False,
    spheres: bool = True,
    first_hits: str = "",
) -> str:
    """The fragment shader of one variant: method × mode × recursion depth × feature defines,
    and the host's choices (record arrays in uniform blocks, one RGBA8 image, the background
    variant without spheres, a pass of rasterised first hits)."""
    variant = Variant(
        method, mode, int(max_recursion_depth), tuple(extra_defines), tuple(blocks), image_only, spheres, first_hits
    )
    return variant_source(variant)


def variant_source(variant: Variant) -> str:
    """The fragment shader of ``variant``: ``raytrace.frag`` with its includes, the header, the
    method's traversal and the recursion colours."""
    return (
        with_includes(read("raytrace.frag"))
        .replace(HEADER_MARK, tracer_header(variant))
        .replace(METHOD_MARK, with_includes(read(method_shader(variant.method))))
        .replace(RECURSION_MARK, recursion_color_function())
    )


def feature_flags(variant: Variant) -> dict[str, bool]:
    """The header's ``FEATURE_*`` flags, each defined to 0 or 1 in every variant:
    ``FEATURE_TRIANGLES`` and ``FEATURE_SHAPES``, the variant traces that kind (its data format,
    and not the background variant, which has no traversal and so meets no primitive);
    ``FEATURE_LIGHTING``, it carries one of :data:`renderer.frame.features.LIGHTING` (emission, an
    environment, the path integrator); ``FEATURE_PBR``, the scene has a glTF metallic-roughness
    material (the PBR data format: kinds in the material records, ``shaders/bsdf_pbr.glsl``);
    ``FEATURE_TEXTURES``, ``FEATURE_VERTEX_COLORS`` and
    ``FEATURE_TANGENTS``, it traces triangles whose PBR materials read textures (and UVs), vertex colours
    or tangents (renderer/gpu/texture_layout.py: only a triangle has them)."""
    traces_triangles = "TRIANGLES" in variant.features and variant.spheres
    return {
        "FEATURE_TRIANGLES": "TRIANGLES" in variant.features and variant.spheres,
        "FEATURE_SHAPES": "SHAPES" in variant.features and variant.spheres,
        "FEATURE_LIGHTING": any(f in LIGHTING for f in variant.features),
        "FEATURE_PBR": "PBR" in variant.features,
        **{f"FEATURE_{f}": f in variant.features and traces_triangles for f in SURFACE_FORMATS},
    }


def _glsl_float(x: float) -> str:
    text = repr(float(x))
    return text if "." in text or "e" in text else text + ".0"


def recursion_color_function() -> str:
    """GLSL ``vec3 recursion_color(int level)``: the colour of ray level 1, 2, … from
    :data:`renderer.modes.RECURSION_COLORS`, and its entry 0 (the primary ray missed) for
    any other level. The colours are defined in Python alone; this is how the tracer (and
    the browser, which compiles the same text) gets them."""

    def vec3(c) -> str:
        return "vec3(" + ", ".join(_glsl_float(x) for x in c) + ")"

    miss = RECURSION_COLORS[0]
    lines = [f"    if (level == {level}) return {vec3(c)};\n" for level, c in enumerate(RECURSION_COLORS) if level]
    other = f"vec3({_glsl_float(miss[0])})" if miss[0] == miss[1] == miss[2] else vec3(miss)
    return "vec3 recursion_color(int level) {\n" + "".join(lines) + f"    return {other};\n}}\n"


def with_includes(text: str, depth: int = 0) -> str:
    """``//@INCLUDE file`` lines replaced by the files, whole (their own includes too)."""
    if INCLUDE_MARK not in text:
        return text
    if depth >= MAX_INCLUDE_DEPTH:
        raise ValueError(f"//@INCLUDE nested deeper than {MAX_INCLUDE_DEPTH}: a cycle?")
    lines = []
    for line in text.splitlines(keepends=True):
        if line.startswith(INCLUDE_MARK):
            name = line[len(INCLUDE_MARK) :].strip()
            lines.append(f"// ---- {name} ----\n" + with_includes(read(name), depth + 1) + "\n")
        else:
            lines.append(line)
    return "".join(lines)


def vertex_source(first_hits: str = "") -> str:
    """The full-screen quad's vertex shader (the tracer and the ray engines' full-screen passes),
    or the spheres' screen quads of rasterised first hits (``first_hits`` ``"spheres"``), or their
    tiles' quads (``"tiles"``)."""
    return read({"spheres": "first_hits.vert", "tiles": "first_hit_tiles.vert"}.get(first_hits, "fullscreen.vert"))


def pass_defines(defines: tuple[str, ...] = ()) -> str:
    """The ``#define`` lines of a ray-engine pass: each of :data:`PASS_SWITCHES` 1 if named in
    ``defines``, else 0; a define with a value (``"TILE 8"``) as it is."""
    values = [d for d in defines if " " in d]
    unknown = [d for d in defines if " " not in d and d not in PASS_SWITCHES]
    if unknown:
        raise ValueError(f"unknown ray-engine pass switches {unknown}; one of {', '.join(PASS_SWITCHES)}")
    switches = [f"{name} {int(name in defines)}" for name in PASS_SWITCHES]
    return "".join(f"#define {d}\n" for d in (*switches, *values))


def pass_source(name: str, defines: tuple[str, ...] = ()) -> str:
    """A ray-engine shader: ``#version``, the layout constants, the defines (:func:`pass_defines`),
    the scene's declarations, the common part, then ``name``. (The passes' own ray textures and
    uniforms are declared in their files and bound by :mod:`renderer.gl.ray_engine`.)"""
    return (
        "#version 300 es\n"
        + gpu_layout.glsl_header()
        + pass_defines(defines)
        + gpu_layout.declarations(gpu_layout.RAY_ENGINE_BINDINGS)
        + with_includes(read("rayengine_common.glsl"))
        + read(name)
    )
