"""The thesis's Phong material (Table 4.1): the Whitted terms (ambient, diffuse, specular,
reflection, refraction) and, for the path integrator, a Lambert lobe beside a mirror or GGX
reflective lobe and a smooth or rough transmissive one. Its BSDF is ``shaders/bsdf_phong.glsl``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .. import limits
from . import MaterialKind, param

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Material(MaterialKind):
    """Whitted/Phong material (thesis Table 4.1).

    The Phong kind of material (:mod:`renderer.materials`): each field below is declared once
    with its default, range, unit and doc, and the validation here, the JSON, the API's model
    and the GPU record (``shaders/bsdf_phong.glsl`` reads it as ``material_<name>(m)``) are made
    from those declarations.
    """

    KIND: ClassVar[str] = "phong"

    color: Vec3 = param((0.9, 0.3, 0.3), lo=0.0, hi=1.0, doc="RGB, each 0 … 1")
    ambient: float = param(0.3, lo=0.0, hi=1.0, doc="Phong's ambient weight (Whitted)")
    diffuse: float = param(0.3, lo=0.0, hi=1.0, doc="diffuse weight: Phong's kd, the path integrator's Lambert lobe")
    specular: float = param(0.1, lo=0.0, hi=1.0, doc="Phong's specular weight ks (Whitted)")
    shininess: float = param(40.0, lo=0.0, hi=limits.MAX_SHININESS, doc="Phong exponent")
    reflective: float = param(0.3, lo=0.0, hi=1.0, doc="weight kr of the reflected ray (a mirror; rough: GGX)")
    transmissive: float = param(0.0, lo=0.0, hi=1.0, doc="weight kt of the refracted ray (glass; rough: GGX)")
    ior: float = param(1.0, lo=0.0, hi=limits.MAX_IOR, lo_open=True, doc="refraction index inside / outside")
    # Emission lives in its own texture (u_emission), packed only for scenes that emit.
    emission: Vec3 = param(
        (0.0, 0.0, 0.0),
        lo=0.0,
        hi=limits.MAX_EMISSION,
        unit="W sr⁻¹ m⁻², linear RGB",
        doc="radiance emitted on the side the normal faces (an area light)",
        record=False,
        omit_default=True,
    )
    roughness: float = param(
        0.0,
        lo=0.0,
        hi=1.0,
        doc="GGX α of the path integrator's reflective and transmissive lobes (0: a mirror, smooth glass)",
        omit_default=True,
    )

    @property
    def emits(self) -> bool:
        return any(c > 0.0 for c in self.emission)

    @property
    def reflects(self) -> bool:
        """Whether a hit spawns a reflected ray (Whitted) or has a reflective lobe (paths)."""
        return self.reflective > 0.0

    @property
    def transmits(self) -> bool:
        """Whether a hit spawns a transmitted ray (Whitted) or has a transmissive lobe (paths)."""
        return self.transmissive > 0.0

    @property
    def rough(self) -> bool:
        """Whether its reflective and transmissive lobes are GGX rather than deltas (paths)."""
        return self.roughness > 0.0
