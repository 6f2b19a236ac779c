"""Models from model files — OBJ, PLY, STL, glTF/GLB, and a zip of a model's folder — and the
functions a command line calls to make scenes of them.

:func:`load_model` parses a file (a path, or bytes held in memory: nothing is written) into a
:class:`~renderer.io.model.Model` — its parts, materials and textures — after the file's declared
numbers are checked (:mod:`renderer.io.model_guard`), then dispatches by format (:data:`READERS`):
glTF and GLB to :mod:`renderer.io.gltf_model` (materials, textures, node instances), OBJ to
:mod:`renderer.io.obj_model` (its MTL), PLY to :mod:`renderer.io.ply_model` (vertex colours and UVs),
STL through trimesh as one part of the scene's material. A model's side files — a glTF's
``.bin`` buffers and images, an OBJ's ``.mtl`` — come from its folder (a path), from the zip it
was sent in (``format="zip"``, :mod:`renderer.io.model_archive`), or not at all (a model file sent
alone: a reference to another file is refused, naming it). On the trimesh path polygons are split
into triangles by trimesh; degenerate triangles are kept (the scene counts them); vertices of
exactly equal position (and normal) are merged (:func:`renderer.geometry.meshes.weld`-like, but keeping
every triangle): STL stores each triangle's corners apart, and only shared vertices make a mesh
watertight for the tracer — exact equality keeps every coordinate as the file has it.

:func:`load_mesh` is the geometry alone (:class:`MeshData`: every part placed and joined), for
exporting and for the answer of ``POST /api/meshes`` (one mesh JSON).

The ``pocketray`` command line (``server/tools/cli.py``) calls :func:`model_scene` for ``render
model.glb`` and :func:`models_scene_json` for ``scene --mesh model.obj -o scene.json``: both keep
the models' materials and textures.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import limits
from ..geometry.scene import Camera, Light, Material, Mesh, Plane, Scene, SceneError, make_mesh
from ..materials.kinds import AnyMaterial
from ..materials.texture import Texture
from .model import Model, ModelPart
from .model_archive import MODEL_SUFFIXES, NO_SIDE_FILES, ModelFiles, SideFiles, folder_files, open_archive
from .model_guard import check_model

MODEL_FORMATS = ("obj", "ply", "stl", "glb", "gltf")
# What a model may be sent as: a model file, or a zip of its folder (one model file with its side files).
UPLOAD_FORMATS = (*MODEL_FORMATS, "zip")
_SUFFIX = {**MODEL_SUFFIXES, ".zip": "zip"}


@dataclass(frozen=True)
class MeshData:
    """A model's geometry as parsed: ``vertices`` float64 (V, 3) in the file's units,
    ``triangles`` int64 (T, 3), ``normals`` float64 (V, 3) or None (the file had none)."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    # the PNG and JPEG files beside the model (in its zip or folder), by name: for its materials
    images: tuple[str, ...] = ()

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def to_mesh(self, material: int = 0, transform: Any = None, smooth: bool | None = None) -> Mesh:
        """The scene's :class:`~renderer.geometry.scene.Mesh` (``transform`` applied); ``smooth``: None
        keeps the file's normals, False shades flat, True uses the file's normals or, when it
        has none, area-weighted ones."""
        normals = self.normals
        if smooth is False:
            normals = None
        elif smooth and normals is None:
            from ..geometry.meshes import vertex_normals

            normals = vertex_normals(self.vertices, self.triangles)
        return make_mesh(self.vertices, self.triangles, material, normals, transform)

    def to_json(self, material: int = 0, transform: Any = None, smooth: bool | None = None) -> dict:
        """The mesh JSON of docs/FORMATS.md (world space: the transform applied)."""
        return self.to_mesh(material, transform, smooth).to_json()


def file_type_of(source: str | Path | bytes, file_type: str | None) -> str:
    """The format to parse: ``file_type`` when given, else the path's suffix."""
    if file_type is not None:
        ft = str(file_type).lower().lstrip(".")
        if ft not in UPLOAD_FORMATS:
            raise SceneError("format", f"unknown model format {file_type!r}; one of {', '.join(UPLOAD_FORMATS)}")
        return ft
    if isinstance(source, (bytes, bytearray, memoryview)):
        raise SceneError("format", f"required for a model given as bytes: one of {', '.join(UPLOAD_FORMATS)}")
    suffix = Path(source).suffix.lower()
    if suffix not in _SUFFIX:
        raise SceneError(
            "format", f"cannot tell the format of {Path(source).name!r}; name one of {', '.join(UPLOAD_FORMATS)}"
        )
    return _SUFFIX[suffix]


def model_files(source: str | Path | bytes, file_type: str | None = None) -> ModelFiles:
    """The model file and its side files: a zip opened (its bounds checked before anything is
    inflated, :func:`renderer.io.model_archive.open_archive`), a path with its folder, bytes alone."""
    ft = file_type_of(source, file_type)
    if isinstance(source, (bytes, bytearray, memoryview)):
        return open_archive(bytes(source)) if ft == "zip" else ModelFiles("", ft, bytes(source))
    if ft == "zip":
        try:
            return open_archive(Path(source).read_bytes())
        except OSError as e:
            raise SceneError("file", f"cannot read {str(source)!r} ({e.strerror or e})") from None
    return folder_files(Path(source), ft)


class _Resolver:
    """trimesh's resolver over a model's side files: the only way its parser reaches another file."""

    def __init__(self, side: SideFiles | None):
        self.side = side

    def get(self, name: str) -> bytes:
        if self.side is None:
            raise SceneError("file", f"the model refers to the file {name!r}; send its folder as a zip (format=zip)")
        return self.side.get(name)

    __getitem__ = get

    def keys(self) -> list[str]:
        return []

    def __contains__(self, name: str) -> bool:
        return self.side is not None and self.side.size(name) is not None

    def namespaced(self, namespace: str) -> _Resolver:
        return self

    def write(self, name: str, data: Any) -> None:
        raise SceneError("file", "a model is read, never written")


def _file_normals(geom) -> np.ndarray | None:
    """The vertex normals trimesh read from the file, if any (it keeps them in its cache; a
    normal it would compute itself is not the file's)."""
    cache = getattr(getattr(geom, "_cache", None), "cache", {})
    n = cache.get("vertex_normals") if isinstance(cache, dict) else None
    if n is None or len(n) != len(geom.vertices):
        return None
    return np.asarray(n, dtype=np.float64)


def _parts(loaded) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """(vertices, faces, normals) of every triangle mesh in what trimesh loaded, each placed by
    its scene node's transform (normals by the inverse transpose)."""
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        return [(np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces, np.int64), _file_normals(loaded))]
    if not isinstance(loaded, trimesh.Scene):
        return []
    out = []
    for node in loaded.graph.nodes_geometry:
        matrix, name = loaded.graph[node]
        geom = loaded.geometry.get(name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue  # points, paths: nothing to trace
        m = np.asarray(matrix, np.float64)
        with np.errstate(invalid="ignore", over="ignore"):  # a non-finite vertex is refused below
            v = np.asarray(geom.vertices, np.float64) @ m[:3, :3].T + m[:3, 3]
        n = _file_normals(geom)
        f = np.asarray(geom.faces, np.int64)
        if n is not None:
            n = n @ np.linalg.inv(m[:3, :3])
        if np.linalg.det(m[:3, :3]) < 0:
            f = f[:, [0, 2, 1]]
        out.append((v, f, n))
    return out


def _merge_equal(v: np.ndarray, t: np.ndarray, n: np.ndarray | None):
    """Merge vertices of exactly equal position (and normal); every triangle is kept."""
    key = v + 0.0 if n is None else np.concatenate([v + 0.0, n + 0.0], axis=1)
    uniq, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    t = inverse.reshape(-1)[t]
    return v[first], t, (None if n is None else n[first])


def _trimesh_part(files: ModelFiles, side: SideFiles | None, max_triangles: int, max_vertices: int) -> ModelPart:
    """Every triangle mesh of the file through trimesh, merged into one part of the scene's
    material (−1): the formats whose materials are not read here."""
    ft, data = files.format, files.data
    import trimesh

    try:
        # materials are not read on this path; every other file the parser asks for comes through
        # the resolver (in memory, or the model's folder)
        loaded = trimesh.load(
            io.BytesIO(data), file_type=ft, resolver=cast(Any, _Resolver(side)), process=False, skip_materials=True
        )
        parts = _parts(loaded)
    except SceneError:
        raise
    except Exception as e:  # a parser's failure is the file's fault: say which
        raise SceneError("file", f"not a readable {ft.upper()} model ({type(e).__name__}: {e})") from None
    if not parts:
        raise SceneError("file", f"the {ft.upper()} file holds no triangle mesh")
    total = sum(len(f) for _, f, _ in parts)
    if total > max_triangles:
        raise SceneError("file", f"the model has {total:,} triangles; at most {max_triangles:,} allowed")
    v, t, n = _joined(parts)
    if len(v) > max_vertices:
        raise SceneError("file", f"the model has {len(v):,} distinct vertices; at most {max_vertices:,} per mesh")
    return ModelPart(v, t, n)


def _joined(parts: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray | None]]):
    """(vertices, triangles, normals) of ``parts`` as one mesh, equal vertices merged; normals
    only when every part has them."""
    with_normals = all(n is not None for _, _, n in parts)
    vs, ts, ns, base = [], [], [], 0
    for v, f, n in parts:
        vs.append(v)
        ts.append(np.asarray(f, np.int64) + base)
        ns.append(n)
        base += len(v)
    v = np.concatenate(vs)
    t = np.concatenate(ts)
    n = np.concatenate(cast(list[np.ndarray], ns)) if with_normals else None  # with_normals: none is None
    if not (np.isfinite(v).all() and (n is None or np.isfinite(n).all())):
        raise SceneError("file", "the model has vertices or normals that are not finite numbers")
    if len(t) and (t.min() < 0 or t.max() >= len(v)):
        raise SceneError("file", "the model has faces that index missing vertices")
    v, t, n = _merge_equal(v, t, n)
    if n is not None and not (np.abs(n).sum(axis=1) > 0).all():
        n = None  # a zero normal in the file: fall back to flat shading rather than refuse the model
    return v, t, n


# The readers of the formats whose materials are read: module and function, imported when a file
# of the format comes (each takes the ModelFiles, checked, and the bounds). Every other format is
# one part of the scene's material through trimesh.
READERS = {
    "gltf": ("renderer.io.gltf_model", "load_gltf_model"),
    "glb": ("renderer.io.gltf_model", "load_gltf_model"),
    "obj": ("renderer.io.obj_model", "load_obj_model"),
    "ply": ("renderer.io.ply_model", "load_ply_model"),
}


def load_model(
    source: str | Path | bytes | ModelFiles,
    file_type: str | None = None,
    *,
    max_triangles: int = limits.MAX_TRIANGLES,
    max_vertices: int = limits.MAX_MESH_VERTICES,
) -> Model:
    """Parse a model file (path, bytes or :class:`~renderer.io.model_archive.ModelFiles`;
    ``file_type`` one of :data:`UPLOAD_FORMATS`, from the suffix when None) into a
    :class:`~renderer.io.model.Model`: glTF and GLB with their materials and textures
    (:mod:`renderer.io.gltf_model`), OBJ with its MTL (:mod:`renderer.io.obj_model`), PLY with its
    vertex colours (:mod:`renderer.io.ply_model`), STL one part of the scene's material. SceneError
    ``format`` for an unknown format, ``file`` for a file that is not a model of that format, an
    archive that breaks a bound, a side file that is missing, a model that holds no triangle, or
    exceeds ``max_triangles`` (all parts, each instance counted) / ``max_vertices`` (one part).
    The file's declared counts, lengths, node tree and images are checked first
    (:func:`renderer.io.model_guard.check_model`), so a parser never allocates what the file only
    claims; parse in a worker process with a deadline when the file comes from someone else
    (``server/sessions/model_worker.py``)."""
    files = source if isinstance(source, ModelFiles) else model_files(source, file_type)
    side = None if files.side is NO_SIDE_FILES else files.side  # a model file alone: no side file to read
    # the file's own counts and lengths first: the parser would allocate whatever they ask for
    check_model(files.data, files.format, max_triangles=max_triangles, max_vertices=max_vertices, side=side)
    reader = _reader(files.format)
    if reader is not None:
        model: Model = reader(files, max_triangles=max_triangles, max_vertices=max_vertices)
        return model
    part = _trimesh_part(files, side, max_triangles, max_vertices)
    return Model((part,), images=tuple(side.image_names()) if side is not None else ())


def _reader(fmt: str) -> Any:
    """The reader of :data:`READERS` for ``fmt``, None for the trimesh path (a reader whose module
    is not installed falls back to it)."""
    import importlib

    if fmt not in READERS:
        return None
    module, name = READERS[fmt]
    try:
        return getattr(importlib.import_module(module), name)
    except ModuleNotFoundError as e:
        if e.name != module:
            raise
        return None


def load_mesh(
    source: str | Path | bytes | ModelFiles,
    file_type: str | None = None,
    *,
    max_triangles: int = limits.MAX_TRIANGLES,
    max_vertices: int = limits.MAX_MESH_VERTICES,
) -> MeshData:
    """The geometry alone of :func:`load_model`'s model: every part placed by its transform and
    joined into one mesh, equal vertices merged (what exporting a model and the checks of the
    parsers' bounds need; the service and the command line take the whole model)."""
    return model_geometry(load_model(source, file_type, max_triangles=max_triangles, max_vertices=max_vertices))


def model_geometry(model: Model) -> MeshData:
    """:class:`MeshData` of ``model``: its parts in the model's coordinates, joined."""
    parts = []
    for p in model.parts:
        v, t, n = p.vertices, np.asarray(p.triangles, np.int64), p.normals
        if p.transform is not None:
            a = p.transform[:3, :3]
            with np.errstate(over="ignore", invalid="ignore"):  # a non-finite vertex is refused by _joined
                v = p.placed_vertices()
                n = None if n is None else n @ np.linalg.inv(a)
            if np.linalg.det(a) < 0:
                t = t[:, [0, 2, 1]]
        parts.append((v, t, n))
    v, t, n = _joined(parts)
    return MeshData(v, t, n, model.images)


def export_mesh(mesh: Mesh | MeshData, file_type: str) -> bytes:
    """A mesh written in ``file_type`` (OBJ, PLY, STL, GLB; with its normals where the format
    keeps them) — for round trips and for handing scenes to other tools."""
    import trimesh

    ft = file_type_of(b"", file_type)
    if ft == "gltf":
        raise SceneError("format", "gltf is several files (JSON and buffers): export glb instead")
    tm = trimesh.Trimesh(
        np.asarray(mesh.vertices),
        np.asarray(mesh.triangles),
        vertex_normals=None if mesh.normals is None else np.asarray(mesh.normals),
        process=False,
    )
    options: dict[str, Any] = {"include_normals": mesh.normals is not None} if ft == "obj" else {}
    data = tm.export(file_type=ft, **options)
    return data.encode() if isinstance(data, str) else bytes(data)


def fit_transform(data: Model | MeshData, size: float = 30.0, floor: float | None = -20.0) -> list[list[float]]:
    """The 4 × 4 transform (row-major) that scales a model uniformly so that its longest side
    is ``size`` world units, centres it on the y axis and sets it on ``floor`` (its lowest
    point at y = floor; None: centred on the origin)."""
    lo, hi = data.bounds()
    extent = float((hi - lo).max())
    if not extent > 0:
        raise SceneError("file", "the model has no extent (all its vertices at one point)")
    s = float(size) / extent
    centre = (lo + hi) / 2.0
    ty = -centre[1] * s if floor is None else floor - lo[1] * s
    return [[s, 0.0, 0.0, -centre[0] * s], [0.0, s, 0.0, ty], [0.0, 0.0, s, -centre[2] * s], [0.0, 0.0, 0.0, 1.0]]


MODEL = Material(
    color=(0.92, 0.9, 0.85),
    ambient=0.15,
    diffuse=0.65,
    specular=0.4,
    shininess=60.0,
    reflective=0.1,
    transmissive=0.0,
    ior=1.0,
)
FLOOR = Material(
    color=(0.9, 0.3, 0.3),
    ambient=0.30,
    diffuse=0.30,
    specular=0.10,
    shininess=40.0,
    reflective=0.30,
    transmissive=0.0,
    ior=1.0,
)  # the thesis's red (Table 4.1)


def model_scene(
    source: str | Path | bytes,
    file_type: str | None = None,
    *,
    size: float = 30.0,
    smooth: bool | None = None,
    material: Material = MODEL,
) -> Scene:
    """A scene of one model: fitted (:func:`fit_transform`) into the thesis's cube, standing
    on its floor plane (y = −20), the thesis's camera and light — what ``pocketray render
    model.glb`` renders. The model's own materials and textures come with it; a part without
    one takes ``material``."""
    model = load_model(source, file_type)
    meshes, materials = model.placed(1, 2, 0, fit_transform(model, size), smooth, max_meshes=Scene.MAX_MESHES)
    return _stage(tuple(meshes), material, tuple(materials), model.textures)


def _stage(
    meshes: tuple[Mesh, ...],
    material: Material = MODEL,
    more: tuple[AnyMaterial, ...] = (),
    textures: tuple[Texture, ...] = (),
) -> Scene:
    """The thesis's camera, light and floor around ``meshes`` (the floor is material 0, ``material``
    1, the models' own ``more`` from 2 on, reading ``textures``)."""
    return Scene(
        Camera((0.0, 0.0, 100.0), (0.0, -5.0, 0.0), (0.0, 1.0, 0.0), 40.0),
        (Light((20.0, 40.0, 30.0), (1.0, 1.0, 1.0)),),
        (FLOOR, material, *more),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        (Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 0),),
        meshes,
        textures=textures,
    )


def models_scene_json(
    sources: Sequence[str | Path], *, size: float = 30.0, smooth: bool | None = None, as_is: bool = False
) -> dict:
    """The scene JSON (docs/FORMATS.md) of the model files ``sources``, in :func:`model_scene`'s
    stage: each part's vertices in its model's coordinates and a ``transform`` that fits the
    model — ``k`` models side by side along x, each scaled to ``size / k`` (so the row is at most
    ``size`` wide and the camera sees it), standing on the floor — with the models' materials and
    textures. ``as_is``: no transform (the file's coordinates are world units). Validated as the
    scene's meshes are."""
    if not sources:
        raise SceneError("mesh", "give at least one model file")
    k = len(sources)
    meshes: list[Mesh] = []
    docs: list[dict] = []
    more: list[AnyMaterial] = []
    textures: list[Texture] = []
    for i, src in enumerate(sources):
        model = load_model(src)
        transform = None
        if not as_is:
            transform = fit_transform(model, size / k)
            transform[0][3] += -size / 2.0 + (i + 0.5) * size / k
        base = 2 + len(more)
        flat, _ = model.placed(1, base, len(textures), None, smooth, max_meshes=Scene.MAX_MESHES)
        placed, materials = model.placed(1, base, len(textures), transform, smooth, max_meshes=Scene.MAX_MESHES)
        for mesh in flat:  # the model's coordinates, validated
            doc = mesh.to_json()
            if transform is not None:
                doc["transform"] = transform
            docs.append(doc)
        meshes.extend(placed)  # checks the placed meshes too
        more.extend(materials)
        textures.extend(model.textures)
    out = _stage(tuple(meshes), MODEL, tuple(more), tuple(textures)).to_json()
    out["meshes"] = docs
    return out


def mesh_json(
    source: str | Path | bytes,
    file_type: str | None = None,
    *,
    material: int = 0,
    transform: Any = None,
    smooth: bool | None = None,
) -> dict:
    """The mesh JSON (docs/FORMATS.md) of a model file's geometry, its parts joined (its materials
    are not kept: a mesh names one scene material)."""
    return load_mesh(source, file_type).to_json(material, transform, smooth)


def write_scene_json(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as scene JSON (compact, no NaN)."""
    Path(path).write_text(json.dumps(scene.to_json(), separators=(",", ":"), allow_nan=False))
