"""PLY files as a :class:`~renderer.io.model.Model`: one part with the file's vertex colours and
texture coordinates.

The file's own numbers are checked first (:func:`renderer.io.model_guard.check_model`); the body is
read by trimesh's PLY reader (its lenient header: a line without a keyword, as Blender 2.4 wrote
``Created by Blender3D …``, is a comment), whose raw vertex element this module reads for what
trimesh keeps apart or drops:

- ``red green blue`` (and ``alpha``), or ``diffuse_red diffuse_green diffuse_blue``, of any
  integer type (divided by the type's largest value: 255 for ``uchar``) or float (clamped to
  [0, 1]) → ``colors``. They are taken as sRGB-encoded, as the tools that paint them show them
  (MeshLab, Blender's vertex paint; the PLYLoader of three, threejs.org, reads them so), and
  decoded to the linear RGBA that :class:`~renderer.geometry.scene.Mesh` keeps; alpha stays as it is.
- ``s t``, ``u v`` or ``texture_u texture_v`` → ``uvs``, V flipped (PLY's ``t``, like OBJ's, is 0
  at the image's bottom; the scene's V is glTF's, 0 at the top).

Not read: per-face colours and per-face texture coordinates (``texcoord`` lists: a vertex would
have to be split per corner), the ``TextureFile`` comment (a PLY names no material: the part takes
the scene's, −1).
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from ..geometry.scene import SceneError
from .model import Model, ModelPart
from .model_archive import NO_SIDE_FILES, ModelFiles
from .model_guard import check_model

_COLOR_NAMES = (("red", "green", "blue", "alpha"), ("diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"))
_UV_NAMES = (("texture_u", "texture_v"), ("u", "v"), ("s", "t"))


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1's decoding of sRGB values in [0, 1] to linear ones."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, np.power((np.maximum(c, 0.04045) + 0.055) / 1.055, 2.4))


def unit_channel(values: np.ndarray) -> np.ndarray:
    """A colour channel as stored (an integer type scaled to its largest value, floats as they
    are) in [0, 1], float64."""
    a = np.asarray(values)
    if a.dtype.kind in "ui":
        top = float(np.iinfo(a.dtype).max)
        return np.clip(a.astype(np.float64) / top, 0.0, 1.0)
    out = np.nan_to_num(a.astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    return np.clip(out, 0.0, 1.0)


def _column(data: Any, name: str) -> np.ndarray | None:
    """The vertex property ``name`` from trimesh's raw element (a dict or a structured array)."""
    try:
        if isinstance(data, dict):
            a = np.asarray(data[name]) if name in data else None
        else:
            names = getattr(getattr(data, "dtype", None), "names", None) or ()
            a = np.asarray(data[name]) if name in names else None
    except (KeyError, ValueError, IndexError):
        return None
    if a is not None and a.ndim == 2 and a.shape[1] == 1:  # trimesh keeps a scalar property as a column
        a = a[:, 0]
    return a


def vertex_colors(data: Any, n: int) -> np.ndarray | None:
    """Linear RGBA float64 (n, 4) from a PLY vertex element's colour properties, None without."""
    for names in _COLOR_NAMES:
        cols = [_column(data, k) for k in names]
        if any(c is None or len(c) != n or c.ndim != 1 for c in cols[:3]):
            continue
        rgb = srgb_to_linear(np.column_stack([unit_channel(c) for c in cols[:3] if c is not None]))
        a = cols[3]
        alpha = unit_channel(a) if a is not None and len(a) == n and a.ndim == 1 else np.ones(n)
        return np.column_stack([rgb, alpha])
    return None


def vertex_uvs(data: Any, n: int) -> np.ndarray | None:
    """float64 (n, 2) texture coordinates, V flipped to the scene's convention; None without."""
    for u_name, v_name in _UV_NAMES:
        u, v = _column(data, u_name), _column(data, v_name)
        if u is None or v is None or len(u) != n or len(v) != n or u.ndim != 1 or v.ndim != 1:
            continue
        uv = np.column_stack([u.astype(np.float64), 1.0 - v.astype(np.float64)])
        if not np.isfinite(uv).all():
            raise SceneError("file", "PLY: texture coordinates that are not finite numbers")
        return uv
    return None


def load_ply_model(files: ModelFiles, *, max_triangles: int, max_vertices: int) -> Model:
    """A PLY file as one part (material −1) with its vertex normals, colours and texture
    coordinates. SceneError ``file`` for a file whose header disagrees with its bytes or breaks
    ``max_triangles`` / ``max_vertices``, one without faces, or one with non-finite vertices."""
    data = files.data
    side = None if files.side is NO_SIDE_FILES else files.side
    check_model(data, "ply", max_triangles=max_triangles, max_vertices=max_vertices, side=side)
    from trimesh.exchange.ply import load_ply

    try:
        kw = load_ply(io.BytesIO(data), skip_materials=True, fix_texture=False)
    except SceneError:
        raise
    except Exception as e:  # the parser's failure is the file's fault: say which
        raise SceneError("file", f"not a readable PLY model ({type(e).__name__}: {e})") from None
    faces = kw.get("faces")
    vertices = kw.get("vertices")
    if vertices is None or faces is None or len(faces) == 0:
        raise SceneError("file", "the PLY file holds no triangle mesh (no faces)")
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(faces, dtype=np.int64)
    if t.ndim != 2 or t.shape[1] < 3:
        raise SceneError("file", "PLY: faces must have 3 or more corners")
    if t.shape[1] > 3:  # polygons of k corners, fanned from their first
        k = t.shape[1]
        t = np.concatenate([t[:, [0, j, j + 1]] for j in range(1, k - 1)], axis=0)
    if len(t) > max_triangles:
        raise SceneError("file", f"the model has {len(t):,} triangles; at most {max_triangles:,} allowed")
    if len(v) > max_vertices:
        raise SceneError("file", f"the model has {len(v):,} vertices; at most {max_vertices:,} per mesh")
    if not np.isfinite(v).all():
        raise SceneError("file", "the model has vertices that are not finite numbers")
    if t.min() < 0 or t.max() >= len(v):
        raise SceneError("file", f"PLY: faces index vertices outside 0 … {len(v) - 1}")
    normals = kw.get("vertex_normals")
    n = None
    if normals is not None:
        n = np.asarray(normals, dtype=np.float64)
        if n.shape != v.shape or not np.isfinite(n).all() or not (np.abs(n).sum(axis=1) > 0).all():
            n = None  # a zero or broken normal in the file: shaded flat rather than refused
    raw = kw.get("metadata", {}).get("_ply_raw", {}).get("vertex", {}).get("data")
    attributes: dict[str, np.ndarray] = {}
    colors = vertex_colors(raw, len(v)) if raw is not None else None
    if colors is not None:
        attributes["colors"] = colors
    uvs = vertex_uvs(raw, len(v)) if raw is not None else None
    if uvs is not None:
        attributes["uvs"] = uvs
    part = ModelPart(v, t, n, attributes, -1)
    images = tuple(side.image_names()) if side is not None else ()
    return Model((part,), images=images)
