"""Every shader variant of a scene with glTF metallic-roughness materials (the ``PBR`` data format,
``FEATURE_PBR`` 1) compiles and links: every one-pass method × single-pass mode × integrator × the
primitive kinds, with the light beyond the thesis's, the PBR define alone, and the host's choices
(uniform blocks, the RGBA8 image, the background variant). The Phong variants are
tests/golden/test_variants_compile.py's."""

from __future__ import annotations

import pytest

from renderer.frame import features as F
from renderer.frame.shader_source import variant_source
from renderer.gpu.gpu_layout import Variant
from tests.golden.test_variants_compile import failed_to_link, product_variants

pytestmark = pytest.mark.gl


def _ordered(defines) -> tuple[str, ...]:
    return tuple(d for d in F.FEATURE_DEFINES if d in set(defines))


def variants() -> list[Variant]:
    out = product_variants(
        ((), ("TRIANGLES", "SMOOTH_TRIANGLES"), ("SHAPES",)),
        ("EMISSION", "ENVIRONMENT"),
        ("PBR", "MATERIAL_TEXTURE"),
        light_in_every_mode=True,
    )
    out.append(Variant("bih", "color", 3, ("PBR",)))
    out.append(Variant("bvh", "color", 1, _ordered(("PBR", "MATERIAL_TEXTURE", "NO_REFLECTION", "NO_TRANSMISSION"))))
    out.append(Variant("bvh", "recursion", 3, _ordered(("PBR", "MATERIAL_TEXTURE", "NO_SPLIT"))))
    out.append(Variant("bih", "color", 3, ("PBR",), (), True, spheres=False))
    return out


def test_every_pbr_variant_compiles_and_links(gl_renderer_released_after):
    vs = variants()
    assert all("#define FEATURE_PBR 1" in variant_source(v) for v in vs)
    failed, n_texts = failed_to_link(gl_renderer_released_after.ctx, vs, 600)
    assert not failed, f"{len(failed)} of {n_texts} variants do not compile, e.g. {failed[:2]}"
