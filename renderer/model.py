"""A model as its author made it: its parts (one mesh per glTF primitive per node, or per OBJ
material group), each with the material it names, its materials and the textures they read.

The readers of each format make one (``renderer/mesh_io.py`` dispatches: glTF and GLB to
``renderer/gltf_model.py``, OBJ with its MTL to ``renderer/obj_model.py``, every other format as
one part of the model's :data:`DEFAULT_MATERIAL`); :meth:`Model.placed` puts it into a scene,
appending its materials and textures to the scene's and renumbering what the parts name."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .materials.kinds import AnyMaterial
from .materials.texture import Texture
from .scene import Mesh, make_mesh


@dataclass(frozen=True)
class ModelPart:
    """One mesh of a model in the file's coordinates: ``vertices`` float64 (V, 3), ``triangles``
    int (T, 3), ``normals`` float64 (V, 3) or None, ``attributes`` the :class:`~renderer.scene.Mesh`
    vertex attributes it has (``uvs``, ``uvs1``, ``colors``, ``tangents``), ``material`` an index
    into its model's ``materials`` (−1: the material the scene gives the model)."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    attributes: dict[str, np.ndarray] = field(default_factory=dict)
    material: int = -1

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def to_mesh(self, material: int, transform: Any = None, smooth: bool | None = None) -> Mesh:
        """The scene's mesh of this part with scene material ``material`` (``transform`` applied);
        ``smooth``: None keeps the file's normals, False shades flat, True uses the file's normals
        or, when it has none, area-weighted ones."""
        normals = self.normals
        if smooth is False:
            normals = None
        elif smooth and normals is None:
            from .meshes import vertex_normals

            normals = vertex_normals(self.vertices, self.triangles)
        return make_mesh(self.vertices, self.triangles, material, normals, transform, **self.attributes)


@dataclass(frozen=True)
class Model:
    """A parsed model file: ``parts``, the ``materials`` they name and the ``textures`` those read
    (indices into ``textures``), ``images`` the names of the PNG and JPEG files beside it,
    ``notices`` what of the file was not read (a sentence each: skipped points and lines, a
    reduced image)."""

    parts: tuple[ModelPart, ...]
    materials: tuple[AnyMaterial, ...] = ()
    textures: tuple[Texture, ...] = ()
    images: tuple[str, ...] = ()
    notices: tuple[str, ...] = ()

    @property
    def n_triangles(self) -> int:
        return sum(p.n_triangles for p in self.parts)

    @property
    def texture_bytes(self) -> int:
        """Bytes of its textures' texels (level 0, RGBA8)."""
        return sum(t.nbytes for t in self.textures)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.min([p.vertices.min(axis=0) for p in self.parts], axis=0)
        hi = np.max([p.vertices.max(axis=0) for p in self.parts], axis=0)
        return lo, hi

    def placed(
        self,
        default_material: int,
        material_base: int,
        texture_base: int,
        transform: Any = None,
        smooth: bool | None = None,
    ) -> tuple[list[Mesh], list[AnyMaterial]]:
        """Its meshes and materials for a scene whose materials (textures) this model's follow from
        ``material_base`` (``texture_base``) on: a part naming no material takes scene material
        ``default_material``; each material's texture indices are moved by ``texture_base``. The
        scene appends the textures themselves (``self.textures``) at ``texture_base``."""
        materials = [_moved_textures(m, texture_base) for m in self.materials]
        meshes = [
            p.to_mesh(default_material if p.material < 0 else material_base + p.material, transform, smooth)
            for p in self.parts
        ]
        return meshes, materials


def _moved_textures(material: AnyMaterial, base: int) -> AnyMaterial:
    slots: Sequence[str] = getattr(material, "texture_slots", lambda: ())()
    if not base or not slots:
        return material
    import dataclasses

    names = [f"{s}_texture" for s in slots]
    moved = {n: getattr(material, n) + base for n in names if getattr(material, n) >= 0}
    return dataclasses.replace(material, **moved)
