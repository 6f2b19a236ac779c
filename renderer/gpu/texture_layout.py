"""Textures and vertex attributes as the GPU reads them (docs/FORMATS.md, "Textures").

A scene whose used PBR materials read textures or vertex attributes carries up to three data
formats (:mod:`renderer.frame.features`), each packed only where it is used, so every other scene packs
and compiles exactly what it did before them:

- ``TEXTURES``: the scene's textures in one ``sampler2DArray`` (``u_textures``), an atlas of square
  slots (:func:`layout_of`: a texture's longer side rounded up to a power of two; the layers the
  largest slot's size; the slots, largest first, in Morton order over the layers), texture ``k``'s
  mip level ``l`` at ``(x0 >> l, y0 >> l)`` of the array's level ``l``, never over another's. The
  texels are the file's RGBA8 bytes; an sRGB texture's mip levels are averaged in linear light and
  encoded again, and the shader decodes every texel it fetches *before* it filters
  (:func:`mip_chain`). Wrap and filter are the shader's, from the texture's record
  (``u_texture_info``, :data:`TEXTURE_RECORD`):
  four ``texelFetch`` es per level, wrapped in texel space, mixed bilinearly; two levels mixed by
  the fraction of the ray cone's level (``shaders/textures.glsl``). Beside them, per triangle,
  ``u_tri_uvs`` (:data:`TRI_UV_RECORD`): each corner's UV sets 0 and 1 and the triangle's level
  terms ½·log2(UV area / world area) of both sets (Akenine-Möller et al. 2021's Δ).
- ``VERTEX_COLORS``: ``u_tri_colors``, each corner's linear RGBA (white where a mesh has none).
- ``TANGENTS``: ``u_tri_tangents``, each corner's tangent and handedness (:func:`mesh_tangents`
  where a mesh with a normal map has none).

The array respects a device's ``MAX_TEXTURE_SIZE`` and ``MAX_ARRAY_TEXTURE_LAYERS`` and
:data:`renderer.limits.MAX_TEXTURE_ARRAY_TEXELS`: a texture beyond them is halved until it fits,
with a notice, never refused for the device's sake (:func:`pack_texture_array`).

GL-free: NumPy only.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from .. import limits
from ..geometry.scene import Mesh, Scene
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..materials.pbr import PbrMaterial
from ..materials.texture import FILTERS, WRAPS, Texture
from .gpu_layout import (
    TEXTURE_INFO,
    TEXTURES,
    TRI_COLORS,
    TRI_TANGENTS,
    TRI_UVS,
    PackedScene,
    PackedTextureArray,
    wrap_rows,
)
from .record_layout import Field, RecordLayout

WEBGL2_MAX_ARRAY_LAYERS = 256  # what WebGL2 guarantees of MAX_ARRAY_TEXTURE_LAYERS
assert limits.MAX_TEXTURES <= WEBGL2_MAX_ARRAY_LAYERS  # so no device refuses a scene for its layer count

TEXTURE_RECORD = RecordLayout(
    "texture",
    TEXTURE_INFO,
    1,
    (
        Field("width", 0, "x", "uint", "level 0's width in texels", bits=(15, 0)),
        Field("height", 0, "x", "uint", "level 0's height in texels", bits=(31, 16)),
        Field("x0", 0, "y", "uint", "its level 0's left column in its layer (level l: x0 >> l)", bits=(15, 0)),
        Field("y0", 0, "y", "uint", "its level 0's top row in its layer (level l: y0 >> l)", bits=(31, 16)),
        Field("levels", 0, "z", "uint", "its mip levels: level l is ⌈width / 2^l⌉ × ⌈height / 2^l⌉", bits=(7, 0)),
        Field("layer", 0, "z", "uint", "the layer of u_textures it is in", bits=(23, 8)),
        Field("wrap_s", 0, "w", "uint", "U outside [0, 1]: 0 repeat, 1 clamp, 2 mirror", bits=(1, 0)),
        Field("wrap_t", 0, "w", "uint", "V outside [0, 1], as wrap_s", bits=(3, 2)),
        Field("nearest", 0, "w", "uint", "1: the nearest texel of a level, 0: bilinear", bits=(4, 4)),
        Field("srgb", 0, "w", "uint", "1: RGB is sRGB-encoded, decoded per texel before filtering", bits=(5, 5)),
    ),
    "a scene texture (its index), where it lies in u_textures and how it is sampled",
)
TRI_UV_TEXELS = 4
TRI_UV_RECORD = RecordLayout(
    "tri_uv",
    TRI_UVS,
    TRI_UV_TEXELS,
    (
        Field("uv0_a", 0, "xy", "float", "corner 0's UV set 0"),
        Field("uv1_a", 0, "zw", "float", "corner 0's UV set 1"),
        Field("uv0_b", 1, "xy", "float", "corner 1's UV set 0"),
        Field("uv1_b", 1, "zw", "float", "corner 1's UV set 1"),
        Field("uv0_c", 2, "xy", "float", "corner 2's UV set 0"),
        Field("uv1_c", 2, "zw", "float", "corner 2's UV set 1"),
        Field("lod", 3, "xy", "float", "½·log2(UV area / world area) of sets 0 and 1 (−64: a degenerate map)"),
    ),
    "a triangle's texture coordinates (0 where its mesh has none)",
)
DEGENERATE_LOD = -64.0  # a triangle whose UVs (or corners) have no area: level 0, never a NaN

WRAP_CODES = {w: i for i, w in enumerate(WRAPS)}
assert WRAPS == ("repeat", "clamp", "mirror") and FILTERS == ("linear", "nearest")


# ---- which scenes carry what ---------------------------------------------------------------
def _pbr_meshes(scene: Scene) -> list[tuple[Mesh, PbrMaterial]]:
    out = []
    for m in scene.meshes:
        mat = scene.materials[m.material]
        if isinstance(mat, PbrMaterial):
            out.append((m, mat))
    return out


def uses_textures(scene: Scene) -> bool:
    """The TEXTURES data format: a mesh's PBR material reads a texture."""
    return any(mat.textures() for _, mat in _pbr_meshes(scene))


def uses_vertex_colors(scene: Scene) -> bool:
    """The VERTEX_COLORS data format: a mesh with a PBR material has vertex colours."""
    return any(m.colors is not None for m, _ in _pbr_meshes(scene))


def uses_tangents(scene: Scene) -> bool:
    """The TANGENTS data format: a mesh's PBR material has a normal map."""
    return any(mat.normal_texture >= 0 for _, mat in _pbr_meshes(scene))


# ---- vertex attributes ---------------------------------------------------------------------
def mesh_tangents(mesh: Mesh, uv_set: str = "uvs") -> np.ndarray:
    """float64 (V, 4): per-vertex tangents of ``mesh`` from its UV set's derivatives.

    MikkTSpace-like, simpler: each triangle's unit dP/du and dP/dv (from its corners and UVs),
    weighted by its area, are added to its three vertices; the sum's ``t`` is made orthogonal to the vertex
    normal (Gram–Schmidt) and unit; ``w`` = +1 where (n × t) points along −dP/dv, the image's up
    (V grows down the image in glTF, and a normal map's green is up), else −1. It differs from
    MikkTSpace in weighting by area rather than by angle and in not splitting vertices whose
    triangles disagree in handedness (a mirrored seam shares one tangent: the seam's normal map
    is wrong there). Vertices no triangle with UV area touches get any unit vector orthogonal to
    the normal. Without normals the area-weighted face normals stand in."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    tri = np.asarray(mesh.triangles, dtype=np.int64)
    uv_attr = getattr(mesh, uv_set)
    uv = np.zeros((len(v), 2)) if uv_attr is None else np.asarray(uv_attr, dtype=np.float64)
    p0, p1, p2 = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    w0, w1, w2 = uv[tri[:, 0]], uv[tri[:, 1]], uv[tri[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = w1 - w0, w2 - w0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = det != 0.0
    r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)[:, None]
    # dP/du and dP/dv, scaled to the triangle's area (|det| normalises the UV scale away).
    dpdu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    dpdv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r

    def unit_rows(a: np.ndarray) -> np.ndarray:
        n = np.linalg.norm(a, axis=1, keepdims=True)
        return np.where(n > 0, a / np.where(n > 0, n, 1.0), 0.0)

    tu = unit_rows(dpdu) * area
    tv = unit_rows(dpdv) * area
    t_sum = np.zeros_like(v)
    b_sum = np.zeros_like(v)
    for k in range(3):
        np.add.at(t_sum, tri[:, k], tu)
        np.add.at(b_sum, tri[:, k], tv)
    if mesh.normals is not None:
        n = unit_rows(np.asarray(mesh.normals, dtype=np.float64))
    else:
        face = np.cross(e1, e2)
        n = np.zeros_like(v)
        for k in range(3):
            np.add.at(n, tri[:, k], face)
        n = unit_rows(n)
    t = t_sum - n * np.sum(n * t_sum, axis=1, keepdims=True)
    t = unit_rows(t)
    # A vertex without a usable direction: any unit vector orthogonal to its normal.
    bad = np.linalg.norm(t, axis=1) == 0.0
    if bad.any():
        nb = n[bad]
        helper = np.where(np.abs(nb[:, 0:1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
        alt = unit_rows(helper - nb * np.sum(nb * helper, axis=1, keepdims=True))
        t[bad] = np.where(np.linalg.norm(alt, axis=1, keepdims=True) > 0, alt, np.array([[1.0, 0.0, 0.0]]))
    w = np.where(np.sum(np.cross(n, t) * -b_sum, axis=1) < 0.0, -1.0, 1.0)
    return np.concatenate([t, w[:, None]], axis=1)


def _per_corner(scene: Scene, name: str, width: int, missing: tuple[float, ...]) -> np.ndarray:
    """float64 (T, 3, width): attribute ``name`` at each triangle's corners, in id order;
    ``missing`` where a mesh has none."""
    parts = []
    for m in scene.meshes:
        a = getattr(m, name)
        if a is None:
            parts.append(np.broadcast_to(np.asarray(missing, dtype=np.float64), (m.n_triangles, 3, width)))
        else:
            parts.append(np.asarray(a, dtype=np.float64)[np.asarray(m.triangles, dtype=np.int64)])
    return np.concatenate(parts) if parts else np.zeros((0, 3, width))


def triangle_lod_terms(corners: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """float64 (T,): ½·log2(UV area / world area) of each triangle (the ray cones' Δ, without the
    texture's size), :data:`DEGENERATE_LOD` where either area is 0."""
    c = np.asarray(corners, dtype=np.float64)
    t = np.asarray(uvs, dtype=np.float64)
    world = np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    tex = np.abs(d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1])
    ok = (world > 0.0) & (tex > 0.0)
    with np.errstate(divide="ignore"):
        lod = 0.5 * np.log2(np.where(ok, tex, 1.0) / np.where(ok, world, 1.0))
    return np.where(ok, lod, DEGENERATE_LOD)


def tri_uv_records(scene: Scene) -> np.ndarray:
    """``u_tri_uvs``: uint32 (TRI_UV_TEXELS · T, 4)."""
    uv0 = _per_corner(scene, "uvs", 2, (0.0, 0.0))
    uv1 = _per_corner(scene, "uvs1", 2, (0.0, 0.0))
    corners = scene.triangle_corners
    lod = np.stack([triangle_lod_terms(corners, uv0), triangle_lod_terms(corners, uv1)], axis=1)
    cols = {"lod": lod}
    for k, name in enumerate("abc"):
        cols[f"uv0_{name}"] = uv0[:, k]
        cols[f"uv1_{name}"] = uv1[:, k]
    return TRI_UV_RECORD.pack(len(uv0), **cols)


def _corner_records(values: np.ndarray) -> np.ndarray:
    """(T, 3, 4) float64 → uint32 (3 T, 4) of float32 bits."""
    return np.ascontiguousarray(np.asarray(values, dtype=np.float32).reshape(-1, 4)).view(np.uint32)


def tri_color_records(scene: Scene) -> np.ndarray:
    """``u_tri_colors``: each corner's linear RGBA, white for meshes without colours."""
    return _corner_records(_per_corner(scene, "colors", 4, (1.0, 1.0, 1.0, 1.0)))


def scene_tangents(scene: Scene) -> list[np.ndarray | None]:
    """Each mesh's tangents: its own, generated (:func:`mesh_tangents`) where a PBR material with
    a normal map reads the mesh and it has none (from the UV set the normal map reads), else None."""
    out: list[np.ndarray | None] = []
    for m in scene.meshes:
        mat = scene.materials[m.material]
        if m.tangents is not None:
            out.append(np.asarray(m.tangents, dtype=np.float64))
        elif isinstance(mat, PbrMaterial) and mat.normal_texture >= 0:
            out.append(mesh_tangents(m, "uvs1" if mat.normal_texcoord == 1 else "uvs"))
        else:
            out.append(None)
    return out


def tri_tangent_records(scene: Scene) -> np.ndarray:
    """``u_tri_tangents``: each corner's tangent and handedness (0 where a mesh needs none)."""
    parts = []
    for m, t in zip(scene.meshes, scene_tangents(scene), strict=True):
        tri = np.asarray(m.triangles, dtype=np.int64)
        parts.append(np.zeros((m.n_triangles, 3, 4)) if t is None else t[tri])
    return _corner_records(np.concatenate(parts) if parts else np.zeros((0, 3, 4)))


# ---- textures ------------------------------------------------------------------------------
def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function's inverse (IEC 61966-2-1) on values in [0, 1]."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1.0 / 2.4) - 0.055)


def _to_linear(pixels: np.ndarray, srgb: bool) -> np.ndarray:
    x = np.asarray(pixels, dtype=np.float64) / 255.0
    if srgb:
        x[..., :3] = srgb_to_linear(x[..., :3])
    return x


def _to_bytes(x: np.ndarray, srgb: bool) -> np.ndarray:
    y = np.array(x, dtype=np.float64)
    if srgb:
        y[..., :3] = linear_to_srgb(y[..., :3])
    return np.clip(np.floor(y * 255.0 + 0.5), 0, 255).astype(np.uint8)


def _halve(x: np.ndarray) -> np.ndarray:
    """One mip step of linear values (H, W, 4): 2 × 2 boxes, ⌈H / 2⌉ × ⌈W / 2⌉; an odd side's last
    row or column is its own pair (repeated), a side of 1 stays 1."""
    h, w = x.shape[:2]
    if h > 1:
        if h % 2:
            x = np.concatenate([x, x[-1:]], axis=0)
        x = 0.5 * (x[0::2] + x[1::2])
    if w > 1:
        if w % 2:
            x = np.concatenate([x, x[:, -1:]], axis=1)
        x = 0.5 * (x[:, 0::2] + x[:, 1::2])
    return x


def levels_of(width: int, height: int) -> int:
    """Mip levels of a ``width × height`` texture halved (rounding up) to 1 × 1."""
    return max(int(width - 1).bit_length(), int(height - 1).bit_length()) + 1


def mip_chain(pixels: np.ndarray, srgb: bool) -> list[np.ndarray]:
    """uint8 (h, w, 4) levels 0 … :func:`levels_of` − 1 of a texture: each the 2 × 2 box average of
    the one above in linear light (an sRGB texture's colour decoded first and encoded again, its
    alpha linear), so a far view of the texture has its true mean, not a darkened one."""
    out = [np.asarray(pixels, dtype=np.uint8)]
    x = _to_linear(pixels, srgb)
    while x.shape[0] > 1 or x.shape[1] > 1:
        x = _halve(x)
        out.append(_to_bytes(x, srgb))
    return out


def shrink(texture: Texture) -> Texture:
    """``texture`` at half its size each side (⌈/ 2⌉), averaged in linear light."""
    from dataclasses import replace

    return replace(texture, pixels=mip_chain(texture.pixels, texture.srgb)[1])


def _pow2(n: int) -> int:
    return 1 << max(0, int(n) - 1).bit_length()


@dataclass
class TextureArray:
    """The scene's textures as one RGBA8 array with mip levels (``array``: level 0 ``size`` =
    (width, height), powers of two, level l ⌈size / 2^l⌉), their records, and ``notices``: what
    was resized for the device's or the array's limits."""

    array: PackedTextureArray
    records: np.ndarray
    notices: list[str] = field(default_factory=list)

    @property
    def nbytes(self) -> int:
        """GPU bytes of the array, every level (RGBA8)."""
        return self.array.nbytes


def slot_side(width: int, height: int) -> int:
    """The square a texture takes in its layer: its longer side rounded up to a power of two."""
    return _pow2(max(width, height))


def layout_of(sizes: list[tuple[int, int]]) -> tuple[int, list[tuple[int, int, int]]]:
    """The layers' side S (the largest slot) and each texture's (layer, x0, y0): the slots, largest
    first (then by index), laid one after another in Morton order over the layers, so that a slot
    of side s lies at multiples of s, its level l at (x0 >> l, y0 >> l) inside the array's level l,
    never over another's (a texture has no level past its slot's 1 × 1)."""
    if not sizes:
        return 1, []
    slots = [slot_side(w, h) for w, h in sizes]
    side = max(slots)
    order = sorted(range(len(sizes)), key=lambda i: (-slots[i], i))
    places: list[tuple[int, int, int]] = [(0, 0, 0)] * len(sizes)
    cursor = 0  # texels of the layers taken so far; a multiple of every later slot's area
    for i in order:
        s2 = slots[i] * slots[i]
        layer, within = divmod(cursor, side * side)
        m = within // s2
        x = y = 0
        for bit in range(16):  # Morton decode: even bits to x, odd to y
            x |= ((m >> (2 * bit)) & 1) << bit
            y |= ((m >> (2 * bit + 1)) & 1) << bit
        places[i] = (layer, x * slots[i], y * slots[i])
        cursor += s2
    return side, places


def array_layers(sizes: list[tuple[int, int]]) -> tuple[int, int]:
    """(side, layers) of the array of ``sizes``."""
    side, places = layout_of(sizes)
    return side, (max(p[0] for p in places) + 1 if places else 1)


def planned_sizes(
    sizes: list[tuple[int, int]],
    max_size: int = limits.MAX_TEXTURE_SIDE,
    max_texels: int = limits.MAX_TEXTURE_ARRAY_TEXELS,
) -> tuple[list[int], list[str]]:
    """How many times each texture of ``sizes`` (width, height) is halved (⌈/ 2⌉ a side) to go into the
    array, and why (empty: kept): until a side fits ``max_size`` (a device's MAX_TEXTURE_SIZE), then the
    largest until the layers' texels (:func:`layout_of`) fit ``max_texels``."""
    cur = list(sizes)
    halvings = [0] * len(cur)
    why = [""] * len(cur)

    def halve(i: int) -> None:
        w, h = cur[i]
        cur[i] = (-(-w // 2), -(-h // 2))
        halvings[i] += 1

    for i in range(len(cur)):
        while max(cur[i]) > max_size:
            halve(i)
            why[i] = f"the device's largest texture side, {max_size}"

    def texels() -> int:
        side, layers = array_layers(cur)
        return layers * side * side

    while cur and texels() > max_texels:
        big = max(w * h for w, h in cur)
        if big <= 1:
            break
        for i, (w, h) in enumerate(cur):
            if w * h == big:
                halve(i)
                why[i] = why[i] or f"the texture array's {max_texels:,} texels (MAX_TEXTURE_ARRAY_TEXELS)"
    return halvings, why


def fit_textures(
    textures: tuple[Texture, ...] | list[Texture],
    max_size: int = limits.MAX_TEXTURE_SIDE,
    max_texels: int = limits.MAX_TEXTURE_ARRAY_TEXELS,
) -> tuple[list[Texture], list[str]]:
    """The textures as the array can hold them (:func:`planned_sizes`), with a notice per texture resized."""
    halvings, why = planned_sizes([(t.width, t.height) for t in textures], max_size, max_texels)
    out = []
    for t, k in zip(textures, halvings, strict=True):
        for _ in range(k):
            t = shrink(t)
        out.append(t)
    notices = [
        f"textures[{i}] ({textures[i].name or 'unnamed'}) {textures[i].width} × {textures[i].height} "
        f"resized to {out[i].width} × {out[i].height} for {why[i]}"
        for i in range(len(out))
        if halvings[i]
    ]
    return out, notices


def array_bytes(
    textures: tuple[Texture, ...] | list[Texture],
    max_size: int = limits.MAX_TEXTURE_SIDE,
    max_texels: int = limits.MAX_TEXTURE_ARRAY_TEXELS,
) -> int:
    """GPU bytes of the array :func:`pack_texture_array` makes of ``textures`` (every mip level,
    the slots' unused texels included), from their sizes alone."""
    if not textures:
        return 0
    sizes = [(t.width, t.height) for t in textures]
    halvings, _ = planned_sizes(sizes, max_size, max_texels)
    fitted = [(-(-w // (1 << k)), -(-h // (1 << k))) for (w, h), k in zip(sizes, halvings, strict=True)]
    side, layers = array_layers(fitted)
    return texture_array_bytes(side, side, layers)


def texture_bytes(texture: Texture) -> int:
    """Bytes of ``texture`` at its own size with its mip levels (RGBA8)."""
    w, h = texture.width, texture.height
    total = 0
    for _ in range(levels_of(w, h)):
        total += 4 * w * h
        w, h = -(-w // 2), -(-h // 2)
    return total


def attribute_bytes(scene: Scene) -> int:
    """GPU bytes of the triangles' attribute records ``scene`` packs (:func:`pack_surface_data`)."""
    per = 0
    if uses_textures(scene):
        per += TRI_UV_RECORD.bytes
    if uses_vertex_colors(scene):
        per += 3 * 16
    if uses_tangents(scene):
        per += 3 * 16
    return per * scene.n_triangles


def pack_texture_array(
    textures: tuple[Texture, ...] | list[Texture],
    max_size: int = limits.MAX_TEXTURE_SIDE,
    max_layers: int = WEBGL2_MAX_ARRAY_LAYERS,
    max_texels: int = limits.MAX_TEXTURE_ARRAY_TEXELS,
) -> TextureArray:
    """The array ``u_textures`` and the records ``u_texture_info`` of ``textures`` for a device whose
    MAX_TEXTURE_SIZE is ``max_size`` and MAX_ARRAY_TEXTURE_LAYERS ``max_layers`` (the module's
    docstring). An empty list packs one 1 × 1 layer (an array cannot be empty)."""
    if len(textures) > max_layers:  # (MAX_TEXTURES ≤ WebGL2's 256: only a non-conforming device)
        raise ValueError(f"{len(textures)} textures exceed the device's {max_layers} array layers")
    fitted, notices = fit_textures(textures, max_size, max_texels)
    if not fitted:
        empty = np.zeros((1, 1, 1, 4), np.uint8)
        return TextureArray(PackedTextureArray(empty, "u1", [empty]), np.zeros((0, 4), np.uint32), [])
    side, places = layout_of([(t.width, t.height) for t in fitted])
    layers = max(p[0] for p in places) + 1
    if layers > max_layers:
        raise ValueError(f"{layers} texture layers exceed the device's {max_layers}")
    n_levels = levels_of(side, side)
    levels = [np.zeros((layers, max(1, side >> lv), max(1, side >> lv), 4), np.uint8) for lv in range(n_levels)]
    for t, (layer, x0, y0) in zip(fitted, places, strict=True):
        for lv, img in enumerate(mip_chain(t.pixels, t.srgb)):
            x, y = x0 >> lv, y0 >> lv
            levels[lv][layer, y : y + img.shape[0], x : x + img.shape[1]] = img
    n = len(fitted)
    records = TEXTURE_RECORD.pack(
        n,
        width=np.array([t.width for t in fitted]),
        height=np.array([t.height for t in fitted]),
        x0=np.array([p[1] for p in places]),
        y0=np.array([p[2] for p in places]),
        levels=np.array([levels_of(t.width, t.height) for t in fitted]),
        layer=np.array([p[0] for p in places]),
        wrap_s=np.array([WRAP_CODES[t.wrap_s] for t in fitted]),
        wrap_t=np.array([WRAP_CODES[t.wrap_t] for t in fitted]),
        nearest=np.array([int(t.filter == "nearest") for t in fitted]),
        srgb=np.array([int(t.srgb) for t in fitted]),
    )
    return TextureArray(PackedTextureArray(levels[0], "u1", levels), records, notices)


# The texture arrays in use (their mip chains take a while to make: made once per scene's textures and
# device size, not per frame), least recently used out; an entry holds its textures weakly and is
# valid while they are the very objects it was made from.
_ARRAYS: OrderedDict[tuple, tuple[list[weakref.ref], TextureArray]] = OrderedDict()
_ARRAYS_LOCK = threading.Lock()
CACHED_ARRAYS = 8


def texture_array(
    textures: tuple[Texture, ...], max_size: int = limits.MAX_TEXTURE_SIDE, max_layers: int = WEBGL2_MAX_ARRAY_LAYERS
) -> TextureArray:
    """:func:`pack_texture_array`, cached."""
    key = (tuple(id(t) for t in textures), max_size, max_layers)
    with _ARRAYS_LOCK:
        got = _ARRAYS.get(key)
        if got is not None and all(r() is t for r, t in zip(got[0], textures, strict=True)):
            _ARRAYS.move_to_end(key)
            return got[1]
    out = pack_texture_array(textures, max_size, max_layers)
    for level in out.array.levels:
        level.setflags(write=False)  # shared by every frame of these textures
    with _ARRAYS_LOCK:
        _ARRAYS[key] = ([weakref.ref(t) for t in textures], out)
        while len(_ARRAYS) > CACHED_ARRAYS:
            _ARRAYS.popitem(last=False)
    return out


@dataclass
class SurfaceData:
    """What :func:`pack_surface_data` packs: the record arrays (wrapped into rows) and the
    texture array, with its notices and the GPU bytes of each part."""

    packed: PackedScene
    array: TextureArray | None
    nbytes: dict[str, int]


def pack_surface_data(
    scene: Scene,
    max_width: int = DEFAULT_TEXTURE_WIDTH,
    max_layers: int = WEBGL2_MAX_ARRAY_LAYERS,
) -> SurfaceData:
    """The surface bindings of ``scene`` (:data:`renderer.gpu.gpu_layout.SURFACE_BINDINGS`) for a device
    whose MAX_TEXTURE_SIZE is ``max_width``: nothing for a scene that uses none of them."""
    textures: dict = {}
    nbytes: dict[str, int] = {}
    array = None
    if uses_textures(scene):
        array = texture_array(scene.textures, max_width, max_layers)
        textures[TEXTURES.name] = array.array
        textures[TEXTURE_INFO.name] = wrap_rows(array.records, max_width)
        textures[TRI_UVS.name] = wrap_rows(tri_uv_records(scene), max_width)
    if uses_vertex_colors(scene):
        textures[TRI_COLORS.name] = wrap_rows(tri_color_records(scene), max_width)
    if uses_tangents(scene):
        textures[TRI_TANGENTS.name] = wrap_rows(tri_tangent_records(scene), max_width)
    for name, t in textures.items():
        nbytes[name] = t.nbytes if isinstance(t, PackedTextureArray) else int(t.data.nbytes)
    return SurfaceData(PackedScene(textures, {}), array, nbytes)


def texture_glsl_constants() -> str:
    """The accessors of the texture and UV records (emitted into variants with TEXTURES only)."""
    return f"#define TRI_UV_TEXELS {TRI_UV_TEXELS}\n" + TEXTURE_RECORD.glsl_accessors() + TRI_UV_RECORD.glsl_accessors()


def texture_array_bytes(width: int, height: int, layers: int) -> int:
    """GPU bytes of a ``width × height × layers`` RGBA8 array with every mip level."""
    return sum(4 * layers * max(1, width >> lv) * max(1, height >> lv) for lv in range(levels_of(width, height)))


def level_for(cone_width: float, lod_term: float, width: int, height: int) -> float:
    """The ray cones' mip level (Akenine-Möller et al. 2021, eq. 34 with the cosine folded into the
    footprint): log2(cone_width) + Δ + ½·log2(width · height), ``cone_width`` the footprint (the
    cone's width at the hit over |cos| of its incidence), ``lod_term`` the triangle's Δ."""
    if cone_width <= 0.0:
        return 0.0
    return math.log2(cone_width) + lod_term + 0.5 * math.log2(width * height)


def formats_markdown() -> str:
    """The block of docs/FORMATS.md between ``<!-- texture-records`` and ``<!-- /texture-records -->``."""
    return "\n".join(r.markdown() for r in (TEXTURE_RECORD, TRI_UV_RECORD)).strip()
