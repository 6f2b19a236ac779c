"""The material boundary: a material kind declares its parameters once, and everything else is made
from that declaration.

A kind is a frozen dataclass deriving :class:`MaterialKind` (the thesis's Phong kind:
:class:`renderer.materials.phong.Material`; glTF's metallic-roughness:
:class:`renderer.materials.pbr.PbrMaterial`), whose fields are made by :func:`param`: a default, a
range (or a set of choices), a unit and a doc each. From those fields come

- the kind's validation, JSON reading and writing (:class:`MaterialKind`'s ``__post_init__``,
  ``to_json``, ``from_json`` loop over :func:`material_params`; the JSON names a kind other than
  Phong by ``"kind"``);
- the API's model of it (``server/api/schemas.py``'s ``MaterialModel``: names, ranges, defaults and
  descriptions of the OpenAPI schema);
- its GPU record: :func:`record_layout` places the fields that go to the GPU in RGBA32F texels
  in declaration order (a vector never straddles two texels), :func:`pack_records` writes them and
  :func:`glsl_accessors` names them for the shaders (``material_color(m)``, ``material_ior(m)``…,
  over the tracer's ``MATERIAL_TEXEL(m, k)``).

The kind's BSDF is its own shader chunk (``shaders/bsdf_phong.glsl`` for the Phong kind), which
reads the record through those accessors. Adding a parameter is one more :func:`param` field, the
BSDF code that uses it and its tests: the texel count, the packer, the accessors, the API and the
JSON follow.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from ..errors import SceneError, construct, finite_number, json_object

PARAM_KEY = "material_param"  # where a dataclass field's metadata holds its MaterialParam
TEXEL_FLOATS = 4  # an RGBA32F texel, or one vec4 of the uniform array
COMPONENTS = "xyzw"


@dataclass(frozen=True)
class MaterialParam:
    """One declared parameter of a material kind.

    ``default``: a number, or a tuple of ``size`` numbers (each bounded alike); ``lo``/``hi``:
    its range (``lo_open``: ``lo`` itself refused); ``unit``: what it measures in (empty: a plain
    weight); ``doc``: what it does, as the API describes it; ``record``: whether it goes to the GPU
    material record (False: packed elsewhere, e.g. emission, which only emitting scenes carry);
    ``omit_default``: the JSON leaves it out while it equals its default; ``integer``: only whole
    numbers (a texture index); ``choices``: the JSON values it takes (strings, booleans), its
    record holding the chosen one's position (``lo``/``hi`` then bound that position)."""

    default: float | tuple[float, ...]
    lo: float
    hi: float
    doc: str
    unit: str = ""
    lo_open: bool = False
    record: bool = True
    omit_default: bool = False
    integer: bool = False
    choices: tuple[Any, ...] = ()

    @property
    def size(self) -> int:
        """Numbers in the parameter: 1 for a scalar, 3 for an RGB triple."""
        return len(self.default) if isinstance(self.default, tuple) else 1


def param(
    default: float | tuple[float, ...],
    *,
    lo: float,
    hi: float,
    doc: str,
    unit: str = "",
    lo_open: bool = False,
    record: bool = True,
    omit_default: bool = False,
    integer: bool = False,
) -> Any:
    """A material kind's dataclass field declared with its range, unit and doc (see MaterialParam)."""
    spec = MaterialParam(default, lo, hi, doc, unit, lo_open, record, omit_default, integer)
    if not 1 <= spec.size <= TEXEL_FLOATS:
        raise ValueError(f"a material parameter has 1 to {TEXEL_FLOATS} numbers, got {spec.size}")
    return field(default=default, metadata={PARAM_KEY: spec})


def choice(default: Any, choices: tuple[Any, ...], *, doc: str, omit_default: bool = False) -> Any:
    """A material kind's dataclass field that takes one of ``choices`` (JSON strings or booleans);
    its GPU record holds the chosen one's position in ``choices``."""
    if default not in choices:
        raise ValueError(f"default {default!r} is not one of {choices!r}")
    spec = MaterialParam(0.0, 0.0, len(choices) - 1, doc, omit_default=omit_default, integer=True, choices=choices)
    return field(default=default, metadata={PARAM_KEY: spec})


def material_params(kind: type) -> dict[str, MaterialParam]:
    """The declared parameters of material kind ``kind`` (a dataclass), in declaration order."""
    return {f.name: f.metadata[PARAM_KEY] for f in fields(kind) if PARAM_KEY in f.metadata}


@dataclass(frozen=True)
class Slot:
    """Where a parameter sits in its kind's GPU record: texel ``texel``, components
    ``offset`` … ``offset + size - 1``."""

    texel: int
    offset: int
    size: int

    @property
    def swizzle(self) -> str:
        return COMPONENTS[self.offset : self.offset + self.size]


def record_layout(kind: type) -> dict[str, Slot]:
    """The GPU record of material kind ``kind``: each ``record`` parameter in declaration order,
    packed into texels of four floats; a parameter that does not fit in what is left of a texel
    starts the next one."""
    layout: dict[str, Slot] = {}
    texel, used = 0, 0
    for name, p in material_params(kind).items():
        if not p.record:
            continue
        if used + p.size > TEXEL_FLOATS:
            texel, used = texel + 1, 0
        layout[name] = Slot(texel, used, p.size)
        used += p.size
    return layout


def record_texels(kind: type) -> int:
    """Texels per material of kind ``kind`` (at least one)."""
    return max((s.texel for s in record_layout(kind).values()), default=0) + 1


def record_value(material: Any, name: str) -> float | tuple[float, ...]:
    """Parameter ``name`` of ``material`` as its record holds it: a choice's position, else the value."""
    value = getattr(material, name)
    choices = material_params(type(material))[name].choices
    return float(choices.index(value)) if choices else value


def pack_records(materials: Sequence[Any], kind: type) -> np.ndarray:
    """float32 (len(materials) × record_texels(kind), 4): the materials' records, one after another
    (unused components 0)."""
    texels = record_texels(kind)
    out = np.zeros((len(materials), texels, TEXEL_FLOATS), dtype=np.float32)
    for name, slot in record_layout(kind).items():
        values = np.array([record_value(m, name) for m in materials], dtype=np.float32).reshape(len(materials), -1)
        out[:, slot.texel, slot.offset : slot.offset + slot.size] = values
    return out.reshape(-1, TEXEL_FLOATS)


def glsl_accessors(kind: type, prefix: str = "material") -> str:
    """GLSL macros ``<prefix>_<name>(m)``: parameter <name> of material ``m``, read from its record
    through ``MATERIAL_TEXEL(m, k)`` (texel k of material m; the shader that uses them defines it
    for where it keeps the records: a texture or the uniform array). The Phong kind's prefix is
    ``material``, the PBR kind's ``pbr``."""
    return "".join(
        f"#define {prefix}_{name}(m) (MATERIAL_TEXEL(m, {slot.texel}).{slot.swizzle})\n"
        for name, slot in record_layout(kind).items()
    )


class MaterialKind:
    """What every material kind shares: its fields checked against their declarations on
    construction, and its JSON. A kind is a frozen dataclass deriving this class, with ``KIND``
    its JSON name."""

    KIND: ClassVar[str]

    def __post_init__(self) -> None:
        for name, p in material_params(type(self)).items():
            object.__setattr__(self, name, _checked(getattr(self, name), name, p))

    def to_json(self) -> dict:
        """The material's JSON: every parameter, less those declared ``omit_default`` that hold
        their default; ``"kind"`` for every kind but the Phong one."""
        out: dict[str, Any] = {} if self.KIND == "phong" else {"kind": self.KIND}
        for name, p in material_params(type(self)).items():
            value = getattr(self, name)
            if p.omit_default and value == (p.choices[0] if p.choices else p.default):
                continue
            out[name] = list(value) if isinstance(value, tuple) else value
        return out

    @classmethod
    def from_json(cls, d: Any, where: str) -> Any:
        keys = tuple(material_params(cls))
        d = json_object(d, where, {"kind", *keys})
        return construct(cls, {k: d[k] for k in keys if k in d}, where)


def _checked(value: Any, name: str, p: MaterialParam) -> Any:
    if p.choices:
        if isinstance(value, np.generic):
            value = value.item()
        for c in p.choices:
            if value == c and type(value) is type(c):
                return c
        raise SceneError(name, f"expected one of {', '.join(repr(c) for c in p.choices)}, got {value!r}")
    if p.size == 1:
        x = finite_number(value, name, lo=p.lo, hi=p.hi, lo_open=p.lo_open)
        if p.integer and not x.is_integer():
            raise SceneError(name, f"expected a whole number, got {x}")
        return int(x) if p.integer else x
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != p.size:
        raise SceneError(name, f"expected a list of {p.size} numbers")
    return tuple(finite_number(v, f"{name}[{i}]", lo=p.lo, hi=p.hi, lo_open=p.lo_open) for i, v in enumerate(value))
