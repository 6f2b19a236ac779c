"""Wavefront OBJ files with their MTL material libraries as a :class:`~renderer.io.model.Model`.

**Geometry.** ``v x y z`` (``v x y z w``: w, a curve's weight, ignored; ``v x y z r g b``: the
common vertex-colour extension), ``vt u [v [w]]``, ``vn x y z``, and faces ``f`` whose corners
are ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``, counted from 1 or, negative, back from the last
element defined before the face. A polygon is fanned from its first corner (a concave one is
split wrongly, as trimesh and three (threejs.org) split it). A vertex of the model is a distinct
(v, vt, vn) triple: corners that share all three share the vertex. ``vt``'s V is flipped to the
scene's convention (glTF's: V = 0 at the image's top; OBJ's v = 0 is its bottom). Vertex
colours are taken as sRGB-encoded (as the tools that write them display them; the OBJLoader of
three, threejs.org, reads them so) and decoded to linear RGBA. ``usemtl`` groups the faces: one
part per material used, in the order of first use; faces before any ``usemtl``, or naming a
material no library defines, take the scene's material (−1). ``o`` and ``g`` do not split the
model; ``s``, ``l``, ``p`` and free-form geometry are not read. A line ending in ``\\``
continues on the next.

An OBJ declares nothing it does not hold, so this reader needs no check before it reads (the
dispatcher, ``load_model`` of renderer/io/mesh_io.py, runs :func:`renderer.io.model_guard.check_model`
first all the same): what it allocates follows the text. It bounds the ``v`` lines
(``DECLARED_VERTEX_FACTOR × max_vertices``), the triangles (``max_triangles``, all parts, before
any is made) and each part's vertices (``max_vertices``), and refuses a malformed line with
``SceneError("file", "OBJ: line N: …")`` naming what is wrong.

**Materials** (``mtllib``: several files on one line, names with spaces; all together at most
``MAX_MTL_BYTES``) become :class:`~renderer.materials.pbr.PbrMaterial` s; only the materials the
faces use are read. The mapping (docs/FORMATS.md has it as a table):

- ``Kd`` → base colour, ``map_Kd`` → base colour texture (sRGB; Kd multiplies it, as the MTL
  specification and three's loader do). Colours are sRGB-encoded (three's loader reads them
  so), decoded to linear; a channel above 1 is linear already. No ``Kd``: 0.8 grey, or 1 under
  a ``map_Kd``.
- ``Ns`` → roughness: a Phong (Blinn–Phong) exponent n has the Beckmann width
  α = √(2 / (n + 2)) (Walter et al. 2007), GGX's α at small widths; the material's roughness is
  perceptual (α = roughness²), so roughness = (2 / (Ns + 2))^¼: Ns 0 → 1, 10 → 0.64, 100 → 0.38,
  1000 → 0.21. ``Ks`` does not colour anything (a dielectric's highlight is white): a black
  ``Ks`` (no highlight) makes it roughness 1. ``Pr`` / ``map_Pr`` (MTL's PBR extension) override.
- Metallic 0: most exporters write ``Ks`` for a plastic's highlight, not a metal's colour; only
  ``Pm`` / ``map_Pm`` make a conductor (``map_Pr`` and ``map_Pm`` are combined on the CPU into
  one metallic-roughness texture: green roughness, blue metallic).
- ``d`` → alpha (``Tr`` = 1 − d where no ``d``; a lone ``Tr 1``, an invisible surface, is the
  inverted d some exporters write, and read as opaque); alpha < 1 blends. ``map_d`` becomes the
  alpha channel of the base colour texture (combined on the CPU; white where no ``map_Kd``);
  its image's alpha where it has one, else its luminance.
- ``illum`` 4, 6, 7 or 9 (glass: "refraction on") with alpha < 1: transmission = 1 − alpha, the
  surface opaque (glass refracts, it does not let light pass beside it). Other values not read.
- ``Ni`` → ior, where > 1 (at most ``MAX_IOR``); 0 and 1, which exporters write for "unset"
  and which would leave a dielectric without any reflection, give glTF's 1.5.
- ``Ke`` → emissive (above 1: the largest channel becomes ``emissive_strength``), ``map_Ke`` →
  emissive texture (sRGB; ``Ke`` 1 under it when absent).
- ``norm`` → normal texture (``-bm`` its scale); ``bump`` / ``map_Bump``: a height map, made a
  tangent-space normal map on the CPU (:func:`height_to_normal`: the white of the map lies
  ``-bm`` × :data:`BUMP_DEPTH` of the texture's side above its black).
- Every OBJ material is double-sided (the format has no culling flag, and its windings are often
  mixed).
- Texture options: ``-s`` and ``-o`` → the slot's UV transform, ``-clamp on`` → clamped wrap,
  ``-bm`` → the bump or normal scale; ``-blendu -blendv -boost -mm -t -texres -cc -imfchan
  -type`` are skipped.
- Not read: ``Ka`` (no ambient term in a path), ``Ks``'s colour, ``Tf``, ``sharpness``,
  ``map_Ka``, ``map_Ks``, ``map_Ns``, ``disp``, ``decal``, ``refl``, ``Pc``/``Pcr``/``Ps``
  (clearcoat, sheen: the material has none), ``aniso``/``anisor``, spectral and CIE XYZ colours.

**Textures** are PNG or JPEG side files (the name as exporters write it: ``textures\\wood.png``,
spaces, another case, an absolute path of the author's machine by its file name; beside their
library first when it lies in another folder, then beside the model), their declared
size checked before decoding (:func:`renderer.io.model_guard.check_image`), scaled down to
``MAX_TEXTURE_SIDE`` when larger. A reference outside the model's folder is refused (422). A
texture that is missing or cannot be decoded, an MTL file not beside the model, a ``usemtl``
without a definition: the model is read without it, and :attr:`Model.notices` says what was left
out — a user gets a model that looks almost right and a line saying why, rather than nothing.
"""

from __future__ import annotations

import posixpath
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from io import BytesIO

import numpy as np

from .. import limits
from ..geometry.scene import SceneError
from ..materials.pbr import PbrMaterial
from ..materials.texture import Texture
from .model import Model, ModelPart
from .model_archive import IMAGE_MAGIC, NO_SIDE_FILES, ModelFiles, SideFiles
from .model_guard import check_image
from .ply_model import srgb_to_linear

# The depth of a bump map's white above its black, per unit of -bm, as a share of the texture's
# side: the normals' tilt then does not depend on the map's resolution (1/64: a step from black
# to white over 4 texels of a 512-texel map tilts the normal by 63°).
BUMP_DEPTH = 1.0 / 64.0
GLASS_ILLUM = (4, 6, 7, 9)
DEFAULT_KD = 0.8
DEFAULT_IOR = 1.5  # glTF's
# Texture options: how many arguments each takes (-s, -o, -t take one to three numbers).
_OPTION_ARGS = {
    "-blendu": 1,
    "-blendv": 1,
    "-boost": 1,
    "-mm": 2,
    "-texres": 1,
    "-clamp": 1,
    "-bm": 1,
    "-imfchan": 1,
    "-type": 1,
    "-cc": 1,
    "-s": 3,
    "-o": 3,
    "-t": 3,
}
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def _refuse(message: str) -> SceneError:
    return SceneError("file", f"OBJ: {message}")


def _text(data: bytes) -> bytes:
    """The file as UTF-8 (or ASCII) bytes: a UTF-16 file (by its byte-order mark) transcoded, a
    UTF-8 byte-order mark dropped."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError as e:
            raise _refuse(f"a UTF-16 file that does not decode ({e})") from None
    return data[3:] if data.startswith(b"\xef\xbb\xbf") else data


def _name(raw: bytes) -> str:
    """A name (material, file) as written: UTF-8, else Latin-1 (old Windows exporters)."""
    try:
        return raw.decode("utf-8").strip()
    except UnicodeDecodeError:
        return raw.decode("latin-1").strip()


def _lines(data: bytes) -> tuple[list[bytes], list[int] | None]:
    """The file's lines (LF, CR LF or CR), and their numbers when a continuation (a line ending
    in a backslash) joined some (None: line i is number i + 1)."""
    lines = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")
    if not re.search(rb"\\[ \t]*[\r\n]", data):
        return lines, None
    out: list[bytes] = []
    numbers: list[int] = []
    pending: list[bytes] = []
    for i, line in enumerate(lines, 1):
        if not pending:
            numbers.append(i)
        if line.rstrip().endswith(b"\\"):
            pending.append(line.rstrip()[:-1])
            continue
        out.append(b" ".join([*pending, line]))
        pending = []
    if pending:
        out.append(b" ".join(pending))
    return out, numbers


def _parsed(text: bytes, count: int, dtype: type) -> np.ndarray | None:
    """``count`` numbers of ``dtype`` from whitespace-separated text in C; None when the text holds
    anything else (the caller then finds the line)."""
    if count == 0:
        return np.zeros(0, dtype)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            out: np.ndarray = np.fromstring(text, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return out if len(out) == count else None


def _bad_number(rows: list[bytes], numbers: list[int], key: str, allowed: Sequence[int], what: str) -> SceneError:
    """The refusal naming the first row of ``key`` lines that is not ``allowed`` numbers."""
    for row, no in zip(rows, numbers, strict=True):
        words = row.split()
        for w in words:
            try:
                float(w)
            except ValueError:
                return _refuse(f"line {no}: '{key} {_name(row)[:60]}': {_name(w)[:20]!r} is not a number")
        if len(words) not in allowed:
            return _refuse(f"line {no}: '{key} {_name(row)[:60]}': {what} (got {len(words)} numbers)")
    return _refuse(f"the '{key}' lines could not be read")


def _tokens(joined: bytes, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Of rows joined by newlines: the words in each row, and where each word starts (words:
    runs of bytes other than ASCII whitespace, as ``bytes.split`` cuts them), counted on arrays."""
    a = np.frombuffer(joined, np.uint8)
    ws = (a == 32) | ((a >= 9) & (a <= 13))
    begins = ~ws
    begins[1:] &= ws[:-1]
    starts = np.flatnonzero(begins)
    row = np.searchsorted(np.flatnonzero(a == 10), starts)
    return np.bincount(row, minlength=n_rows).astype(np.int64), starts


def _rows(
    rows: list[bytes], numbers: list[int], key: str, allowed: Sequence[int], what: str
) -> tuple[np.ndarray, np.ndarray]:
    """float64 numbers of ``key`` lines, flat, and each row's count (each in ``allowed``)."""
    joined = b"\n".join(rows)
    counts, _ = _tokens(joined, len(rows))
    values = _parsed(joined, int(counts.sum()), np.float64)
    if values is None or not np.isin(counts, allowed).all():
        raise _bad_number(rows, numbers, key, allowed, what)
    return values, counts


def _columns(values: np.ndarray, counts: np.ndarray, first: int, width: int) -> np.ndarray:
    """Numbers ``first`` … ``first + width − 1`` of each row (rows with fewer: NaN)."""
    starts = np.cumsum(counts) - counts
    out = np.full((len(counts), width), np.nan)
    for k in range(width):
        has = counts > first + k
        out[has, k] = values[starts[has] + first + k]
    return out


# ---- faces --------------------------------------------------------------------------------------
_FORMS = {  # corner form → (its slashes, fields, separator replaced by a space)
    "v": (0, 1, None),
    "v/vt": (1, 2, b"/"),
    "v//vn": (2, 2, b"//"),
    "v/vt/vn": (2, 3, b"/"),
}


def _corner_form(token: bytes) -> str:
    if b"//" in token:
        return "v//vn"
    return ("v", "v/vt", "v/vt/vn", "?")[min(token.count(b"/"), 3)]


def _corners(rows: list[bytes], numbers: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Each face's corner count, and int64 (corners, 3): each corner's v, vt and vn reference as
    written (0: absent). The whole face text is read at once when every corner has the first
    one's form (each corner's slashes counted on arrays); otherwise, corner by corner."""
    joined = b"\n".join(rows)
    sizes, starts = _tokens(joined, len(rows))
    total = int(sizes.sum())
    first = rows[int(np.argmax(sizes > 0))].split()[0] if total else b""
    form = _corner_form(first)
    if form in _FORMS:
        n_slashes, width, sep = _FORMS[form]
        a = np.frombuffer(joined, np.uint8)
        slashes = np.bincount(np.searchsorted(starts, np.flatnonzero(a == 47), "right") - 1, minlength=total)
        doubles = joined.count(b"//")
        uniform = (slashes == n_slashes).all() and doubles == (total if form == "v//vn" else 0)
        if uniform:
            ints = _parsed(joined if sep is None else joined.replace(sep, b" "), total * width, np.int64)
            if ints is not None:
                out = np.zeros((total, 3), np.int64)
                cols = {"v": (0,), "v/vt": (0, 1), "v//vn": (0, 2), "v/vt/vn": (0, 1, 2)}[form]
                out[:, cols] = ints.reshape(total, width)
                return sizes, out
    out = np.zeros((total, 3), np.int64)
    k = 0
    for row, no in zip(rows, numbers, strict=True):
        for token in row.split():
            fields = token.split(b"/")
            if len(fields) > 3 or not fields[0]:
                raise _refuse(
                    f"line {no}: face 'f {_name(row)[:60]}': {_name(token)[:20]!r} is not a corner "
                    "(v, v/vt, v//vn or v/vt/vn)"
                )
            for j, f in enumerate(fields):
                if f:
                    try:
                        out[k, j] = int(f)
                    except ValueError:
                        raise _refuse(
                            f"line {no}: face 'f {_name(row)[:60]}': {_name(f)[:20]!r} is not a whole number (an index)"
                        ) from None
            k += 1
    return sizes, out


def _resolve(
    refs: np.ndarray, before: np.ndarray, total: int, kind: str, rows: list[bytes], face_of: np.ndarray, numbers
) -> np.ndarray:
    """0-based indices of OBJ references (1 … total, or −1 … −before), −1 where absent (0)."""
    out = np.where(refs > 0, refs - 1, before + refs)
    absent = refs == 0
    bad = ~absent & ((out < 0) | (out >= total))
    if kind == "v":
        bad |= absent
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        f = int(face_of[j])
        k = int(refs[j])
        why = (
            "vertex index 0 (OBJ counts from 1; negative indices count back from the last)"
            if k == 0
            else f"{kind} {k:,} of the {total:,} the file has"
            if k > 0
            else f"{kind} {k} counts back past the {int(before[j]):,} defined before it"
        )
        raise _refuse(f"line {numbers[f]}: face 'f {_name(rows[f])[:60]}': {why}")
    return np.where(absent, -1, out)


@dataclass
class _Obj:
    """The OBJ's lines sorted by keyword, each with its line number."""

    v: list[bytes] = field(default_factory=list)
    v_no: list[int] = field(default_factory=list)
    vt: list[bytes] = field(default_factory=list)
    vt_no: list[int] = field(default_factory=list)
    vn: list[bytes] = field(default_factory=list)
    vn_no: list[int] = field(default_factory=list)
    f: list[bytes] = field(default_factory=list)
    f_no: list[int] = field(default_factory=list)
    usemtl: list[tuple[int, str]] = field(default_factory=list)
    mtllib: list[tuple[int, bytes]] = field(default_factory=list)


def _scan(data: bytes) -> _Obj:
    lines, numbers = _lines(data)
    obj = _Obj()
    v, v_no, vt, vt_no, vn, vn_no, f, f_no = obj.v, obj.v_no, obj.vt, obj.vt_no, obj.vn, obj.vn_no, obj.f, obj.f_no
    for i, line in enumerate(lines):
        at = line.find(b"#")
        if at >= 0:
            line = line[:at]
        words = line.split(None, 1)
        if not words:
            continue
        key = words[0]
        rest = words[1] if len(words) > 1 else b""
        no = i + 1 if numbers is None else numbers[i]
        if key == b"v":
            v.append(rest)
            v_no.append(no)
        elif key == b"f":
            f.append(rest)
            f_no.append(no)
        elif key == b"vt":
            vt.append(rest)
            vt_no.append(no)
        elif key == b"vn":
            vn.append(rest)
            vn_no.append(no)
        elif key == b"usemtl":
            obj.usemtl.append((no, _name(rest)))
        elif key == b"mtllib":
            obj.mtllib.append((no, rest.strip()))
    return obj


# ---- the OBJ -------------------------------------------------------------------------------------
def load_obj_model(files: ModelFiles, *, max_triangles: int, max_vertices: int) -> Model:
    """An OBJ file (and the MTL files and textures beside it, ``files.side``) as a Model: one
    part per material used. SceneError ``file`` for a file that breaks a bound or has a malformed
    line (naming its number), a side file outside the model's folder, an image that declares
    more pixels than ``MAX_MODEL_IMAGE_*``, more materials or textures than a scene holds."""
    side = None if files.side is NO_SIDE_FILES else files.side
    obj = _scan(_text(bytes(files.data)))
    if not obj.f:
        raise SceneError("file", "the OBJ file holds no triangle mesh (no faces)")
    if len(obj.v) > limits.DECLARED_VERTEX_FACTOR * max_vertices:
        raise _refuse(
            f"the file has {len(obj.v):,} vertices; at most {limits.DECLARED_VERTEX_FACTOR * max_vertices:,} "
            f"({limits.DECLARED_VERTEX_FACTOR} per vertex of a mesh)"
        )

    values, counts = _rows(obj.v, obj.v_no, "v", (3, 4, 6), "a vertex is x y z, x y z w or x y z r g b")
    positions = _columns(values, counts, 0, 3)
    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise _refuse(f"line {obj.v_no[i]}: 'v {_name(obj.v[i])[:60]}': not finite numbers")
    colors = None
    if (counts == 6).any():
        rgb = np.where(np.isnan(c := _columns(values, counts, 3, 3)), 1.0, c)
        if (counts != 6).any():
            rgb[counts != 6] = 1.0  # a vertex without colour among coloured ones: white
        rgb = np.nan_to_num(rgb, nan=1.0, posinf=1.0, neginf=0.0)
        if rgb.max(initial=0.0) > 1.0 and rgb.max() <= 255.0:
            rgb = rgb / 255.0  # some exporters write bytes
        colors = np.column_stack([srgb_to_linear(np.clip(rgb, 0.0, 1.0)), np.ones(len(rgb))])
    uv = None
    if obj.vt:
        values, counts = _rows(obj.vt, obj.vt_no, "vt", (1, 2, 3), "a texture coordinate is u, u v or u v w")
        uv = np.nan_to_num(_columns(values, counts, 0, 2), nan=0.0)
        if not np.isfinite(uv).all():
            i = int(np.flatnonzero(~np.isfinite(uv).all(axis=1))[0])
            raise _refuse(f"line {obj.vt_no[i]}: 'vt {_name(obj.vt[i])[:60]}': not finite numbers")
        uv[:, 1] = 1.0 - uv[:, 1]
    normals = None
    if obj.vn:
        values, counts = _rows(obj.vn, obj.vn_no, "vn", (3,), "a normal is x y z")
        normals = values.reshape(-1, 3)

    # faces: corners, their references resolved, fanned into triangles
    sizes, refs = _corners(obj.f, obj.f_no)
    if (sizes < 3).any():
        i = int(np.flatnonzero(sizes < 3)[0])
        raise _refuse(f"line {obj.f_no[i]}: face 'f {_name(obj.f[i])[:60]}': a face needs 3 corners or more")
    n_tri = int((sizes - 2).sum())
    if n_tri > max_triangles:
        raise SceneError("file", f"the model has {n_tri:,} triangles; at most {max_triangles:,} allowed")
    face_of = np.repeat(np.arange(len(sizes)), sizes)
    f_no = np.asarray(obj.f_no)
    refs_v = _resolve(refs[:, 0], np.searchsorted(obj.v_no, f_no)[face_of], len(obj.v), "v", obj.f, face_of, obj.f_no)
    refs_vt = _resolve(
        refs[:, 1], np.searchsorted(obj.vt_no, f_no)[face_of], len(obj.vt), "vt", obj.f, face_of, obj.f_no
    )
    refs_vn = _resolve(
        refs[:, 2], np.searchsorted(obj.vn_no, f_no)[face_of], len(obj.vn), "vn", obj.f, face_of, obj.f_no
    )
    start = np.cumsum(sizes) - sizes
    tri_face = np.repeat(np.arange(len(sizes)), sizes - 2)
    local = np.arange(n_tri) - np.repeat(np.cumsum(sizes - 2) - (sizes - 2), sizes - 2) + 1
    first = start[tri_face]
    triangles = np.column_stack([first, first + local, first + local + 1])  # corner ids

    # materials: each face's usemtl, its library's definition
    names = [name for _, name in obj.usemtl]
    use_at = np.searchsorted([no for no, _ in obj.usemtl], f_no) - 1  # −1: before any usemtl
    used = list(dict.fromkeys(names[u] for u in dict.fromkeys(use_at.tolist()) if u >= 0))  # first use first
    notices: list[str] = []
    library = _Library.read(obj.mtllib, side, notices)
    bank = _TextureBank(side, notices)
    keys = {name: library.key(name) for name in used}  # usemtl's name → the definition's ("Oak" for "oak")
    defined = len({k for k in keys.values() if k is not None})
    if defined > limits.MAX_MATERIALS:
        raise _refuse(f"it uses {defined:,} materials; at most {limits.MAX_MATERIALS} (MAX_MATERIALS)")
    materials: list[PbrMaterial] = []
    index_of_key: dict[str, int] = {}
    for name, key in keys.items():
        if key is None:
            if obj.mtllib and library.files:
                notices.append(f"the material {name!r} (usemtl) is not in the material library: the scene's material")
            continue
        if key not in index_of_key:
            definition = library.find(key)
            assert definition is not None
            index_of_key[key] = len(materials)
            materials.append(_material(definition, bank))
    index_of = {name: index_of_key[key] for name, key in keys.items() if key is not None}
    face_material = np.array([-1] + [index_of.get(n, -1) for n in names], np.int64)[use_at + 1]
    tri_material = face_material[tri_face]

    spans = (len(obj.v), len(obj.vt) + 1, len(obj.vn) + 1)
    order = list(dict.fromkeys(tri_material.tolist()))  # in the order of first use
    if len(order) > limits.MAX_MESHES:
        raise _refuse(f"its faces make {len(order)} parts (one per material); at most {limits.MAX_MESHES} (MAX_MESHES)")
    parts: list[ModelPart] = []
    for m in order:
        tris = triangles[tri_material == m]
        corners = tris.ravel()
        unique, inverse = _distinct_corners(refs_v[corners], refs_vt[corners], refs_vn[corners], spans)
        if len(unique) > max_vertices:
            raise SceneError(
                "file", f"the model has {len(unique):,} distinct vertices in a part; at most {max_vertices:,} per mesh"
            )
        attributes: dict[str, np.ndarray] = {}
        if uv is not None and (unique[:, 1] >= 0).any():
            attributes["uvs"] = np.where(unique[:, 1:2] >= 0, uv[np.maximum(unique[:, 1], 0)], 0.0)
        if colors is not None:
            attributes["colors"] = colors[unique[:, 0]]
        vertices, part_triangles = positions[unique[:, 0]], inverse.reshape(-1, 3)
        parts.append(
            ModelPart(
                vertices, part_triangles, _part_normals(normals, unique[:, 2], vertices, part_triangles), attributes, m
            )
        )
    images = tuple(side.image_names()) if side is not None else ()
    said = list(dict.fromkeys(notices))
    if len(said) > limits.MAX_MODEL_NOTICES:
        more = len(said) - limits.MAX_MODEL_NOTICES + 1
        said = [*said[: limits.MAX_MODEL_NOTICES - 1], f"… and {more:,} more like these"]
    return Model(tuple(parts), tuple(materials), bank.textures(), images, tuple(said))


def _distinct_corners(
    v: np.ndarray, vt: np.ndarray, vn: np.ndarray, spans: tuple[int, int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (v, vt, vn) triples (−1: absent) of corners, (N, 3), and each corner's one.
    The triple as one int64 (v · Nt + vt + 1) · Nn + vn + 1 where that fits: a sort of integers,
    not of rows."""
    nv, nt, nn = spans
    if nv * nt * nn < 1 << 62:
        key = (v * nt + (vt + 1)) * nn + (vn + 1)
        keys, inverse = np.unique(key, return_inverse=True)
        unique = np.column_stack([keys // (nt * nn), (keys // nn) % nt - 1, keys % nn - 1])
        return unique, inverse.reshape(-1)
    unique, inverse = np.unique(np.column_stack([v, vt, vn]), axis=0, return_inverse=True)
    return unique, inverse.reshape(-1)


def _part_normals(
    normals: np.ndarray | None, refs: np.ndarray, vertices: np.ndarray, triangles: np.ndarray
) -> np.ndarray | None:
    """A part's vertex normals from the file's (``refs``: each vertex's vn, −1 none): where a
    corner has none, or the file's is zero or not finite, the area-weighted normal of the part
    (an exporter's ``vn 0 0 0`` costs that vertex its normal, not the part its smoothness);
    None when no vertex has one from the file (flat)."""
    if normals is None or not (refs >= 0).any():
        return None
    n = np.where(refs[:, None] >= 0, normals[np.maximum(refs, 0)], 0.0)
    bad = ~np.isfinite(n).all(axis=1) | ~(np.abs(n).sum(axis=1) > 0)
    if bad.any():
        from ..geometry.meshes import vertex_normals

        n[bad] = vertex_normals(vertices, triangles)[bad]
        if not (np.isfinite(n).all() and (np.abs(n).sum(axis=1) > 0).all()):
            return None  # a vertex only on degenerate triangles: the part is shaded flat
    return n


# ---- the material library -----------------------------------------------------------------------
@dataclass(frozen=True)
class _Definition:
    """One ``newmtl`` of a library: its name, the file and its statements (keyword lowercased →
    (line number, the rest of the line))."""

    name: str
    file: str
    statements: dict[str, tuple[int, str]]
    spelled: dict[str, str]  # each keyword as the file writes it
    folder: str = ""  # the library's folder from the model's ("" the same): its maps are looked up there first

    def where(self, key: str) -> str:
        return f"MTL {self.file!r} line {self.statements[key][0]}"

    def line(self, key: str) -> str:
        """The statement as written (shortened), for messages."""
        return f"'{self.spelled[key]} {self.statements[key][1][:40]}'"


@dataclass
class _Library:
    """The material libraries' definitions (by name: the first wins), read lazily: only the
    materials the faces use are parsed."""

    files: list[str] = field(default_factory=list)
    lines: dict[str, list[bytes]] = field(default_factory=dict)
    ranges: dict[str, tuple[str, int, int]] = field(default_factory=dict)
    folders: dict[str, str] = field(default_factory=dict)
    _folded: dict[str, str] | None = None  # lowercased name → the first name defined so

    @classmethod
    def read(cls, mtllib: list[tuple[int, bytes]], side: SideFiles | None, notices: list[str]) -> _Library:
        lib = cls()
        total = 0
        for _no, rest in mtllib:
            for ref in _library_names(rest, side):
                if side is None:
                    notices.append(
                        f"the model names the material library {ref!r}; send the model's folder as a zip "
                        "(format=zip) for its materials"
                    )
                    continue
                name = side.resolve(ref)  # outside the folder: refused
                if name in lib.lines:
                    continue
                size = side.size(ref)
                if size is None:
                    notices.append(f"the material library {ref!r} is not beside the model: its materials are not read")
                    continue
                total += size
                if total > limits.MAX_MTL_BYTES:
                    raise _refuse(
                        f"its material libraries hold more than {limits.MAX_MTL_BYTES:,} bytes together (MAX_MTL_BYTES)"
                    )
                lib.files.append(name)
                folder = posixpath.relpath(posixpath.dirname(name) or ".", side.base or ".")
                lib.folders[name] = "" if folder == "." else folder
                lines = _text(side.get(ref)).replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")
                lib.lines[name] = lines
                lib._index(name, lines)
        return lib

    def _index(self, file: str, lines: list[bytes]) -> None:
        current: str | None = None
        begin = 0
        for i, line in enumerate(lines):
            s = line.lstrip()
            if s[:6].lower() == b"newmtl" and (len(s) == 6 or s[6:7].isspace()):
                if current is not None and current not in self.ranges:
                    self.ranges[current] = (file, begin, i)
                current = _name(s[6:])
                begin = i + 1
        if current is not None and current not in self.ranges:
            self.ranges[current] = (file, begin, len(lines))

    def key(self, name: str) -> str | None:
        """The defined name ``usemtl name`` means: the same, else the same but for case."""
        if name in self.ranges:
            return name
        if self._folded is None:
            self._folded = {}
            for n in self.ranges:
                self._folded.setdefault(n.lower(), n)
        return self._folded.get(name.lower())

    def find(self, name: str) -> _Definition | None:
        key = self.key(name)
        if key is None:
            return None
        file, begin, end = self.ranges[key]
        statements: dict[str, tuple[int, str]] = {}
        spelled: dict[str, str] = {}
        for i in range(begin, end):
            line = self.lines[file][i]
            at = line.find(b"#")
            if at >= 0:
                line = line[:at]
            words = line.split(None, 1)
            if words:
                keyword = _name(words[0])
                statements[keyword.lower()] = (i + 1, _name(words[1]) if len(words) > 1 else "")
                spelled[keyword.lower()] = keyword
        return _Definition(key, posixpath.basename(file), statements, spelled, self.folders.get(file, ""))


def _library_names(rest: bytes, side: SideFiles | None) -> list[str]:
    """The file names of an ``mtllib`` line: several, separated by spaces, or one whose name has
    spaces (the whole line when it names a file; else words joined until one ends in .mtl)."""
    whole = _name(rest)
    if not whole:
        return []
    if side is not None and side.size(whole) is not None:
        return [whole]
    out: list[str] = []
    pending: list[str] = []
    for word in whole.split():
        pending.append(word)
        joined = " ".join(pending)
        if joined.lower().endswith(".mtl") or (side is not None and side.size(joined) is not None):
            out.append(joined)
            pending = []
    if pending:
        out.append(" ".join(pending))
    return out


# ---- materials ----------------------------------------------------------------------------------
def _numbers(d: _Definition, key: str, sizes: Sequence[int]) -> list[float] | None:
    """The numbers of statement ``key`` (None when absent); refused unless ``sizes`` of them."""
    if key not in d.statements:
        return None
    words = d.statements[key][1].split()
    if words and words[0].lower() in ("spectral", "xyz"):
        return None  # a spectral curve or CIE XYZ colour: not read (docs/FORMATS.md)
    if words and words[0].lower() == "-halo":
        words = words[1:]  # d's halo (dissolve by the view's angle): read as the plain d
    try:
        out = [float(w) for w in words]
    except ValueError:
        out = []
    if len(out) not in sizes or not all(np.isfinite(out)):
        raise _refuse(f"{d.where(key)}: {d.line(key)}: {' or '.join(map(str, sizes))} numbers expected")
    return out


def _color(d: _Definition, key: str) -> np.ndarray | None:
    """An RGB statement (one number: grey) as linear RGB: sRGB decoded in [0, 1], linear above."""
    c = _numbers(d, key, (1, 3))
    if c is None:
        return None
    rgb = np.maximum(np.array(c * 3 if len(c) == 1 else c, np.float64), 0.0)
    return np.where(rgb <= 1.0, srgb_to_linear(np.minimum(rgb, 1.0)), rgb)


def _scalar(d: _Definition, key: str) -> float | None:
    c = _numbers(d, key, (1,))
    return None if c is None else c[0]


def roughness_of_exponent(ns: float) -> float:
    """Perceptual roughness (GGX α = roughness²) of a Phong exponent: α = √(2 / (Ns + 2))."""
    return float((2.0 / (max(ns, 0.0) + 2.0)) ** 0.25)


@dataclass(frozen=True)
class _Map:
    """A texture statement: the file as written and its options."""

    file: str
    scale: tuple[float, float] = (1.0, 1.0)
    offset: tuple[float, float] = (0.0, 0.0)
    clamp: bool = False
    bm: float = 1.0
    folder: str = ""  # its library's folder, from the model's

    def uv_transform(self) -> tuple[tuple[float, float, float, float], tuple[float, float]]:
        """``-s`` and ``-o`` in the scene's V-down UVs: OBJ samples (u·su + ou, v·sv + ov) with
        v = 1 − V, so V' = sv·V + (1 − sv − ov)."""
        su, sv = self.scale
        ou, ov = self.offset
        return (su, 0.0, 0.0, sv), (ou, 1.0 - sv - ov)


def _map(d: _Definition, *keys: str) -> _Map | None:
    """The first of ``keys`` the material has, parsed: the options (before the file name, as
    the specification has them, or after it, as some exporters write them) and the file name
    (which may hold spaces)."""
    key = next((k for k in keys if k in d.statements), None)
    if key is None:
        return None
    text = d.statements[key][1]
    tokens = [(m.group(), m.start(), m.end()) for m in re.finditer(r"\S+", text)]
    number = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
    opts: dict[str, list[str]] = {}
    file = ""
    i = 0
    while i < len(tokens):
        word = tokens[i][0]
        if word.lower() in _OPTION_ARGS:
            name = word.lower()
            args: list[str] = []
            i += 1
            while i < len(tokens) and len(args) < _OPTION_ARGS[name]:
                if name in ("-s", "-o", "-t") and args and not number.fullmatch(tokens[i][0]):
                    break
                args.append(tokens[i][0])
                i += 1
            opts[name] = args
        elif not file:  # the name: every word up to the next option
            j = i
            while j < len(tokens) and tokens[j][0].lower() not in _OPTION_ARGS:
                j += 1
            file = text[tokens[i][1] : tokens[j - 1][2]]
            i = j
        else:
            i += 1
    if not file:
        raise _refuse(f"{d.where(key)}: {d.line(key)} names no file")

    def nums(name: str, default: tuple[float, float]) -> tuple[float, float]:
        try:
            got = [float(x) for x in opts.get(name, [])]
        except ValueError:
            raise _refuse(f"{d.where(key)}: {name} takes numbers") from None
        got += list(default[len(got) :])
        if not all(np.isfinite(got[:2])):
            raise _refuse(f"{d.where(key)}: {name} takes finite numbers")
        return (got[0], got[1])

    bm = 1.0
    if "-bm" in opts:
        try:
            bm = float(opts["-bm"][0])
        except (ValueError, IndexError):
            raise _refuse(f"{d.where(key)}: -bm takes a number") from None
        if not np.isfinite(bm):
            raise _refuse(f"{d.where(key)}: -bm takes a finite number")
    clamp = [w.lower() for w in opts.get("-clamp", [])] == ["on"]
    return _Map(file, nums("-s", (1.0, 1.0)), nums("-o", (0.0, 0.0)), clamp, bm, d.folder)


def _material(d: _Definition, bank: _TextureBank) -> PbrMaterial:
    kd = _color(d, "kd")
    ks = _color(d, "ks")
    ke = _color(d, "ke")
    ns, pr, pm = _scalar(d, "ns"), _scalar(d, "pr"), _scalar(d, "pm")
    dissolve, tr, ni = _scalar(d, "d"), _scalar(d, "tr"), _scalar(d, "ni")
    illum = _scalar(d, "illum")
    map_kd, map_d, map_ke = _map(d, "map_kd"), _map(d, "map_d"), _map(d, "map_ke")
    map_pr, map_pm = _map(d, "map_pr"), _map(d, "map_pm")
    norm, bump = _map(d, "norm"), _map(d, "map_bump", "bump")
    what = f"material {d.name!r}"
    params: dict = {"double_sided": True, "metallic": 0.0}

    base = kd if kd is not None else np.full(3, 1.0 if map_kd is not None else DEFAULT_KD)
    params["base_color"] = tuple(float(x) for x in np.clip(base, 0.0, 1.0))
    if dissolve is not None:
        alpha = dissolve
    elif tr is not None:
        alpha = 1.0 if tr == 1.0 else 1.0 - tr
    else:
        alpha = 1.0
    alpha = float(np.clip(alpha, 0.0, 1.0))
    glass = illum is not None and int(illum) in GLASS_ILLUM
    if glass and alpha < 1.0:
        params["transmission"] = 1.0 - alpha
        alpha = 1.0
    params["alpha"] = alpha
    if alpha < 1.0 or map_d is not None:
        params["alpha_mode"] = "blend"

    if pr is not None:
        params["roughness"] = float(np.clip(pr, 0.0, 1.0))
    elif ks is not None and not (ks > 0).any():
        params["roughness"] = 1.0
    elif ns is not None:
        params["roughness"] = roughness_of_exponent(ns)
    else:
        params["roughness"] = 1.0
    if pm is not None:
        params["metallic"] = float(np.clip(pm, 0.0, 1.0))
    elif map_pm is not None:
        params["metallic"] = 1.0
    if pr is None and map_pr is not None:
        params["roughness"] = 1.0
    params["ior"] = float(min(ni, limits.MAX_IOR)) if ni is not None and ni > 1.0 else DEFAULT_IOR

    emissive = ke if ke is not None else (np.ones(3) if map_ke is not None else None)
    if emissive is not None and (emissive > 0).any():
        strength = float(emissive.max())
        scale = max(strength, 1.0)
        params["emissive"] = tuple(float(x) for x in np.clip(emissive / scale, 0.0, 1.0))
        if scale > 1.0:
            params["emissive_strength"] = float(min(scale, limits.MAX_EMISSION))

    def place(slot: str, index: int | None, m: _Map) -> None:
        if index is None:
            return
        params[f"{slot}_texture"] = index
        matrix, offset = m.uv_transform()
        if matrix != (1.0, 0.0, 0.0, 1.0) or offset != (0.0, 0.0):
            params[f"{slot}_uv_matrix"] = matrix
            params[f"{slot}_uv_offset"] = offset

    if map_kd is not None or map_d is not None:
        primary = map_kd if map_kd is not None else map_d
        assert primary is not None
        place("base_color", bank.base_color(map_kd, map_d, what), primary)
    if map_ke is not None:
        place("emissive", bank.color(map_ke, what, "map_Ke"), map_ke)
    if map_pr is not None or map_pm is not None:
        primary = map_pr if map_pr is not None else map_pm
        assert primary is not None
        place("metallic_roughness", bank.metallic_roughness(map_pr, map_pm, what), primary)
    if norm is not None:
        index = bank.normal(norm, what)
        place("normal", index, norm)
        if index is not None and norm.bm != 1.0:
            params["normal_scale"] = norm.bm
    elif bump is not None:
        place("normal", bank.bump(bump, what), bump)
    try:
        return PbrMaterial(**params)
    except SceneError as e:
        raise _refuse(f"{what}: {e.field}: {e.message}") from None


# ---- textures -----------------------------------------------------------------------------------
def _luminance(pixels: np.ndarray) -> np.ndarray:
    """float32 (H, W) in [0, 1]: the encoded values' luminance (Rec. 709 weights)."""
    return (pixels[..., :3].astype(np.float32) @ _LUMA.astype(np.float32)) / np.float32(255.0)


def _matte(pixels: np.ndarray) -> np.ndarray:
    """uint8 (H, W): a map_d image's alpha where it has one, else its luminance."""
    a = pixels[..., 3]
    if (a < 255).any():
        return a
    return np.rint(_luminance(pixels) * 255.0).astype(np.uint8)


def _resized(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    if pixels.shape[1] == width and pixels.shape[0] == height:
        return pixels
    from PIL import Image

    return np.asarray(Image.fromarray(pixels, "RGBA").resize((width, height), Image.Resampling.BILINEAR))


def height_to_normal(height: np.ndarray, bm: float, clamp: bool = False) -> np.ndarray:
    """uint8 (H, W, 4): the tangent-space normal map (glTF's: +X right, +Y up the image) of a
    height map ``height`` (H, W) in [0, 1], its white ``bm`` × :data:`BUMP_DEPTH` of the
    texture's side above its black; central differences, wrapping unless ``clamp``. In float32
    and a row band at a time: a 4,096² map costs ~100 MB beside its texels, not gigabytes."""
    h = np.asarray(height, np.float32)
    rows, cols = h.shape
    depth = bm * BUMP_DEPTH
    out = np.empty((rows, cols, 4), np.uint8)
    out[..., 3] = 255
    band = 256
    for r0 in range(0, rows, band):
        r1 = min(rows, r0 + band)
        if clamp:
            dcol = np.gradient(h[r0:r1], axis=1) if cols > 1 else np.zeros((r1 - r0, cols), np.float32)
            up = np.minimum(np.arange(r0 + 1, r1 + 1), rows - 1)
            down = np.maximum(np.arange(r0 - 1, r1 - 1), 0)
            span = np.maximum(up - down, 1).astype(np.float32)[:, None]  # one-sided at the edges
            drow = (h[up] - h[down]) / span
        else:
            rows_here = h[r0:r1]
            dcol = (np.roll(rows_here, -1, axis=1) - np.roll(rows_here, 1, axis=1)) / 2.0
            drow = (h[np.arange(r0 + 1, r1 + 1) % rows] - h[np.arange(r0 - 1, r1 - 1) % rows]) / 2.0
        # heights in units of the texture's side: slope = depth · Δh per texel · texels per side
        nx = (-depth * cols) * dcol
        ny = (depth * rows) * drow
        inv = 1.0 / np.sqrt(nx * nx + ny * ny + 1.0)
        for k, c in enumerate((nx * inv, ny * inv, inv)):
            out[r0:r1, :, k] = np.rint((c * 0.5 + 0.5) * 255.0)
    return out


class _TextureBank:
    """The model's textures: images decoded once each (by side-file name), textures made once
    per (image, role, options), what could not be read said in ``notices``."""

    def __init__(self, side: SideFiles | None, notices: list[str]):
        self.side = side
        self.notices = notices
        self._images: dict[str, np.ndarray | None] = {}
        self._made: dict[tuple, int] = {}
        self._textures: list[Texture] = []
        self._texels = 0

    def textures(self) -> tuple[Texture, ...]:
        return tuple(self._textures)

    def _image(self, m: _Map, what: str, statement: str) -> tuple[str, np.ndarray] | None:
        """(the side file's name, uint8 RGBA) of a map's file, None (and a notice) when there is
        none or it cannot be decoded; SceneError when it lies outside the model's folder or its
        declared size breaks the image bounds."""
        if self.side is None:
            self.notices.append(
                f"the {what} reads {m.file!r} ({statement}); send the model's folder as a zip (format=zip) "
                "for its textures"
            )
            return None
        ref = m.file
        if m.folder:  # relative to its library's folder first, as three's and Blender's loaders read it
            beside = posixpath.join(m.folder, m.file.replace("\\", "/"))
            try:
                ref = beside if self.side.size(beside) is not None else ref
            except SceneError:
                pass
        name = self.side.resolve(ref)  # outside the model's folder: refused
        if name not in self._images:
            self._images[name] = self._decode(name, ref, what, statement)
        pixels = self._images[name]
        return None if pixels is None else (name, pixels)

    def _decode(self, name: str, ref: str, what: str, statement: str) -> np.ndarray | None:
        data = self.side.get(ref) if self.side is not None and self.side.size(ref) is not None else None
        if data is None:
            self.notices.append(f"the texture {ref!r} ({what}, {statement}) is not beside the model: not read")
            return None
        if not data.startswith(IMAGE_MAGIC):
            self.notices.append(f"the texture {ref!r} ({what}, {statement}) is not a PNG or JPEG image: not read")
            return None
        check_image(data, repr(ref))  # the declared size, before any pixel is decoded
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(BytesIO(data)) as im:
                side = limits.MAX_TEXTURE_SIDE
                if max(im.size) > side:
                    im.draft("RGB", (side, side))  # JPEG: decoded at a reduced scale already
                    rgba = im.convert("RGBA")
                    rgba.thumbnail((side, side), Image.Resampling.LANCZOS)
                    return np.asarray(rgba, np.uint8).copy()
                return np.asarray(im.convert("RGBA"), np.uint8).copy()
        except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as e:
            self.notices.append(f"the texture {ref!r} ({what}, {statement}) cannot be decoded ({e}): not read")
            return None

    def _add(self, key: tuple, pixels: np.ndarray, srgb: bool, clamp: bool, name: str) -> int:
        if key in self._made:
            return self._made[key]
        if len(self._textures) >= limits.MAX_TEXTURES:
            raise _refuse(f"its materials read more than {limits.MAX_TEXTURES} textures (MAX_TEXTURES)")
        self._texels += pixels.shape[0] * pixels.shape[1]
        if self._texels > limits.MAX_TEXTURE_TEXELS:
            raise _refuse(
                f"its textures hold more than {limits.MAX_TEXTURE_TEXELS:,} texels together (MAX_TEXTURE_TEXELS)"
            )
        wrap = "clamp" if clamp else "repeat"
        self._textures.append(Texture(pixels, srgb, wrap, wrap, "linear", name[: limits.MAX_TEXTURE_NAME]))
        self._made[key] = len(self._textures) - 1
        return self._made[key]

    def color(self, m: _Map, what: str, statement: str) -> int | None:
        got = self._image(m, what, statement)
        if got is None:
            return None
        name, pixels = got
        return self._add(("color", name, m.clamp), pixels, True, m.clamp, posixpath.basename(name))

    def base_color(self, kd: _Map | None, d: _Map | None, what: str) -> int | None:
        """map_Kd, with map_d as its alpha (white under map_d alone)."""
        color = self._image(kd, what, "map_Kd") if kd is not None else None
        matte = self._image(d, what, "map_d") if d is not None else None
        clamp = (kd or d).clamp if (kd or d) is not None else False  # type: ignore[union-attr]
        if matte is None:
            if color is None:
                return None
            return self._add(("color", color[0], clamp), color[1], True, clamp, posixpath.basename(color[0]))
        if color is None:
            h, w = matte[1].shape[:2]
            pixels = np.full((h, w, 4), 255, np.uint8)
            names = posixpath.basename(matte[0])
        else:
            pixels = color[1].copy()
            h, w = pixels.shape[:2]
            names = f"{posixpath.basename(color[0])}+{posixpath.basename(matte[0])}"
        pixels[..., 3] = _matte(_resized(matte[1], w, h))
        key = ("color+alpha", color[0] if color else None, matte[0], clamp)
        return self._add(key, pixels, True, clamp, names)

    def metallic_roughness(self, pr: _Map | None, pm: _Map | None, what: str) -> int | None:
        """map_Pr (green) and map_Pm (blue) in one texture; 255 in a channel without a map."""
        rough = self._image(pr, what, "map_Pr") if pr is not None else None
        metal = self._image(pm, what, "map_Pm") if pm is not None else None
        if rough is None and metal is None:
            return None
        first = rough if rough is not None else metal
        assert first is not None
        h, w = first[1].shape[:2]
        pixels = np.full((h, w, 4), 255, np.uint8)
        pixels[..., 0] = 0
        for channel, got in ((1, rough), (2, metal)):
            if got is not None:
                pixels[..., channel] = np.rint(_luminance(_resized(got[1], w, h)) * 255.0).astype(np.uint8)
        clamp = (pr or pm).clamp  # type: ignore[union-attr]
        key = ("mr", rough[0] if rough else None, metal[0] if metal else None, clamp)
        names = "+".join(posixpath.basename(g[0]) for g in (rough, metal) if g is not None)
        return self._add(key, pixels, False, clamp, names)

    def normal(self, m: _Map, what: str) -> int | None:
        got = self._image(m, what, "norm")
        if got is None:
            return None
        return self._add(("normal", got[0], m.clamp), got[1], False, m.clamp, posixpath.basename(got[0]))

    def bump(self, m: _Map, what: str) -> int | None:
        got = self._image(m, what, "bump")
        if got is None:
            return None
        name, pixels = got
        key = ("bump", name, m.clamp, m.bm)
        if key in self._made:
            return self._made[key]
        normal = height_to_normal(_luminance(pixels), m.bm, m.clamp)
        return self._add(key, normal, False, m.clamp, posixpath.basename(name))
