"""Every shader variant the service can ask for compiles and links (llvmpipe, GLSL ES 3.00).

The variants come from the registries: every one-pass method (``METHODS``), every single-pass
mode (``SINGLE_PASS_MODES``), every integrator (the ``integrator`` setting's choices; paths in
colour only), the primitive kinds beyond spheres (``TRIANGLES``, ``SHAPES``, both), the light
beyond the thesis's (``renderer.frame.features.LIGHTING``), each define of
``renderer.frame.features.FEATURE_DEFINES`` on its own, the recursion depths that change the text
(1: primary rays only, 2: the least that spawns, the limits) and the host's choices (uniform
blocks, the RGBA8 image, the background variant, rasterised first hits). The full product is
far too large to compile; this covers every value of every axis, the kinds with every method,
mode and integrator, and compiles each distinct text once (by its hash), in one context.
"""

from __future__ import annotations

import hashlib
import itertools

from renderer import limits
from renderer.config.methods import METHODS
from renderer.config.settings import SETTINGS
from renderer.frame import features as F
from renderer.frame.shader_source import variant_source, vertex_source
from renderer.gpu.gpu_layout import Variant
from renderer.modes import SINGLE_PASS_MODES

ONE_PASS = tuple(name for name, m in METHODS.items() if m.capabilities.shader)
INTEGRATORS = next(s.choices for s in SETTINGS if s.name == "integrator")
KINDS = ((), ("TRIANGLES", "SMOOTH_TRIANGLES"), ("SHAPES",), ("TRIANGLES", "SHAPES"))
WHITTED_LIGHT = ("EMISSION", "ENVIRONMENT", "ENVIRONMENT_MAP")
PATH_LIGHT = ("EMISSION", "ENVIRONMENT_MAP", "PATH", "GUIDES")


def _ordered(defines) -> tuple[str, ...]:
    """Defines in FEATURE_DEFINES order (as renderer.frame.features emits them)."""
    return tuple(d for d in F.FEATURE_DEFINES if d in set(defines))


def product_variants(
    kinds_list=KINDS, whitted_light=WHITTED_LIGHT, extra: tuple[str, ...] = (), light_in_every_mode: bool = False
) -> list[Variant]:
    """Every one-pass method × single-pass mode × integrator × kinds (+ ``extra``), with the light
    beyond the thesis's: the path integrator's, or ``whitted_light`` (in the colour mode alone unless
    ``light_in_every_mode``)."""
    out = []
    for method, mode, integrator, kinds in itertools.product(ONE_PASS, SINGLE_PASS_MODES, INTEGRATORS, kinds_list):
        if integrator == "path" and mode != "color":
            continue
        path = integrator == "path"
        depth = limits.MAX_PATH_DEPTH if path else limits.MAX_RECURSION_DEPTH
        light = PATH_LIGHT if path else whitted_light if mode == "color" or light_in_every_mode else ()
        out.append(Variant(method, mode, depth, _ordered((*kinds, *extra, *light))))
    return out


def failed_to_link(ctx, variants: list[Variant], chars: int) -> tuple[list[str], int]:
    """The variants whose text (each distinct text once) does not compile and link in ``ctx``, each
    with the last ``chars`` characters of its log (negative: the first), and the count of texts."""
    texts: dict[str, tuple[Variant, str]] = {}
    for v in variants:
        text = variant_source(v)
        texts.setdefault(hashlib.sha256(text.encode()).hexdigest(), (v, text))
    failed = []
    for v, text in texts.values():
        vs = vertex_source(v.first_hits if v.first_hits in ("spheres", "tiles") else "")
        try:
            ctx.program(vertex_shader=vs, fragment_shader=text).release()
        except Exception as e:
            failed.append(f"{v}: {str(e)[-chars:] if chars > 0 else str(e)[:-chars]}")
    return failed, len(texts)


def variants() -> list[Variant]:
    # Every method × mode × integrator × kinds, with the light beyond the thesis's where it applies.
    out = product_variants()
    # Each define on its own (counts: the least and the most), on a sphere variant and a path one.
    counts = {F.PLANE_COUNTS[0], F.PLANE_COUNTS[1], F.PLANE_COUNTS[-1], F.LIGHT_COUNTS[0], F.LIGHT_COUNTS[-1]}
    singles = [d for d in F.FEATURE_DEFINES if d not in F.PLANE_COUNTS + F.LIGHT_COUNTS] + sorted(counts)
    for define in singles:
        out.append(Variant("bih", "color", 3, (define,)))
        out.append(Variant("bvh", "color", 4, _ordered(("TRIANGLES", "SHAPES", "PATH", "EMISSION", define))))
    # The depths that change the text, Whitted's and the path integrator's.
    for depth in (1, 2, limits.MAX_RECURSION_DEPTH):
        out.append(Variant("kdtree", "color", depth, ("EQUAL_RADII",)))
        out.append(Variant("kdtree", "recursion", depth, ("NO_SPLIT", "PLANES_1", "LIGHTS_1")))
    for depth in (1, 2, limits.MAX_PATH_DEPTH):
        out.append(Variant("bruteforce", "color", depth, ("PATH", "SHAPES")))
    # The host's choices: record arrays in uniform blocks, the RGBA8 image, the background variant
    # (no traversal: the kinds are off), and rasterised first hits.
    for method in ONE_PASS:
        records = tuple(b.name for b in METHODS[method].bindings if b.records and b.needs is None)
        out.append(Variant(method, "color", 3, ("EQUAL_RADII",), records, True))
    for mode in SINGLE_PASS_MODES:
        if mode != "heat":
            out.append(Variant("bih", mode, 3, ("TRIANGLES", "SHAPES", "EMISSION"), (), True, spheres=False))
    for mode, first_hits in itertools.product(("depth", "primid", "normal"), ("planes", "spheres", "tiles")):
        out.append(Variant("bih", mode, 1, ("EQUAL_RADII",), (), False, spheres=False, first_hits=first_hits))
    return out


def test_every_variant_compiles_and_links(gl_renderer):
    failed, n_texts = failed_to_link(gl_renderer.ctx, variants(), -400)
    assert not failed, f"{len(failed)} of {n_texts} variants do not compile, e.g. {failed[:3]}"
    assert n_texts > 100  # the covering above, deduplicated (a broken enumeration would be small)
