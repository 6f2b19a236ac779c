"""The registry of material kinds: each kind by its JSON name, and the scene JSON's reading of a
material by its ``"kind"`` (the Phong kind when absent)."""

from __future__ import annotations

from typing import Any

from ..errors import SceneError
from .pbr import PbrMaterial
from .phong import Material

AnyMaterial = Material | PbrMaterial
KINDS: dict[str, type[Material] | type[PbrMaterial]] = {k.KIND: k for k in (Material, PbrMaterial)}


def material_from_json(d: Any, where: str) -> AnyMaterial:
    """The material of JSON object ``d``, of the kind its ``"kind"`` names (default ``"phong"``)."""
    kind = d.get("kind", Material.KIND) if isinstance(d, dict) else Material.KIND
    if kind not in KINDS:
        raise SceneError(f"{where}.kind", f"expected one of {', '.join(KINDS)}, got {kind!r}")
    material: AnyMaterial = KINDS[kind].from_json(d, where)
    return material
