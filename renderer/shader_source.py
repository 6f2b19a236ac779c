"""Shader text, and only text: the one assembler for the tracer and every ray-engine pass.

The tracer of a variant is ``raytrace.frag`` with the layout header and the variant's
defines after ``#version`` (at ``//@HEADER@``) and the method's traversal
(``shaders/<capabilities.shader>``) spliced in at ``//@METHOD@`` and the recursion mode's
colours (:data:`renderer.modes.RECURSION_COLORS`) at ``//@RECURSION_COLORS@``; in a variant that traces
triangles (the ``TRIANGLES`` data format) the ``//@TRIANGLES <name>`` marks of both get the
sections of ``shaders/triangles.glsl``, in every other variant they are removed, so a
sphere-only variant's text is exactly the one before meshes; likewise the ``//@SHAPES <name>``
marks get ``shaders/shapes_tracer.glsl``'s sections (and ``shaders/shapes.glsl``) in a
variant that traces analytic shapes (the ``SHAPES`` data format) only. A ray-engine pass is
``#version``, the same header, the pass's defines, ``rayengine_common.glsl`` and the
pass's own file. The same text serves moderngl and the browser (WebGL2, ``GET
/api/shader``); nothing here touches OpenGL.
"""

from __future__ import annotations

from functools import cache

from . import first_hits, gpu_layout
from .features import LIGHTING
from .gpu_layout import Binding, Variant
from .methods import METHODS
from .modes import RECURSION_COLORS
from .resources import shader_dir

SHADER_DIR = shader_dir()  # the package's shaders/ (installed) or the checkout's top-level shaders/
HEADER_MARK = "//@HEADER@"
METHOD_MARK = "//@METHOD@"
RECURSION_MARK = "//@RECURSION_COLORS@\n"  # the whole line becomes recursion_color_function()
INCLUDE_MARK = "//@INCLUDE "  # a line "//@INCLUDE method_bvh.glsl" in a method file inlines that file
# A line "//@TRIANGLES <name>" in the tracer or a traversal: section <name> of TRIANGLES_FILE in a
# variant that traces triangles, nothing at all in any other (with_triangles).
TRIANGLES_MARK = "//@TRIANGLES "
TRIANGLES_FILE = "triangles.glsl"
SECTION_MARK = "//@SECTION "
# Likewise "//@SHAPES <name>": section <name> of SHAPES_FILE (section "library": shaders/shapes.glsl, the
# intersection tests) in a variant that traces analytic shapes (the SHAPES data format), nothing in any
# other (with_shapes). A tree method's sections that open its traversal to trees without spheres
# (TREE_SECTIONS of TRIANGLES_FILE) serve a variant with shapes but no triangles too.
SHAPES_MARK = "//@SHAPES "
SHAPES_FILE = "shapes_tracer.glsl"
SHAPES_LIBRARY = "shapes.glsl"
TREE_SECTIONS = frozenset({"bih_box", "if0", "end_if0"})
# Likewise "//@LIGHTING <name>": section <name> of LIGHTING_FILE in a variant that carries one of
# renderer.features.LIGHTING (emission, an environment, the path integrator), nothing in any other.
LIGHTING_MARK = "//@LIGHTING "
LIGHTING_FILE = "lighting.glsl"


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


def tracer_header(variant: Variant) -> str:
    """Layout constants, the variant's defines and its bindings' declarations."""
    unknown = set(variant.blocks) - {b.name for b in tracer_bindings(variant) if b.records}
    if unknown:
        raise ValueError(f"blocks {sorted(unknown)} are not record arrays the {variant.method} variant reads")
    defines = [
        f"METHOD_{variant.method.upper()}",
        f"MODE_{variant.mode.upper()}",
        f"MAX_RECURSION_DEPTH {int(variant.depth)}",
        *variant.features,
        *variant.defines(),
    ]
    for f in variant.features:  # compiled-in counts (renderer.features): PLANES_k → N_PLANES k
        for prefix, name in (("PLANES_", "N_PLANES"), ("LIGHTS_", "N_LIGHTS")):
            if f.startswith(prefix):
                defines.append(f"{name} {int(f[len(prefix) :])}")
    if variant.image_only:
        defines.append("IMAGE_ONLY")
    if not variant.spheres:
        defines.append("BACKGROUND")
    if variant.first_hits:
        defines += ["FIRST_HITS", f"FIRST_HITS_{variant.first_hits.upper()}"]
    if variant.first_hits == "tiles":  # the tile lists' layout (renderer/first_hits.py)
        defines.append(f"TILE_ENTRY_TEXELS {first_hits.ENTRY_TEXELS}")
    # Features as 0/1, defined in every variant, for code inside a function that reads #if FEATURE_X.
    defines += [f"FEATURE_TRIANGLES {int(traces_triangles(variant))}", f"FEATURE_SHAPES {int(traces_shapes(variant))}"]
    triangles = ""
    if "TRIANGLES" in variant.features:  # (only there: a sphere variant's text stays as it was)
        triangles = gpu_layout.triangle_constants() + "".join(
            f"#define READS_{g.upper()}\n" for g in gpu_layout.SILENT_GROUPS if variant.reads(g)
        )
    if "SHAPES" in variant.features:
        triangles += gpu_layout.shape_constants()
    if variant.path:
        triangles += gpu_layout.path_constants()
    return (
        gpu_layout.glsl_header()
        + gpu_layout.tracer_constants()
        + triangles
        + METHODS[variant.method].glsl_defines()
        + "".join(f"#define {d}\n" for d in defines)
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
    """The fragment shader of ``variant``."""
    method_src = _with_includes(read(method_shader(variant.method)))
    text = (
        _with_includes(read("raytrace.frag"))
        .replace(HEADER_MARK, tracer_header(variant))
        .replace(METHOD_MARK, method_src)
        .replace(RECURSION_MARK, recursion_color_function())
    )
    text = with_sections(text, LIGHTING_MARK, LIGHTING_FILE, any(f in LIGHTING for f in variant.features))
    shapes = traces_shapes(variant)
    text = with_shapes(text, shapes)
    if shapes and not traces_triangles(variant):  # a tree of spheres and shapes: may have no sphere
        return with_sections(text, TRIANGLES_MARK, TRIANGLES_FILE, True, only=TREE_SECTIONS)
    return with_triangles(text, traces_triangles(variant))


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


def traces_triangles(variant: Variant) -> bool:
    """Whether the variant traces triangles: the TRIANGLES data format, and not the
    background variant (which has no traversal and so meets no triangle)."""
    return "TRIANGLES" in variant.features and variant.spheres


@cache
def triangle_sections() -> dict[str, str]:
    """``shaders/triangles.glsl`` cut at its ``//@SECTION <name>`` lines: name → text."""
    return sections_of(TRIANGLES_FILE)


@cache
def sections_of(name: str) -> dict[str, str]:
    """``shaders/<name>`` cut at its ``//@SECTION <name>`` lines: name → text."""
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in read(name).splitlines(keepends=True):
        if line.startswith(SECTION_MARK):
            current = sections.setdefault(line[len(SECTION_MARK) :].strip(), [])
        elif current is not None:
            current.append(line)
    return {name: "".join(lines).rstrip("\n") + "\n" for name, lines in sections.items()}


def with_triangles(text: str, triangles: bool) -> str:
    """The ``//@TRIANGLES <name>`` marks of ``text`` replaced by their sections of
    ``shaders/triangles.glsl`` (``triangles``), or removed, line and all: a variant without
    triangles is then byte for byte the text it was before meshes (tests/golden), so
    sphere-only frames compile to the same program and render the same pixels. A mark
    without a section is an error (KeyError)."""
    return with_sections(text, TRIANGLES_MARK, TRIANGLES_FILE, triangles)


def traces_shapes(variant: Variant) -> bool:
    """Whether the variant traces analytic shapes: the SHAPES data format, not the background variant."""
    return "SHAPES" in variant.features and variant.spheres


@cache
def shape_sections() -> dict[str, str]:
    """``shaders/shapes_tracer.glsl``'s sections, and ``library``: ``shaders/shapes.glsl`` whole."""
    return {**sections_of(SHAPES_FILE), "library": read(SHAPES_LIBRARY).rstrip("\n") + "\n"}


def with_shapes(text: str, shapes: bool) -> str:
    """The ``//@SHAPES <name>`` marks of ``text`` replaced by their sections (``shapes``), or
    removed, line and all: a variant without shapes is byte for byte the text it was before."""
    return with_sections(text, SHAPES_MARK, SHAPES_FILE, shapes, sections=shape_sections())


def with_sections(
    text: str,
    mark: str,
    name: str,
    on: bool,
    only: frozenset[str] | None = None,
    sections: dict[str, str] | None = None,
) -> str:
    """The ``<mark><section>`` lines of ``text`` replaced by those sections of ``shaders/<name>``
    (``on``; ``only``: just the sections named there, the other marks removed), or removed,
    line and all. ``sections``: the sections to use instead of the file's."""
    if mark not in text:
        return text
    if sections is None:
        sections = sections_of(name) if on else {}
    out = []
    for line in text.splitlines(keepends=True):
        if line.startswith(mark):
            section = line[len(mark) :].strip()
            if on and (only is None or section in only):
                out.append(sections[section])
        else:
            out.append(line)
    return "".join(out)


def _with_includes(text: str) -> str:
    """Inline ``//@INCLUDE file`` lines (one level: a method built from other methods)."""
    lines = []
    for line in text.splitlines(keepends=True):
        if line.startswith(INCLUDE_MARK):
            name = line[len(INCLUDE_MARK) :].strip()
            lines.append(f"// ---- {name} ----\n" + read(name) + "\n")
        else:
            lines.append(line)
    return "".join(lines)


def vertex_source(first_hits: str = "") -> str:
    """The full-screen quad's vertex shader (the tracer and the ray engines' full-screen passes),
    or the spheres' screen quads of rasterised first hits (``first_hits`` ``"spheres"``), or their
    tiles' quads (``"tiles"``)."""
    return read({"spheres": "first_hits.vert", "tiles": "first_hit_tiles.vert"}.get(first_hits, "fullscreen.vert"))


def pass_source(name: str, defines: tuple[str, ...] = ()) -> str:
    """A ray-engine shader: ``#version``, the layout constants, the defines, the scene's
    declarations, the common part, then ``name``. (The passes' own ray textures and
    uniforms are declared in their files and bound by :mod:`renderer.gl.ray_engine`.)"""
    return (
        "#version 300 es\n"
        + gpu_layout.glsl_header()
        + "".join(f"#define {d}\n" for d in defines)
        + gpu_layout.declarations(gpu_layout.RAY_ENGINE_BINDINGS)
        + _with_includes(read("rayengine_common.glsl"))
        + read(name)
    )
