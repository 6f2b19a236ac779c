"""A model as its author made it: its parts (one mesh per glTF primitive per node, or per OBJ
material group), each with the material it names, its materials and the textures they read.

The readers of each format make one (``renderer/io/mesh_io.py`` dispatches: glTF and GLB to
``renderer/io/gltf_model.py``, OBJ with its MTL to ``renderer/io/obj_model.py``, every other format as
one part of the model's :data:`DEFAULT_MATERIAL`); :meth:`Model.placed` puts it into a scene,
appending its materials and textures to the scene's and renumbering what the parts name."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry.scene import Mesh, make_mesh
from ..materials.kinds import AnyMaterial
from ..materials.texture import Texture


@dataclass(frozen=True)
class ModelPart:
    """One mesh of a model: ``vertices`` float64 (V, 3), ``triangles`` int (T, 3), ``normals``
    float64 (V, 3) or None, ``attributes`` the :class:`~renderer.geometry.scene.Mesh` vertex attributes it
    has (``uvs``, ``uvs1``, ``colors``, ``tangents``), ``material`` an index into its model's
    ``materials`` (−1: the material the scene gives the model).

    ``transform``: the 4 × 4 row-major affine map from these arrays to the model's coordinates (a
    glTF node's world transform), None for the identity. ``mesh``: the file's mesh it comes from
    (a glTF mesh index; −1: the file has none), ``node``: the node that places it (−1: none). A
    mesh that several nodes use is read once: its parts share their arrays and differ in
    ``node`` and ``transform`` (what a two-level hierarchy instances)."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    attributes: dict[str, np.ndarray] = field(default_factory=dict)
    material: int = -1
    mesh: int = -1
    node: int = -1
    transform: np.ndarray | None = None

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
            from ..geometry.meshes import vertex_normals

            normals = vertex_normals(self.vertices, self.triangles)
        if self.transform is not None:
            transform = self.transform if transform is None else np.asarray(transform, np.float64) @ self.transform
        return make_mesh(self.vertices, self.triangles, material, normals, transform, **self.attributes)

    def placed_vertices(self) -> np.ndarray:
        """float64 (V, 3): its vertices in the model's coordinates (``transform`` applied)."""
        if self.transform is None:
            return self.vertices
        return self.vertices @ self.transform[:3, :3].T + self.transform[:3, 3]


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
        """Triangles of every part: a mesh on k nodes counts k times (the instanced triangles)."""
        return sum(p.n_triangles for p in self.parts)

    @property
    def n_unique_triangles(self) -> int:
        """Triangles of the distinct geometry: a mesh on k nodes counts once."""
        return sum({id(p.triangles): p.n_triangles for p in self.parts}.values())

    @property
    def texture_bytes(self) -> int:
        """Bytes of its textures' texels (level 0, RGBA8)."""
        return sum(t.nbytes for t in self.textures)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The box of its parts in the model's coordinates (each part's transform applied)."""
        placed = [p.placed_vertices() for p in self.parts]
        with np.errstate(over="ignore", invalid="ignore"):  # a non-finite bound is refused by the caller
            lo = np.min([v.min(axis=0) for v in placed], axis=0)
            hi = np.max([v.max(axis=0) for v in placed], axis=0)
        return lo, hi

    def placed(
        self,
        default_material: int,
        material_base: int,
        texture_base: int,
        transform: Any = None,
        smooth: bool | None = None,
        max_meshes: int | None = None,
    ) -> tuple[list[Mesh], list[AnyMaterial]]:
        """Its meshes and materials for a scene whose materials (textures) this model's follow from
        ``material_base`` (``texture_base``) on: a part naming no material takes scene material
        ``default_material``; each material's texture indices are moved by ``texture_base``. The
        scene appends the textures themselves (``self.textures``) at ``texture_base``.
        ``max_meshes``: when it has more parts, the parts of one material (and the same vertex
        attributes) become one mesh each — what a scene of few meshes can hold."""
        materials = [_moved_textures(m, texture_base) for m in self.materials]
        meshes = [
            p.to_mesh(default_material if p.material < 0 else material_base + p.material, transform, smooth)
            for p in self.parts
        ]
        if max_meshes is not None and len(meshes) > max_meshes:
            meshes = merged_meshes(meshes)
        return meshes, materials


def merged_meshes(meshes: Sequence[Mesh]) -> list[Mesh]:
    """``meshes`` of one material, shading (normals or not) and vertex attributes joined into one
    mesh each, in the order of their first one (the world-space geometry is unchanged)."""
    groups: dict[tuple, list[Mesh]] = {}
    for m in meshes:
        groups.setdefault((m.material, m.normals is not None, tuple(sorted(m.attributes))), []).append(m)
    out = []
    for (material, smooth, names), group in groups.items():
        if len(group) == 1:
            out.append(group[0])
            continue
        starts = np.cumsum([0] + [len(m.vertices) for m in group[:-1]])
        out.append(
            Mesh(
                np.concatenate([m.vertices for m in group]),
                np.concatenate([m.triangles + s for m, s in zip(group, starts, strict=True)]),
                material,
                np.concatenate([m.normals for m in group if m.normals is not None]) if smooth else None,
                **{n: np.concatenate([getattr(m, n) for m in group]) for n in names},
            )
        )
    return out


def _moved_textures(material: AnyMaterial, base: int) -> AnyMaterial:
    slots: Sequence[str] = getattr(material, "texture_slots", lambda: ())()
    if not base or not slots:
        return material
    import dataclasses

    names = [f"{s}_texture" for s in slots]
    moved = {n: getattr(material, n) + base for n in names if getattr(material, n) >= 0}
    return dataclasses.replace(material, **moved)
