"""Checks of a model file's own numbers before a parser believes them.

A parser allocates what a file declares: a glTF accessor of 30 million vertices without any
data behind it becomes a 360 MB array of zeros (and several copies of it) before anything
notices that the model is empty; a binary STL whose header count disagrees with its length
sends trimesh down its text path; a PLY header may promise rows the file does not hold. So
:func:`check_model` reads only the counts, lengths and structure of a file — the glTF JSON,
the STL header, the PLY header, the OBJ face lines — and compares them with the bytes that
are really there and with the bounds of :mod:`renderer.limits`, refusing with
``SceneError("file", ...)`` that says what is wrong and which limit. Nothing here allocates
more than the file's own size. GL-free and server-free, like the rest of the core.
"""

from __future__ import annotations

import base64
import gc
import json
import re
import struct
from typing import Any
from urllib.parse import unquote

from .. import limits
from ..geometry.scene import SceneError
from .model_archive import ArchiveFiles, SideFiles

GLTF1 = "glTF 1.0 is not supported; convert to glTF 2.0 (e.g. with the Khronos glTF converters or Blender)"


def _refuse(fmt: str, message: str) -> SceneError:
    return SceneError("file", f"{fmt.upper()}: {message}")


def check_model(
    data: bytes,
    ft: str,
    *,
    max_triangles: int = limits.MAX_TRIANGLES,
    max_vertices: int = limits.MAX_MESH_VERTICES,
    side: SideFiles | None = None,
) -> None:
    """Refuse (SceneError ``file``) a model file of format ``ft`` whose declared counts exceed
    ``max_triangles`` triangles or ``DECLARED_VERTEX_FACTOR × max_vertices`` vertices, or
    disagree with the bytes it holds, or whose images (beside it or inside it) declare more
    pixels than ``MAX_MODEL_IMAGE_*``. ``side``: the files beside it (a glTF's external
    buffers); None: a model given alone has none."""
    try:
        _check(data, ft, max_triangles, limits.DECLARED_VERTEX_FACTOR * max_vertices, side)
        if isinstance(side, ArchiveFiles):  # held in memory: every image in the archive
            for name in side.image_names():
                check_image(side.entries[name], repr(name))
    except SceneError:
        raise
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, struct.error, RecursionError) as e:
        # a structure the checks did not foresee (a list where a number belongs, bad base64 …)
        raise _refuse(ft, f"not a readable {ft.upper()} file ({type(e).__name__}: {str(e)[:200]})") from None


def _check(data: bytes, ft: str, max_triangles: int, max_declared_vertices: int, side: SideFiles | None) -> None:
    if ft == "glb":
        doc, bin_at, bin_len = _glb_chunks(data)
        _check_gltf(doc, bin_len, None, max_triangles, max_declared_vertices, "glb")
        _check_gltf_images(doc, data[bin_at : bin_at + (bin_len or 0)], "glb", side)
    elif ft == "gltf":
        try:
            doc = _json(bytes(data))
        except (UnicodeDecodeError, ValueError) as e:
            raise _refuse(ft, f"not a glTF JSON document ({e})") from None
        _check_gltf(doc, None, side, max_triangles, max_declared_vertices, "gltf")
        _check_gltf_images(doc, b"", "gltf", side)
    elif ft == "stl":
        _check_stl(data, max_triangles)
    elif ft == "ply":
        _check_ply(data, max_triangles, max_declared_vertices)
    elif ft == "obj":
        _check_obj(data, max_triangles, max_declared_vertices)


# ---- glTF / GLB ---------------------------------------------------------------------------------
# Looked up with whatever JSON value the file holds there (a miss is refused).
_COMPONENT_BYTES: dict[Any, int] = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COMPONENTS: dict[Any, int] = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _json(text: bytes) -> Any:
    """The JSON document, parsed without a garbage collection meanwhile: 100,000 nodes are as
    many dicts, and each collection they trigger would walk the whole heap of the process."""
    was = gc.isenabled()
    gc.disable()
    try:
        return json.loads(text.decode("utf-8-sig"))
    finally:
        if was:
            gc.enable()


def _glb_chunks(data: bytes) -> tuple[Any, int, int | None]:
    """The GLB's JSON document, where its BIN chunk's data starts and its length (None without one)."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise _refuse("glb", "no GLB header (the file must start with 'glTF' and hold a JSON chunk)")
    version, length = struct.unpack_from("<II", data, 4)
    if version == 1:
        raise _refuse("glb", GLTF1)
    if version != 2:
        raise _refuse("glb", f"version {version}; only glTF 2 is read")
    if length > len(data):
        raise _refuse("glb", f"the header says {length:,} bytes, the file has {len(data):,}")
    json_len, json_type = struct.unpack_from("<II", data, 12)
    if json_type != 0x4E4F534A or 20 + json_len > length:
        raise _refuse(
            "glb", f"the first chunk must be JSON within the file ({json_len:,} bytes declared, {length - 20:,} there)"
        )
    try:
        doc = _json(bytes(data[20 : 20 + json_len]))
    except (UnicodeDecodeError, ValueError) as e:
        raise _refuse("glb", f"its JSON chunk is not JSON ({e})") from None
    bin_len = None
    at = 20 + json_len
    if at + 8 <= length:
        chunk_len, chunk_type = struct.unpack_from("<II", data, at)
        if chunk_type == 0x004E4942:
            if at + 8 + chunk_len > length:
                raise _refuse("glb", f"its BIN chunk declares {chunk_len:,} bytes, {length - at - 8:,} are there")
            bin_len = chunk_len
    return doc, at + 8, bin_len


def _list(doc: dict, key: str, fmt: str) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list):
        raise _refuse(fmt, f"'{key}' must be a list")
    return value


def _index(obj: dict, key: str, n: int, where: str, fmt: str, required: bool = False) -> int | None:
    value = obj.get(key)
    if value is None:
        if required:
            raise _refuse(fmt, f"{where} has no '{key}'")
        return None
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < n:
        raise _refuse(fmt, f"{where}.{key} = {value!r} is not an index of the {n} there are")
    return value


def _count(obj: dict, key: str, where: str, fmt: str, default: int | None = None, limit: int | None = None) -> int:
    value = obj.get(key, default)
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise _refuse(fmt, f"{where}.{key} = {value!r} must be a whole number ≥ 0")
    if limit is not None and value > limit:
        raise _refuse(fmt, f"{where}.{key} = {value:,}; at most {limit:,} allowed")
    return value


def _buffer_sizes(doc: dict, bin_len: int | None, side: SideFiles | None, fmt: str) -> list[int]:
    """The bytes really available to each buffer (and that its byteLength fits in them)."""
    sizes = []
    for i, buf in enumerate(_list(doc, "buffers", fmt)):
        where = f"buffers[{i}]"
        if not isinstance(buf, dict):
            raise _refuse(fmt, f"{where} must be an object")
        declared = _count(buf, "byteLength", where, fmt)
        uri = buf.get("uri")
        if uri is None:
            have = bin_len if (i == 0 and bin_len is not None) else 0
            what = "the GLB's BIN chunk" if i == 0 and bin_len is not None else "no data (no uri, no BIN chunk)"
        elif not isinstance(uri, str):
            raise _refuse(fmt, f"{where}.uri must be a string")
        elif uri.startswith("data:"):
            payload = uri.partition(",")[2]
            have = (
                len(base64.b64decode(payload, validate=False))
                if ";base64" in uri.partition(",")[0]
                else len(unquote(payload).encode())
            )
            what = "its data URI"
        elif side is None:
            raise _refuse(
                fmt,
                f"{where} is the file {uri!r} beside the model, which a model file sent alone cannot "
                "read: send the model's folder as a zip (format=zip)",
            )
        else:
            have = side.size(uri) or 0
            what = f"the file {uri!r}"
        if declared > have:
            raise _refuse(fmt, f"{where} declares {declared:,} bytes, {what} holds {have:,}")
        sizes.append(declared)
    return sizes


def _gltf_version(doc: dict, fmt: str) -> None:
    """Refuse glTF 1.0 by what it declares, or by its shape: objects of named buffers, not lists."""
    asset = doc.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if (
        str(version).strip().startswith("1")
        or isinstance(doc.get("buffers"), dict)
        or isinstance(doc.get("meshes"), dict)
    ):
        raise _refuse(fmt, GLTF1)


# Extensions that hold a mesh's geometry compressed: trimesh cannot decode them and would read
# placeholder zeros in their place.
_COMPRESSED_GEOMETRY = ("KHR_draco_mesh_compression", "EXT_meshopt_compression")


def _compressed_geometry(doc: dict, fmt: str) -> None:
    used = doc.get("extensionsUsed", [])
    required = doc.get("extensionsRequired", [])
    for name in _COMPRESSED_GEOMETRY:
        if (isinstance(used, list) and name in used) or (isinstance(required, list) and name in required):
            raise _refuse(
                fmt, f"its geometry is compressed with {name}, which is not read; export the model without it"
            )


def _check_gltf(
    doc: Any, bin_len: int | None, side: SideFiles | None, max_triangles: int, max_vertices: int, fmt: str
) -> None:
    if not isinstance(doc, dict):
        raise _refuse(fmt, "the JSON document must be an object")
    _gltf_version(doc, fmt)
    _compressed_geometry(doc, fmt)
    buffers = _buffer_sizes(doc, bin_len, side, fmt)
    views = _list(doc, "bufferViews", fmt)
    view_bytes = 0
    for i, view in enumerate(views):
        where = f"bufferViews[{i}]"
        if not isinstance(view, dict):
            raise _refuse(fmt, f"{where} must be an object")
        b = _index(view, "buffer", len(buffers), where, fmt, required=True)
        assert b is not None  # required
        offset = _count(view, "byteOffset", where, fmt, 0)
        length = _count(view, "byteLength", where, fmt)
        _count(view, "byteStride", where, fmt, 4, limit=252)
        if offset + length > buffers[b]:
            raise _refuse(
                fmt, f"{where} spans bytes {offset:,} … {offset + length:,} of buffers[{b}], which has {buffers[b]:,}"
            )
        view_bytes += length
    if view_bytes > limits.MAX_MODEL_ARRAY_BYTES:
        raise _refuse(
            fmt,
            f"its bufferViews add up to {view_bytes:,} bytes; at most "
            f"{limits.MAX_MODEL_ARRAY_BYTES:,} allowed (MAX_MODEL_ARRAY_BYTES)",
        )

    accessors = _list(doc, "accessors", fmt)
    counts, array_bytes, zero_bytes = [], 0, 0
    for i, acc in enumerate(accessors):
        where = f"accessors[{i}]"
        if not isinstance(acc, dict):
            raise _refuse(fmt, f"{where} must be an object")
        count = _count(acc, "count", where, fmt, limit=limits.MAX_ACCESSOR_COUNT)
        comp = _COMPONENT_BYTES.get(acc.get("componentType"))
        comps = _TYPE_COMPONENTS.get(acc.get("type"))
        if comp is None or comps is None:
            raise _refuse(
                fmt, f"{where} has componentType {acc.get('componentType')!r} / type {acc.get('type')!r}, not glTF's"
            )
        element = comp * comps
        v = _index(acc, "bufferView", len(views), where, fmt)
        if v is not None:
            stride = views[v].get("byteStride") or element
            offset = _count(acc, "byteOffset", where, fmt, 0)
            need = offset + (stride * (count - 1) + element if count else 0)
            if need > views[v]["byteLength"]:
                raise _refuse(
                    fmt,
                    f"{where} needs {count:,} × {element} bytes (to byte {need:,}) of "
                    f"bufferViews[{v}], which has {views[v]['byteLength']:,}",
                )
        sparse = acc.get("sparse")
        if sparse is not None and (
            not isinstance(sparse, dict) or _count(sparse, "count", where + ".sparse", fmt) > count
        ):
            raise _refuse(fmt, f"{where}.sparse must be an object of at most {count:,} elements")
        counts.append(count)
        array_bytes += count * element
        if v is None:
            zero_bytes += count * element
            if zero_bytes > limits.MAX_BUFFERLESS_BYTES:
                raise _refuse(
                    fmt,
                    f"{where} has no bufferView and {count:,} elements: its accessors without data "
                    f"would take {zero_bytes:,} bytes of zeros; at most {limits.MAX_BUFFERLESS_BYTES:,} "
                    "allowed (MAX_BUFFERLESS_BYTES)",
                )
    if array_bytes > limits.MAX_MODEL_ARRAY_BYTES:
        raise _refuse(
            fmt,
            f"its accessors add up to {array_bytes:,} bytes of arrays; at most "
            f"{limits.MAX_MODEL_ARRAY_BYTES:,} allowed (MAX_MODEL_ARRAY_BYTES)",
        )

    # per mesh: the triangles and vertices one instance of it adds
    mesh_cost = []
    for i, mesh in enumerate(_list(doc, "meshes", fmt)):
        prims = mesh.get("primitives", []) if isinstance(mesh, dict) else None
        if not isinstance(prims, list):
            raise _refuse(fmt, f"meshes[{i}].primitives must be a list")
        tris = verts = 0
        for j, p in enumerate(prims):
            where = f"meshes[{i}].primitives[{j}]"
            attrs = p.get("attributes", {}) if isinstance(p, dict) else None
            if not isinstance(attrs, dict):
                raise _refuse(fmt, f"{where}.attributes must be an object")
            for name in attrs:
                _index(attrs, name, len(accessors), f"{where}.attributes", fmt)
            pos = attrs.get("POSITION")
            ind = _index(p, "indices", len(accessors), where, fmt)
            n = counts[ind] if ind is not None else (counts[pos] if pos is not None else 0)
            mode = p.get("mode", 4)
            tris += n // 3 if mode == 4 else (max(0, n - 2) if mode in (5, 6) else 0)
            verts += counts[pos] if pos is not None else 0
        mesh_cost.append((tris, verts))

    nodes = _list(doc, "nodes", fmt)
    if len(nodes) > limits.MAX_MODEL_NODES:
        raise _refuse(fmt, f"{len(nodes):,} nodes; at most {limits.MAX_MODEL_NODES:,} allowed (MAX_MODEL_NODES)")
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise _refuse(fmt, f"nodes[{i}] must be an object")
        _index(node, "mesh", len(mesh_cost), f"nodes[{i}]", fmt)
        children = node.get("children", [])
        if not isinstance(children, list):
            raise _refuse(fmt, f"nodes[{i}].children must be a list")
        for c in children:
            if not isinstance(c, int) or isinstance(c, bool) or not 0 <= c < len(nodes):
                raise _refuse(fmt, f"nodes[{i}].children holds {c!r}, not an index of the {len(nodes)} nodes")
            if c in parent or c == i:
                raise _refuse(
                    fmt, f"nodes[{c}] is a child of more than one node (or of itself): the node graph must be a tree"
                )
            parent[c] = i

    scenes = _list(doc, "scenes", fmt)
    if scenes:
        s = _index(doc, "scene", len(scenes), "the document", fmt) or 0
        roots = scenes[s].get("nodes", []) if isinstance(scenes[s], dict) else None
        if not isinstance(roots, list):
            raise _refuse(fmt, f"scenes[{s}].nodes must be a list")
        for r in roots:
            if not isinstance(r, int) or isinstance(r, bool) or not 0 <= r < len(nodes) or r in parent:
                raise _refuse(fmt, f"scenes[{s}].nodes holds {r!r}, not a root node's index")
    else:
        roots = []
    # every node reachable from a node without parent; what is not is on a cycle
    seen = 0
    tris = verts = 0
    reached = [False] * len(nodes)
    in_scene = set(roots)
    stack = [(i, 1, i in in_scene) for i in range(len(nodes)) if i not in parent]
    while stack:
        i, depth, counted = stack.pop()
        if depth > limits.MAX_MODEL_NODE_DEPTH:
            raise _refuse(
                fmt, f"its node tree is deeper than {limits.MAX_MODEL_NODE_DEPTH} levels (MAX_MODEL_NODE_DEPTH)"
            )
        reached[i] = True
        seen += 1
        m = nodes[i].get("mesh")
        if counted and m is not None:
            tris += mesh_cost[m][0]
            verts += mesh_cost[m][1]
        stack.extend((c, depth + 1, counted) for c in nodes[i].get("children", []))
    if seen != len(nodes):
        first = reached.index(False)
        raise _refuse(fmt, f"its node graph has a cycle (through nodes[{first}]): it must be a tree")
    if not scenes:
        tris = sum(t for t, _ in mesh_cost)
        verts = sum(v for _, v in mesh_cost)
    _check_totals(fmt, tris, verts, max_triangles, max_vertices)


def _check_totals(fmt: str, tris: int, verts: int, max_triangles: int, max_vertices: int) -> None:
    if tris > max_triangles:
        raise _refuse(fmt, f"the file declares {tris:,} triangles; at most {max_triangles:,} allowed")
    if verts > max_vertices:
        raise _refuse(
            fmt,
            f"the file declares {verts:,} vertices; at most {max_vertices:,} allowed "
            f"({limits.DECLARED_VERTEX_FACTOR} per vertex of a mesh before equal ones merge)",
        )


# ---- images inside a model -----------------------------------------------------------------------
def image_size(data: bytes) -> tuple[int, int] | None:
    """A PNG's or JPEG's declared (width, height) from its header, None for another format or a
    header that cannot be read (nothing is decoded)."""
    if data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) >= 24 and data[12:16] == b"IHDR":
        w, h = struct.unpack_from(">II", data, 16)
        return int(w), int(h)
    if data.startswith(b"\xff\xd8"):
        at = 2
        while at + 4 <= len(data):
            if data[at] != 0xFF:
                return None
            marker = data[at + 1]
            if marker == 0xFF:  # fill byte
                at += 1
                continue
            if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
                at += 2
                continue
            length = struct.unpack_from(">H", data, at + 2)[0]
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC) and at + 9 <= len(data):
                h, w = struct.unpack_from(">HH", data, at + 5)
                return int(w), int(h)
            if marker == 0xDA or length < 2:  # the scan starts before any frame header: not a JPEG we read
                return None
            at += 2 + length
    return None


def check_image(data: bytes, what: str) -> None:
    """Refuse an image whose declared size exceeds ``MAX_MODEL_IMAGE_SIDE`` or
    ``MAX_MODEL_IMAGE_PIXELS`` — before any decoder allocates its pixels."""
    size = image_size(data)
    if size is None:
        return
    w, h = size
    if max(w, h) > limits.MAX_MODEL_IMAGE_SIDE or w * h > limits.MAX_MODEL_IMAGE_PIXELS:
        raise SceneError(
            "file",
            f"the image {what} declares {w:,} × {h:,} pixels; at most {limits.MAX_MODEL_IMAGE_SIDE:,} a side "
            f"and {limits.MAX_MODEL_IMAGE_PIXELS:,} in all (MAX_MODEL_IMAGE_SIDE, MAX_MODEL_IMAGE_PIXELS)",
        )


def _check_gltf_images(doc: dict, binary: bytes, fmt: str, side: SideFiles | None) -> None:
    """Each of the glTF's images (in a data URI, a bufferView of the GLB's BIN chunk, or a side
    file) within the image bounds."""
    views = doc.get("bufferViews", [])
    for i, image in enumerate(_list(doc, "images", fmt)):
        if not isinstance(image, dict):
            raise _refuse(fmt, f"images[{i}] must be an object")
        uri, view = image.get("uri"), image.get("bufferView")
        data = b""
        if isinstance(uri, str) and uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            try:  # the header is in the first bytes: a truncated decode of them is enough
                data = base64.b64decode(payload[: 1 << 16], validate=False) if ";base64" in head else b""
            except ValueError:
                data = b""
        elif isinstance(uri, str) and side is not None and not isinstance(side, ArchiveFiles):
            data = side.get(uri) if side.size(uri) is not None else b""
        elif view is not None and binary:
            v = _index(image, "bufferView", len(views), f"images[{i}]", fmt)
            assert v is not None
            if views[v].get("buffer", 0) == 0:
                start = _count(views[v], "byteOffset", f"bufferViews[{v}]", fmt, 0)
                data = bytes(binary[start : start + min(views[v]["byteLength"], 1 << 20)])
        check_image(data, f"images[{i}]")


# ---- STL ----------------------------------------------------------------------------------------
def _check_stl(data: bytes, max_triangles: int) -> None:
    n = len(data)
    count = struct.unpack_from("<I", data, 80)[0] if n >= 84 else None
    if count is not None and 84 + 50 * count == n:
        _check_totals("stl", count, 0, max_triangles, 1)
        if count == 0:
            raise _refuse("stl", "the binary header says 0 triangles")
        return
    head = bytes(data[:512]).lstrip().lower()
    if head.startswith(b"solid"):
        facets = len(re.findall(rb"(?i)\bendfacet\b", data))
        if facets:
            _check_totals("stl", facets, 0, max_triangles, 1)
            return
        if count is None:
            raise _refuse("stl", "a text STL ('solid …') without any facet")
    if count is None:
        raise _refuse("stl", f"{n:,} bytes: shorter than a binary STL's 84-byte header")
    raise _refuse(
        "stl",
        f"the binary header says {count:,} triangles, which take 84 + 50 × {count:,} = "
        f"{84 + 50 * count:,} bytes; the file has {n:,}",
    )


# ---- PLY ----------------------------------------------------------------------------------------
_PLY_TYPES = {
    "char": 1,
    "int8": 1,
    "uchar": 1,
    "uint8": 1,
    "short": 2,
    "int16": 2,
    "ushort": 2,
    "uint16": 2,
    "int": 4,
    "int32": 4,
    "uint": 4,
    "uint32": 4,
    "float": 4,
    "float32": 4,
    "double": 8,
    "float64": 8,
}


def _check_ply(data: bytes, max_triangles: int, max_vertices: int) -> None:
    end = data.find(b"end_header", 0, limits.MAX_PLY_HEADER_BYTES)
    if not data.startswith(b"ply") or end < 0:
        raise _refuse(
            "ply",
            f"no PLY header ('ply' … 'end_header' within {limits.MAX_PLY_HEADER_BYTES:,} bytes, MAX_PLY_HEADER_BYTES)",
        )
    nl = data.find(b"\n", end)
    body_at = len(data) if nl < 0 else nl + 1
    fmt = None
    elements: list[list] = []  # [name, count, fixed bytes, list count bytes]
    for raw in bytes(data[:end]).decode("ascii", "replace").splitlines()[1:]:
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            if not words[2].isdigit():
                raise _refuse("ply", f"'element {words[1]} {words[2]}': the count must be a whole number ≥ 0")
            elements.append([words[1], int(words[2]), 0, 0])
        elif words[0] == "property" and elements:
            if len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES:
                elements[-1][3] += _PLY_TYPES[words[2]]
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1][2] += _PLY_TYPES[words[1]]
            else:
                raise _refuse("ply", f"'{raw.strip()}' is not a PLY property")
        elif words[0] in ("element", "property", "format"):
            raise _refuse("ply", f"'{raw.strip()[:60]}' is not a PLY header line")
        # any other line is a comment without its keyword (Blender 2.4's 'Created by Blender3D …'),
        # which trimesh's reader skips too
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _refuse("ply", f"format {fmt!r}; one of ascii, binary_little_endian, binary_big_endian")
    counts = {name: count for name, count, _, _ in elements}
    _check_totals("ply", counts.get("face", 0), counts.get("vertex", 0), max_triangles, max_vertices)
    declared = ", ".join(f"element {name} {count:,}" for name, count, _, _ in elements)
    if fmt == "ascii":
        rows = sum(count for _, count, _, _ in elements)
        present = sum(1 for _ in re.finditer(rb"(?m)^[ \t\r]*[^\s]", data[body_at:]))
        if present < rows:
            raise _refuse("ply", f"the header declares {declared} ({rows:,} rows); the file holds {present:,}")
    else:
        # each row takes its fixed properties plus each list's count (a list may be empty)
        least = sum(count * (fixed + lists) for _, count, fixed, lists in elements)
        if len(data) - body_at < least:
            raise _refuse(
                "ply",
                f"the header declares {declared}, at least {least:,} bytes of data; the file "
                f"holds {len(data) - body_at:,}",
            )


# ---- OBJ ----------------------------------------------------------------------------------------
_OBJ_VERTEX = re.compile(rb"(?m)^[ \t]*v[ \t]")
_OBJ_FACE = re.compile(rb"(?m)^[ \t]*f[ \t]+([^\r\n#]*)")


def _check_obj(data: bytes, max_triangles: int, max_vertices: int) -> None:
    """Every face's vertex references within the vertices (1 … V, or −1 … −(those defined
    before the face)); the triangles its polygons split into within ``max_triangles``. On
    arrays: a 16 MiB file is checked in a fraction of its parse."""
    import numpy as np

    vertex_at = np.fromiter((m.start() for m in _OBJ_VERTEX.finditer(data)), np.int64)
    n_vertices = len(vertex_at)
    _check_totals("obj", 0, n_vertices, max_triangles, max_vertices)
    faces = [(m.start(), m.group(1)) for m in _OBJ_FACE.finditer(data)]
    if not faces:
        return
    starts = np.fromiter((at for at, _ in faces), np.int64, len(faces))
    # the vertex reference is what comes before a face corner's first '/' ('7/2/7'); '|' ends each face
    words = np.array((b" | ".join(text for _, text in faces) + b" |").split())
    if words.dtype.itemsize > 1:
        chars = words.view(np.uint8).reshape(len(words), words.dtype.itemsize).copy()
        slash = chars == ord("/")
        cut = np.where(slash.any(axis=1), slash.argmax(axis=1), chars.shape[1])
        chars[np.arange(chars.shape[1]) >= cut[:, None]] = 0
        words = chars.view(words.dtype).ravel()
    ends = np.flatnonzero(words == b"|")
    sizes = np.diff(ends, prepend=-1) - 1
    tris = int(np.maximum(sizes - 2, 0).sum())
    if tris > max_triangles:
        raise _refuse("obj", f"its faces split into {tris:,} triangles; at most {max_triangles:,} allowed")
    try:
        refs = words[words != b"|"].astype(np.int64)
    except ValueError:
        for at, text in faces:
            for ref in text.split():
                try:
                    int(ref.split(b"/", 1)[0])
                except ValueError:
                    raise _refuse(
                        "obj",
                        f"line {_line_of(data, at)}: face 'f {text.strip().decode(errors='replace')[:60]}': "
                        f"{ref.decode(errors='replace')[:20]!r} is not a whole number "
                        "(a vertex reference)",
                    ) from None
        raise
    face_of = np.repeat(np.arange(len(faces)), sizes)
    before = np.searchsorted(vertex_at, starts)[face_of]  # vertices defined before each face
    bad = (refs == 0) | (refs > n_vertices) | (-refs > before)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        k, line = int(refs[j]), faces[face_of[j]][1].strip().decode(errors="replace")[:60]
        why = (
            "vertex index 0 (OBJ counts from 1; negative indices count back from the last vertex)"
            if k == 0
            else f"vertex {k:,} of the {n_vertices:,} the file has"
            if k > 0
            else f"vertex {k} counts back past the {int(before[j]):,} vertices defined before it"
        )
        raise _refuse("obj", f"line {_line_of(data, faces[face_of[j]][0])}: face 'f {line}': {why}")


def _line_of(data: bytes, at: int) -> int:
    """The number of the line holding byte ``at`` (from 1; a lone CR ends a line too)."""
    head = data[:at]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1
