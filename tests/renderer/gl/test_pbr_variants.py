"""Every shader variant of a scene with glTF metallic-roughness materials (the ``PBR`` data format,
``FEATURE_PBR`` 1) compiles and links: every one-pass method × single-pass mode × integrator × the
primitive kinds, with the light beyond the thesis's, the PBR define alone, and the host's choices
(uniform blocks, the RGBA8 image, the background variant). The Phong variants are
tests/golden/test_variants_compile.py's."""

from __future__ import annotations

import hashlib
import itertools

import pytest

from renderer import limits
from renderer.config.methods import METHODS
from renderer.config.settings import SETTINGS
from renderer.frame import features as F
from renderer.frame.shader_source import variant_source, vertex_source
from renderer.gpu.gpu_layout import Variant
from renderer.modes import SINGLE_PASS_MODES

pytestmark = pytest.mark.gl

ONE_PASS = tuple(name for name, m in METHODS.items() if m.capabilities.shader)
INTEGRATORS = next(s.choices for s in SETTINGS if s.name == "integrator")
KINDS = ((), ("TRIANGLES", "SMOOTH_TRIANGLES"), ("SHAPES",))


def _ordered(defines) -> tuple[str, ...]:
    return tuple(d for d in F.FEATURE_DEFINES if d in set(defines))


def variants() -> list[Variant]:
    out = []
    for method, mode, integrator, kinds in itertools.product(ONE_PASS, SINGLE_PASS_MODES, INTEGRATORS, KINDS):
        if integrator == "path" and mode != "color":
            continue
        path = integrator == "path"
        depth = limits.MAX_PATH_DEPTH if path else limits.MAX_RECURSION_DEPTH
        light = ("EMISSION", "ENVIRONMENT_MAP", "PATH", "GUIDES") if path else ("EMISSION", "ENVIRONMENT")
        out.append(Variant(method, mode, depth, _ordered((*kinds, "PBR", "MATERIAL_TEXTURE", *light))))
    out.append(Variant("bih", "color", 3, ("PBR",)))
    out.append(Variant("bvh", "color", 1, _ordered(("PBR", "MATERIAL_TEXTURE", "NO_REFLECTION", "NO_TRANSMISSION"))))
    out.append(Variant("bvh", "recursion", 3, _ordered(("PBR", "MATERIAL_TEXTURE", "NO_SPLIT"))))
    out.append(Variant("bih", "color", 3, ("PBR",), (), True, spheres=False))
    return out


def test_every_pbr_variant_compiles_and_links(gl_renderer_released_after):
    ctx = gl_renderer_released_after.ctx
    texts: dict[str, tuple[Variant, str]] = {}
    for v in variants():
        text = variant_source(v)
        assert "#define FEATURE_PBR 1" in text
        texts.setdefault(hashlib.sha256(text.encode()).hexdigest(), (v, text))
    failed = []
    for v, text in texts.values():
        try:
            ctx.program(vertex_shader=vertex_source(), fragment_shader=text).release()
        except Exception as e:
            failed.append(f"{v}: {str(e)[-600:]}")
    assert not failed, f"{len(failed)} of {len(texts)} variants do not compile, e.g. {failed[:2]}"
    assert len(texts) > 30
