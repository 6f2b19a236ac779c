"""glTF 2.0's metallic-roughness material (the specification's appendix B BRDF): a Fresnel mix of a
GGX specular lobe over a Lambert diffuse one, a conductor with F0 = base colour where metallic,
with KHR_materials_emissive_strength, _ior, _transmission and _volume (attenuation). Its BSDF is
``shaders/bsdf_pbr.glsl``; docs/SHADING.md gives the formulas and docs/FORMATS.md what a glTF or
MTL file maps to.

Each texture slot ``<slot>`` (base colour, metallic-roughness, normal, emissive, occlusion,
transmission) is four parameters: ``<slot>_texture``, an index into the scene's textures (−1:
none); ``<slot>_texcoord``, the vertex UV set it reads (0 or 1); and KHR_texture_transform's
``uv' = M·uv + offset`` as ``<slot>_uv_matrix`` (M row-major: rotation · scale) and
``<slot>_uv_offset``. A texture's value multiplies its factor (the normal texture is scaled by
``normal_scale``; occlusion mixes by ``occlusion_strength``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .. import limits
from . import MaterialKind, choice, param

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
Vec4 = tuple[float, float, float, float]

# KHR_texture_transform's bounds: an offset or matrix entry beyond ±UV_BOUND repeats a texture
# more than float32 UVs can address.
UV_BOUND = 1e4
ALPHA_MODES = ("opaque", "mask", "blend")
# Whitted's ambient term of a PBR material: this × occlusion × base colour (the Phong kind's default
# ambient weight, so that both kinds light a scene alike; docs/SHADING.md, "PBR").
WHITTED_AMBIENT = 0.3
SLOTS = ("base_color", "metallic_roughness", "normal", "emissive", "occlusion", "transmission")


def _texture(what: str) -> int:
    return param(
        -1,
        lo=-1,
        hi=limits.MAX_TEXTURES - 1,
        integer=True,
        omit_default=True,
        doc=f"the scene's texture {what} reads (−1: none)",
    )


def _texcoord() -> int:
    return param(0, lo=0, hi=1, integer=True, omit_default=True, doc="the vertex UV set the texture reads (0 or 1)")


def _uv_matrix() -> Vec4:
    return param(
        (1.0, 0.0, 0.0, 1.0),
        lo=-UV_BOUND,
        hi=UV_BOUND,
        omit_default=True,
        doc="M of uv' = M·uv + offset, row-major (KHR_texture_transform: rotation · scale)",
    )


def _uv_offset() -> Vec2:
    return param((0.0, 0.0), lo=-UV_BOUND, hi=UV_BOUND, omit_default=True, doc="offset of uv' = M·uv + offset")


@dataclass(frozen=True)
class PbrMaterial(MaterialKind):
    """glTF 2.0's metallic-roughness material. Defaults are the specification's."""

    KIND: ClassVar[str] = "pbr"

    base_color: Vec3 = param((1.0, 1.0, 1.0), lo=0.0, hi=1.0, doc="baseColorFactor's RGB, linear")
    alpha: float = param(1.0, lo=0.0, hi=1.0, doc="baseColorFactor's alpha: coverage (see alpha_mode)")
    metallic: float = param(1.0, lo=0.0, hi=1.0, doc="metallicFactor: 0 a dielectric, 1 a conductor")
    roughness: float = param(1.0, lo=0.0, hi=1.0, doc="roughnessFactor, perceptual (GGX α = roughness²)")
    emissive: Vec3 = param((0.0, 0.0, 0.0), lo=0.0, hi=1.0, doc="emissiveFactor, linear RGB", omit_default=True)
    emissive_strength: float = param(
        1.0,
        lo=0.0,
        hi=limits.MAX_EMISSION,
        unit="W sr⁻¹ m⁻² per unit of emissive",
        doc="KHR_materials_emissive_strength: the emitted radiance is emissive × this",
        omit_default=True,
    )
    ior: float = param(1.5, lo=1.0, hi=limits.MAX_IOR, doc="KHR_materials_ior: the dielectric's index of refraction")
    transmission: float = param(
        0.0, lo=0.0, hi=1.0, doc="KHR_materials_transmission: the dielectric's share that refracts", omit_default=True
    )
    attenuation_color: Vec3 = param(
        (1.0, 1.0, 1.0),
        lo=0.0,
        hi=1.0,
        doc="KHR_materials_volume: the colour white light has after attenuation_distance inside",
        omit_default=True,
    )
    attenuation_distance: float = param(
        0.0,
        lo=0.0,
        hi=limits.MAX_COORDINATE,
        unit="world units",
        doc="KHR_materials_volume: the distance of attenuation_color (0: no attenuation, the glTF's infinity)",
        omit_default=True,
    )
    normal_scale: float = param(
        1.0, lo=-UV_BOUND, hi=UV_BOUND, doc="normalTexture.scale: the normal map's XY factor", omit_default=True
    )
    occlusion_strength: float = param(
        1.0, lo=0.0, hi=1.0, doc="occlusionTexture.strength (Whitted's ambient term)", omit_default=True
    )
    alpha_mode: str = choice(
        "opaque",
        ALPHA_MODES,
        doc="alphaMode: opaque ignores alpha, mask cuts at alpha_cutoff, blend is stochastic coverage",
        omit_default=True,
    )
    alpha_cutoff: float = param(0.5, lo=0.0, hi=1.0, doc="alphaCutoff of the mask mode", omit_default=True)
    double_sided: bool = choice(
        False, (False, True), doc="doubleSided: the back face shades as the front (else culled)", omit_default=True
    )

    base_color_texture: int = _texture("the base colour (sRGB RGB × alpha)")
    base_color_texcoord: int = _texcoord()
    base_color_uv_matrix: Vec4 = _uv_matrix()
    base_color_uv_offset: Vec2 = _uv_offset()
    metallic_roughness_texture: int = _texture("metallic (blue) and roughness (green)")
    metallic_roughness_texcoord: int = _texcoord()
    metallic_roughness_uv_matrix: Vec4 = _uv_matrix()
    metallic_roughness_uv_offset: Vec2 = _uv_offset()
    normal_texture: int = _texture("the tangent-space normal map")
    normal_texcoord: int = _texcoord()
    normal_uv_matrix: Vec4 = _uv_matrix()
    normal_uv_offset: Vec2 = _uv_offset()
    emissive_texture: int = _texture("the emissive colour (sRGB)")
    emissive_texcoord: int = _texcoord()
    emissive_uv_matrix: Vec4 = _uv_matrix()
    emissive_uv_offset: Vec2 = _uv_offset()
    occlusion_texture: int = _texture("ambient occlusion (red)")
    occlusion_texcoord: int = _texcoord()
    occlusion_uv_matrix: Vec4 = _uv_matrix()
    occlusion_uv_offset: Vec2 = _uv_offset()
    transmission_texture: int = _texture("the transmission factor (red)")
    transmission_texcoord: int = _texcoord()
    transmission_uv_matrix: Vec4 = _uv_matrix()
    transmission_uv_offset: Vec2 = _uv_offset()

    @property
    def emits(self) -> bool:
        return self.emissive_strength > 0.0 and any(c > 0.0 for c in self.emissive)

    @property
    def emission(self) -> Vec3:
        """The radiance a surface of this material emits where its emissive texture is white."""
        r, g, b = (c * self.emissive_strength for c in self.emissive)
        return (r, g, b)

    @property
    def reflects(self) -> bool:
        """Whether Whitted's rule traces a reflected ray: its weight, the specular Fresnel times
        (1 − roughness)², is 0 only for roughness 1 (docs/SHADING.md, "PBR")."""
        return self.roughness < 1.0

    @property
    def transmits(self) -> bool:
        """Whether some light refracts through it: the dielectric's transmissive share."""
        return self.transmission > 0.0 and self.metallic < 1.0

    @property
    def rough(self) -> bool:
        return self.roughness > 0.0

    @staticmethod
    def texture_slots() -> tuple[str, ...]:
        """The names of its texture slots (``<slot>_texture`` … ``<slot>_uv_offset``)."""
        return SLOTS

    def textures(self) -> tuple[int, ...]:
        """The scene textures this material reads."""
        return tuple(i for i in (getattr(self, f"{s}_texture") for s in SLOTS) if i >= 0)
