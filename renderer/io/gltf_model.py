"""glTF 2.0 and GLB files read as their authors made them: a :class:`~renderer.io.model.Model` of one
part per primitive per node instance, each with its glTF material as a
:class:`~renderer.materials.pbr.PbrMaterial` and the textures those read.

The JSON is read here, not through trimesh: trimesh keeps only the core material fields (it drops
every extension but specular-glossiness, ``normalTexture.scale``, each texture's ``texCoord`` and
``TEXCOORD_1``). Accessors are read from their buffers with NumPy (strides, normalized integer
types, sparse substitutions, accessors without a buffer view). Node transforms (``matrix`` or
``translation``/``rotation``/``scale``) are composed down the tree and kept with each part
(:attr:`~renderer.io.model.ModelPart.transform`); a mesh that several nodes use is read once and its
parts share their arrays. Images come from a GLB's BIN chunk, data URIs or the files beside the
model, their declared size checked (:func:`renderer.io.model_guard.check_image`) before a pixel is
decoded. docs/FORMATS.md ("glTF") lists every field and extension read and every one that is not,
with the reason.

The caller has checked the file's declared counts and lengths first
(:func:`renderer.io.model_guard.check_model`, as :func:`renderer.io.mesh_io.load_model` does); the reads
here check again what they index, so a file that slips past is refused, never read out of bounds.
Every refusal is ``SceneError("file", ...)`` naming the glTF field. GL-free and server-free.
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import math
import struct
from typing import Any, cast
from urllib.parse import unquote

import numpy as np

from .. import limits
from ..geometry.scene import SceneError
from ..materials import material_params
from ..materials.pbr import PbrMaterial
from ..materials.texture import Texture
from .model import Model, ModelPart
from .model_archive import NO_SIDE_FILES, ModelFiles
from .model_guard import GLTF1, check_image, image_size

# Extensions whose data is read (docs/FORMATS.md, "glTF": what each maps to). A file that requires
# another one (``extensionsRequired``) is refused: what it needs to look right would be missing.
READ_EXTENSIONS = (
    "KHR_texture_transform",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
)
_DTYPES: dict[Any, Any] = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
_WIDTH: dict[Any, int] = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_WRAPS = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_NEAREST = (9728, 9984, 9986)  # NEAREST, NEAREST_MIPMAP_NEAREST, NEAREST_MIPMAP_LINEAR: nearest within a level
_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips"}
_PBR = material_params(PbrMaterial)


def _refuse(fmt: str, message: str) -> SceneError:
    return SceneError("file", f"{fmt.upper()}: {message}")


def load_gltf_model(files: ModelFiles, *, max_triangles: int, max_vertices: int) -> Model:
    """The :class:`~renderer.io.model.Model` of a glTF (``files.format`` ``gltf``) or GLB (``glb``)
    file with its side files. ``max_triangles``: triangles of all parts together (each instance
    counted); ``max_vertices``: vertices of one part. SceneError ``file`` for a file that is not
    glTF 2.0, requires an extension not read, refers to a side file that is not there (naming it),
    holds no triangle, or breaks a bound."""
    return _Reader(files, max_triangles, max_vertices).model()


class _Reader:
    def __init__(self, files: ModelFiles, max_triangles: int, max_vertices: int):
        self.fmt = files.format
        self.side = None if files.side is NO_SIDE_FILES else files.side
        self.max_triangles, self.max_vertices = max_triangles, max_vertices
        self.binary: bytes | None = None
        if self.fmt == "glb":
            self.doc = self._glb(files.data)
        else:
            try:
                self.doc = json.loads(bytes(files.data).decode("utf-8-sig"))
            except (UnicodeDecodeError, ValueError) as e:
                raise _refuse(self.fmt, f"not a glTF JSON document ({e})") from None
        if not isinstance(self.doc, dict):
            raise _refuse(self.fmt, "the JSON document must be an object")
        self._buffers: dict[int, bytes] = {}
        self._accessors: dict[int, np.ndarray] = {}
        self._geometry: dict[tuple[int, int], tuple | None] = {}
        self._textures: dict[tuple, int] = {}
        self._materials: dict[int, int] = {}
        self._pending: list[tuple[int, bool, str, str, str]] = []  # (image, sRGB, wraps, filter) per texture
        self.materials: list[PbrMaterial] = []
        self.notices: list[str] = []

    # ---- the document -------------------------------------------------------------------------
    def _glb(self, data: bytes) -> Any:
        if len(data) < 20 or data[:4] != b"glTF":
            raise _refuse("glb", "no GLB header (the file must start with 'glTF')")
        version, length = struct.unpack_from("<II", data, 4)
        if version != 2:
            raise _refuse("glb", GLTF1 if version == 1 else f"version {version}; only glTF 2 is read")
        length = min(length, len(data))
        json_len = struct.unpack_from("<I", data, 12)[0]
        try:
            doc = json.loads(bytes(data[20 : 20 + json_len]).decode("utf-8-sig"))
        except (UnicodeDecodeError, ValueError) as e:
            raise _refuse("glb", f"its JSON chunk is not JSON ({e})") from None
        at = 20 + json_len
        if at + 8 <= length:
            chunk_len, chunk_type = struct.unpack_from("<II", data, at)
            if chunk_type == 0x004E4942:
                self.binary = bytes(data[at + 8 : min(at + 8 + chunk_len, length)])
        return doc

    def _list(self, key: str) -> list:
        value = self.doc.get(key, [])
        if not isinstance(value, list):
            raise _refuse(self.fmt, f"'{key}' must be a list")
        return value

    def _item(self, key: str, index: Any, where: str) -> dict:
        items = self._list(key)
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise _refuse(self.fmt, f"{where} = {index!r} is not an index of the {len(items)} {key}")
        item = items[index]
        if not isinstance(item, dict):
            raise _refuse(self.fmt, f"{key}[{index}] must be an object")
        return item

    def _check_extensions(self) -> None:
        required = self.doc.get("extensionsRequired", [])
        if not isinstance(required, list):
            raise _refuse(self.fmt, "'extensionsRequired' must be a list")
        missing = [str(e) for e in required if e not in READ_EXTENSIONS]
        if missing:
            raise _refuse(
                self.fmt,
                f"the file requires {', '.join(repr(m) for m in missing)}, which is not read (the extensions read: "
                f"{', '.join(READ_EXTENSIONS)}; docs/FORMATS.md, 'glTF'); export the model without it",
            )

    # ---- buffers and accessors ------------------------------------------------------------------
    def _buffer(self, i: int) -> bytes:
        if i in self._buffers:
            return self._buffers[i]
        buf = self._item("buffers", i, "a bufferView's buffer")
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or self.binary is None:
                raise _refuse(self.fmt, f"buffers[{i}] has no data (no uri, no BIN chunk)")
            data = self.binary
        else:
            data = self._uri(uri, f"buffers[{i}]")
        self._buffers[i] = data
        return data

    def _uri(self, uri: Any, where: str) -> bytes:
        """The bytes a ``uri`` names: a data URI, or a file beside the model."""
        if not isinstance(uri, str):
            raise _refuse(self.fmt, f"{where}.uri must be a string")
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if ";base64" not in head:
                return unquote(payload).encode("latin-1", "replace")
            try:
                return base64.b64decode(payload, validate=False)
            except (binascii.Error, ValueError) as e:
                raise _refuse(self.fmt, f"{where}.uri is not base64 data ({e})") from None
        if self.side is None:
            raise _refuse(
                self.fmt,
                f"{where} is the file {uri!r} beside the model, which a model file sent alone cannot read: "
                "send the model's folder as a zip (format=zip)",
            )
        if self.side.size(uri) is None:
            raise _refuse(self.fmt, f"{where} is the file {uri!r}, which is not beside the model")
        return self.side.get(uri)

    def _view(self, index: Any, where: str) -> tuple[bytes, int, int, int]:
        """(buffer bytes, offset, length, stride or 0) of a bufferView."""
        view = self._item("bufferViews", index, where)
        data = self._buffer(view.get("buffer", -1))
        offset, length = int(view.get("byteOffset", 0)), int(view.get("byteLength", 0))
        if offset < 0 or length < 0 or offset + length > len(data):
            raise _refuse(
                self.fmt, f"bufferViews[{index}] spans bytes {offset:,} … {offset + length:,} of {len(data):,}"
            )
        return data, offset, length, int(view.get("byteStride", 0) or 0)

    def _raw(self, view: Any, offset: int, count: int, dtype: Any, width: int, where: str) -> np.ndarray:
        data, at, length, stride = self._view(view, where)
        item = np.dtype(dtype).itemsize
        element = item * width
        stride = stride or element
        need = offset + (stride * (count - 1) + element if count else 0)
        if offset < 0 or need > length:
            raise _refuse(self.fmt, f"{where} needs bytes to {need:,} of bufferViews[{view}], which has {length:,}")
        if count == 0:
            return np.zeros((0, width), dtype)
        a = np.ndarray((count, width), np.dtype(dtype).newbyteorder("<"), data, at + offset, (stride, item))
        return a.astype(dtype)

    def accessor(self, index: Any, where: str) -> np.ndarray:
        """The accessor's elements as stored, (count, width): float32, or its integer type (the
        normalized ones as glTF maps them to [0, 1] or [−1, 1], float32)."""
        if isinstance(index, int) and index in self._accessors:
            return self._accessors[index]
        acc = self._item("accessors", index, where)
        where = f"accessors[{index}]"
        dtype = _DTYPES.get(acc.get("componentType"))
        width = _WIDTH.get(acc.get("type"))
        if dtype is None or width is None:
            raise _refuse(
                self.fmt,
                f"{where} is componentType {acc.get('componentType')!r} / type {acc.get('type')!r}; "
                "scalars and vectors of glTF's component types are read",
            )
        count = acc.get("count")
        if not isinstance(count, int) or not 0 <= count <= limits.MAX_ACCESSOR_COUNT:
            raise _refuse(self.fmt, f"{where}.count = {count!r}; 0 … {limits.MAX_ACCESSOR_COUNT:,}")
        if acc.get("bufferView") is None:
            a = np.zeros((count, width), dtype)
        else:
            a = self._raw(acc["bufferView"], int(acc.get("byteOffset", 0)), count, dtype, width, where)
        sparse = acc.get("sparse")
        if isinstance(sparse, dict):
            a = self._sparse(a, sparse, dtype, width, where)
        if acc.get("normalized") and dtype is not np.float32:
            top = float(np.iinfo(dtype).max)
            a = np.maximum(a.astype(np.float32) / top, -1.0)
        self._accessors[index] = a
        return a

    def _sparse(self, a: np.ndarray, sparse: dict, dtype: Any, width: int, where: str) -> np.ndarray:
        n = sparse.get("count", 0)
        ind, val = sparse.get("indices", {}), sparse.get("values", {})
        if not isinstance(n, int) or not 0 <= n <= len(a) or not isinstance(ind, dict) or not isinstance(val, dict):
            raise _refuse(self.fmt, f"{where}.sparse must hold a count ≤ {len(a):,}, indices and values")
        idt = _DTYPES.get(ind.get("componentType"))
        if idt not in (np.uint8, np.uint16, np.uint32):
            raise _refuse(self.fmt, f"{where}.sparse.indices.componentType must be an unsigned integer type")
        at = self._raw(ind.get("bufferView"), int(ind.get("byteOffset", 0)), n, idt, 1, where + ".sparse.indices")
        values = self._raw(val.get("bufferView"), int(val.get("byteOffset", 0)), n, dtype, width, where + ".sparse")
        at = at[:, 0].astype(np.int64)
        if n and at.max() >= len(a):
            raise _refuse(self.fmt, f"{where}.sparse.indices reach {int(at.max())}; the accessor has {len(a):,}")
        a = a.copy()
        a[at] = values
        return a

    # ---- geometry ------------------------------------------------------------------------------
    def _attribute(self, attrs: dict, name: str, n: int, widths: tuple[int, ...], where: str) -> np.ndarray | None:
        if name not in attrs:
            return None
        a = self.accessor(attrs[name], f"{where}.attributes.{name}")
        if a.shape[1] not in widths or len(a) != n:
            raise _refuse(
                self.fmt,
                f"{where}.attributes.{name} holds {len(a):,} elements of {a.shape[1]}; "
                f"{n:,} of {' or '.join(map(str, widths))} expected (one per POSITION)",
            )
        out = a.astype(np.float64)
        if not np.isfinite(out).all():
            raise _refuse(self.fmt, f"{where}.attributes.{name} holds numbers that are not finite")
        return out

    def primitive(self, m: int, j: int) -> tuple | None:
        """(vertices, triangles, normals, attributes, material) of meshes[m].primitives[j], read
        once however many nodes use it; None when it holds no triangle."""
        key = (m, j)
        if key in self._geometry:
            return self._geometry[key]
        where = f"meshes[{m}].primitives[{j}]"
        p = self._item("meshes", m, "a node's mesh").get("primitives", [])[j]
        if not isinstance(p, dict) or not isinstance(p.get("attributes"), dict):
            raise _refuse(self.fmt, f"{where}.attributes must be an object")
        attrs = p["attributes"]
        mode = p.get("mode", 4)
        if mode not in (4, 5, 6):
            self.notices.append(f"{where}: {_MODES.get(mode, f'mode {mode!r}')} skipped (only triangles are traced)")
            self._geometry[key] = None
            return None
        if "POSITION" not in attrs:
            raise _refuse(self.fmt, f"{where} has no POSITION")
        v = self.accessor(attrs["POSITION"], f"{where}.attributes.POSITION").astype(np.float64)
        if v.shape[1] != 3 or not np.isfinite(v).all():
            raise _refuse(self.fmt, f"{where}.attributes.POSITION must be finite 3-vectors")
        n = len(v)
        if p.get("indices") is None:
            idx = np.arange(n, dtype=np.int64)
        else:
            ia = self.accessor(p["indices"], f"{where}.indices")
            if ia.dtype.kind != "u" or ia.shape[1] != 1:
                raise _refuse(self.fmt, f"{where}.indices must be unsigned integer scalars")
            idx = ia[:, 0].astype(np.int64)
            if len(idx) and idx.max() >= n:
                raise _refuse(
                    self.fmt, f"{where}.indices reach vertex {int(idx.max()):,}; POSITION holds {n:,} vertices"
                )
        tri = _triangles(idx, mode)
        if len(tri) == 0:
            self._geometry[key] = None
            return None
        normals = self._attribute(attrs, "NORMAL", n, (3,), where)
        extra: dict[str, np.ndarray | None] = {
            "uvs": self._attribute(attrs, "TEXCOORD_0", n, (2,), where),
            "uvs1": self._attribute(attrs, "TEXCOORD_1", n, (2,), where),
            "colors": self._attribute(attrs, "COLOR_0", n, (3, 4), where),
            "tangents": self._attribute(attrs, "TANGENT", n, (4,), where),
        }
        colors = extra["colors"]
        if colors is not None:
            if colors.shape[1] == 3:
                colors = np.concatenate([colors, np.ones((n, 1))], axis=1)
            extra["colors"] = np.clip(colors, 0.0, 1.0)
        tangents = extra["tangents"]
        if tangents is not None:
            tangents[:, 3] = np.where(tangents[:, 3] < 0.0, -1.0, 1.0)
        if normals is not None and not (np.abs(normals).sum(axis=1) > 0).all():
            normals = None  # a zero normal in the file: shade flat rather than refuse the model
            self.notices.append(f"{where}: zero normals in the file, shaded flat")
        # only the vertices these triangles use (primitives often share one large accessor)
        used, tri = np.unique(tri, return_inverse=True)
        tri = tri.reshape(-1, 3)
        if len(used) > self.max_vertices:
            raise _refuse(self.fmt, f"{where} has {len(used):,} vertices; at most {self.max_vertices:,} per mesh")
        if len(used) < n:
            v = v[used]
            normals = None if normals is None else normals[used]
            extra = {k: None if a is None else a[used] for k, a in extra.items()}
        arrays = {k: a for k, a in extra.items() if a is not None}
        for a in (v, tri, normals, *arrays.values()):
            if a is not None:
                a.setflags(write=False)
        out = (v, tri.astype(np.int64), normals, arrays, p.get("material"))
        self._geometry[key] = out
        return out

    # ---- nodes ----------------------------------------------------------------------------------
    def _instances(self) -> list[tuple[int, int, np.ndarray]]:
        """(node, mesh, 4 × 4 world transform) of every node with a mesh in the scene, in order."""
        nodes = self._list("nodes")
        scenes = self._list("scenes")
        if scenes:
            s = self.doc.get("scene", 0)
            roots = self._item("scenes", s, "scene").get("nodes", [])
        else:  # no scene: every root node, as viewers show such a file
            children = {c for n in nodes if isinstance(n, dict) for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        if not nodes and not scenes:  # meshes without nodes: each once, where it is
            return [(-1, m, np.eye(4)) for m in range(len(self._list("meshes")))]
        out = []
        stack = [(r, np.eye(4), 1) for r in reversed(roots)]
        while stack:
            i, parent, depth = stack.pop()
            node = self._item("nodes", i, "a scene's node")
            if depth > limits.MAX_MODEL_NODE_DEPTH:
                raise _refuse(self.fmt, f"its node tree is deeper than {limits.MAX_MODEL_NODE_DEPTH} levels")
            world = parent @ self._local(node, i)
            if node.get("mesh") is not None:
                out.append((i, node["mesh"], world))
            stack.extend((c, world, depth + 1) for c in reversed(node.get("children", [])))
        return out

    def _local(self, node: dict, i: int) -> np.ndarray:
        where = f"nodes[{i}]"
        try:
            if "matrix" in node:
                m = np.array(node["matrix"], dtype=np.float64)
                if m.shape != (16,):
                    raise ValueError
                out = m.reshape(4, 4).T  # glTF's matrices are column-major
            else:
                t = np.array(node.get("translation", (0, 0, 0)), np.float64).reshape(3)
                q = np.array(node.get("rotation", (0, 0, 0, 1)), np.float64).reshape(4)
                s = np.array(node.get("scale", (1, 1, 1)), np.float64).reshape(3)
                out = np.eye(4)
                out[:3, :3] = _rotation(q) * s
                out[:3, 3] = t
        except (TypeError, ValueError):
            raise _refuse(self.fmt, f"{where}: matrix (16 numbers) or translation/rotation/scale (3, 4, 3)") from None
        if not np.isfinite(out).all():
            raise _refuse(self.fmt, f"{where}: its transform holds numbers that are not finite")
        if not np.allclose(out[3], (0.0, 0.0, 0.0, 1.0)):
            raise _refuse(self.fmt, f"{where}.matrix is not affine (its last row must be 0, 0, 0, 1)")
        out[3] = (0.0, 0.0, 0.0, 1.0)  # exporters' float noise: the map is affine
        return out

    # ---- materials and textures ----------------------------------------------------------------
    def material(self, index: Any) -> int:
        """The model's material for glTF material ``index`` (None: the glTF default material)."""
        key = -1 if index is None else index
        if key in self._materials:
            return self._materials[key]
        made = PbrMaterial() if index is None else self._pbr(index)
        self.materials.append(made)
        self._materials[key] = len(self.materials) - 1
        return self._materials[key]

    def _pbr(self, i: Any) -> PbrMaterial:
        m = self._item("materials", i, "a primitive's material")
        where = f"materials[{i}]"
        pbr = _obj(m.get("pbrMetallicRoughness"), f"{where}.pbrMetallicRoughness", self.fmt)
        ext = _obj(m.get("extensions"), f"{where}.extensions", self.fmt)
        kw: dict[str, Any] = {}
        color = _numbers(pbr.get("baseColorFactor", (1, 1, 1, 1)), 4, f"{where}.baseColorFactor", self.fmt)
        kw["base_color"], kw["alpha"] = color[:3], color[3]
        kw["metallic"] = pbr.get("metallicFactor", 1.0)
        kw["roughness"] = pbr.get("roughnessFactor", 1.0)
        kw["emissive"] = _numbers(m.get("emissiveFactor", (0, 0, 0)), 3, f"{where}.emissiveFactor", self.fmt)
        mode = m.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise _refuse(self.fmt, f"{where}.alphaMode = {mode!r}; one of OPAQUE, MASK, BLEND")
        kw["alpha_mode"] = mode.lower()
        kw["alpha_cutoff"] = m.get("alphaCutoff", 0.5)
        kw["double_sided"] = m.get("doubleSided", False) is True
        if "KHR_materials_emissive_strength" in ext:
            kw["emissive_strength"] = _obj(ext["KHR_materials_emissive_strength"], where, self.fmt).get(
                "emissiveStrength", 1.0
            )
        if "KHR_materials_ior" in ext:
            ior = _obj(ext["KHR_materials_ior"], where, self.fmt).get("ior", 1.5)
            kw["ior"] = 1.0 if ior == 0 else ior  # 0: the extension's "no refraction" (an index of 1)
        transmission: dict = {}
        if "KHR_materials_transmission" in ext:
            transmission = _obj(ext["KHR_materials_transmission"], where, self.fmt)
            kw["transmission"] = transmission.get("transmissionFactor", 0.0)
        if "KHR_materials_volume" in ext:
            volume = _obj(ext["KHR_materials_volume"], where, self.fmt)
            kw["attenuation_color"] = _numbers(
                volume.get("attenuationColor", (1, 1, 1)), 3, f"{where}.attenuationColor", self.fmt
            )
            distance = volume.get("attenuationDistance")
            # absent or beyond the scene's coordinates: glTF's infinity, no attenuation (0 here)
            ok = isinstance(distance, (int, float)) and 0 < distance <= limits.MAX_COORDINATE
            kw["attenuation_distance"] = float(cast(float, distance)) if ok else 0.0
        kw = {k: self._clamped(k, v, where) for k, v in kw.items()}
        normal = m.get("normalTexture")
        occlusion = m.get("occlusionTexture")
        for slot, name, info, srgb in (
            ("base_color", "pbrMetallicRoughness.baseColorTexture", pbr.get("baseColorTexture"), True),
            (
                "metallic_roughness",
                "pbrMetallicRoughness.metallicRoughnessTexture",
                pbr.get("metallicRoughnessTexture"),
                False,
            ),
            ("normal", "normalTexture", normal, False),
            ("emissive", "emissiveTexture", m.get("emissiveTexture"), True),
            ("occlusion", "occlusionTexture", occlusion, False),
            (
                "transmission",
                "KHR_materials_transmission.transmissionTexture",
                transmission.get("transmissionTexture"),
                False,
            ),
        ):
            if info is not None:
                kw.update(self._texture_info(slot, info, srgb, f"{where}.{name}"))
        if isinstance(normal, dict) and "normal_texture" in kw:
            kw["normal_scale"] = self._clamped("normal_scale", normal.get("scale", 1.0), where)
        if isinstance(occlusion, dict) and "occlusion_texture" in kw:
            kw["occlusion_strength"] = self._clamped("occlusion_strength", occlusion.get("strength", 1.0), where)
        try:
            return PbrMaterial(**kw)
        except SceneError as e:
            raise _refuse(self.fmt, f"{where}: {e.field}: {e.message}") from None

    def _clamped(self, name: str, value: Any, where: str) -> Any:
        """A factor within its declared range: exporters write 1.0000001 for 1."""
        p = _PBR[name]
        if p.choices:
            return value
        if isinstance(value, tuple):
            return tuple(min(max(x, p.lo), p.hi) for x in value)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _refuse(self.fmt, f"{where}: {name} = {value!r} is not a finite number")
        return min(max(float(value), p.lo), p.hi)

    def _texture_info(self, slot: str, info: Any, srgb: bool, where: str) -> dict[str, Any]:
        """The PbrMaterial fields of a textureInfo (index, texCoord, KHR_texture_transform)."""
        info = _obj(info, where, self.fmt)
        texcoord = info.get("texCoord", 0)
        transform = _obj(info.get("extensions"), where, self.fmt).get("KHR_texture_transform")
        out: dict[str, Any] = {}
        if isinstance(transform, dict):
            ox, oy = _numbers(transform.get("offset", (0, 0)), 2, f"{where}.KHR_texture_transform.offset", self.fmt)
            sx, sy = _numbers(transform.get("scale", (1, 1)), 2, f"{where}.KHR_texture_transform.scale", self.fmt)
            r = transform.get("rotation", 0.0)
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r):
                raise _refuse(self.fmt, f"{where}.KHR_texture_transform.rotation must be a number")
            c, s = math.cos(r), math.sin(r)
            # uv' = T · R · S · uv (the extension's order), R = [[cos, sin], [−sin, cos]]
            matrix = (c * sx, s * sy, -s * sx, c * sy)
            bound = _PBR[f"{slot}_uv_matrix"].hi
            if not all(abs(x) <= bound for x in (*matrix, ox, oy)):
                raise _refuse(self.fmt, f"{where}.KHR_texture_transform: offset and scale within ±{bound:g}")
            out[f"{slot}_uv_matrix"], out[f"{slot}_uv_offset"] = matrix, (ox, oy)
            texcoord = transform.get("texCoord", texcoord)
        if texcoord not in (0, 1) or isinstance(texcoord, bool):
            self.notices.append(f"{where} reads TEXCOORD_{texcoord}: not read (sets 0 and 1 are), texture dropped")
            return {}
        texture = self._texture(info.get("index"), srgb, where)
        if texture < 0:
            return {}
        out[f"{slot}_texture"], out[f"{slot}_texcoord"] = texture, texcoord
        return out

    def _texture(self, index: Any, srgb: bool, where: str) -> int:
        """The model's texture for glTF texture ``index`` read as sRGB or linear (an image read
        both ways is stored twice: the GPU decodes sRGB as it samples); −1 when it has no PNG or
        JPEG source."""
        tex = self._item("textures", index, f"{where}.index")
        source = tex.get("source")
        if source is None:
            self.notices.append(
                f"textures[{index}] has no PNG or JPEG source (only an extension's image, not read): texture dropped"
            )
            return -1
        absent = self._absent_image(source)
        if absent:
            self.notices.append(f"images[{source}] is the file {absent!r}, {self._not_there()}: texture dropped")
            return -1
        sampler = self._item("samplers", tex["sampler"], f"textures[{index}].sampler") if "sampler" in tex else {}
        wrap_s = _WRAPS.get(sampler.get("wrapS", 10497), "repeat")
        wrap_t = _WRAPS.get(sampler.get("wrapT", 10497), "repeat")
        mag, minify = sampler.get("magFilter"), sampler.get("minFilter")
        nearest = mag == 9728 or (mag is None and minify in _NEAREST)
        key = (source, wrap_s, wrap_t, nearest, srgb)
        if key in self._textures:
            return self._textures[key]
        if len(self._pending) >= limits.MAX_TEXTURES:
            raise _refuse(
                self.fmt, f"its materials read more than {limits.MAX_TEXTURES} textures (MAX_TEXTURES per scene)"
            )
        self._pending.append((source, srgb, wrap_s, wrap_t, "nearest" if nearest else "linear"))
        self._textures[key] = len(self._pending) - 1
        return self._textures[key]

    def _absent_image(self, source: Any) -> str | None:
        """The file name images[source] gives when that file is not beside the model (a model loads
        without a texture it lacks, as an OBJ's, and says so: its shape is still what was asked for)."""
        uri = self._item("images", source, "a texture's source").get("uri")
        if not isinstance(uri, str) or uri.startswith("data:"):
            return None
        return uri if self.side is None or self.side.size(uri) is None else None

    def _not_there(self) -> str:
        if self.side is None:
            return "beside the model, which a model file sent alone cannot read (send its folder as a zip: format=zip)"
        return "which is not beside the model"

    def _decoded_textures(self) -> list[Texture]:
        """The textures the materials read, decoded once every image's declared size is checked
        and their texels together are within MAX_TEXTURE_TEXELS: nothing is decoded for a model
        whose images could not all be kept."""
        sources = {}
        declared = 0
        for source, *_ in self._pending:
            if source not in sources:
                sources[source] = self._image_bytes(source)
            data, where, name = sources[source]
            size = image_size(data)
            if size is not None:
                f = math.ceil(max(size) / limits.MAX_TEXTURE_SIDE)
                declared += math.ceil(size[0] / f) * math.ceil(size[1] / f)
        if declared > limits.MAX_TEXTURE_TEXELS:
            raise _refuse(
                self.fmt,
                f"its textures declare {declared:,} texels; at most {limits.MAX_TEXTURE_TEXELS:,} "
                "(MAX_TEXTURE_TEXELS, a scene's textures together)",
            )
        pixels: dict[int, np.ndarray] = {}
        out, texels = [], 0
        for source, srgb, wrap_s, wrap_t, filter in self._pending:
            data, where, name = sources[source]
            if source not in pixels:
                pixels[source] = self._decode(data, where, name)
            texels += pixels[source].shape[0] * pixels[source].shape[1]
            if texels > limits.MAX_TEXTURE_TEXELS:  # (an image whose header did not say its size)
                raise _refuse(
                    self.fmt,
                    f"its textures hold more than {limits.MAX_TEXTURE_TEXELS:,} texels with {where} "
                    "(MAX_TEXTURE_TEXELS, a scene's textures together)",
                )
            out.append(Texture(pixels[source], srgb, wrap_s, wrap_t, filter, name))
        return out

    def _image_bytes(self, i: int) -> tuple[bytes, str, str]:
        """The bytes of images[i], where it is and its name; its declared size checked."""
        image = self._item("images", i, "a texture's source")
        where = f"images[{i}]"
        uri = image.get("uri")
        if image.get("bufferView") is not None:
            data, at, length, _ = self._view(image["bufferView"], f"{where}.bufferView")
            data = data[at : at + length]
            name = str(image.get("name") or where)
        elif uri is not None:
            data = self._uri(uri, where)
            name = where if str(uri).startswith("data:") else unquote(str(uri))
        else:
            raise _refuse(self.fmt, f"{where} has neither a uri nor a bufferView")
        name = name[: limits.MAX_TEXTURE_NAME]
        check_image(data, f"{where} ({name!r})" if name != where else where)
        return data, where, name

    def _decode(self, data: bytes, where: str, name: str) -> np.ndarray:
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(io.BytesIO(data)) as im:
                if im.format not in ("PNG", "JPEG"):
                    raise _refuse(self.fmt, f"{where} ({name!r}) is {im.format}; PNG and JPEG images are read")
                w, h = im.size
                if max(w, h) > limits.MAX_MODEL_IMAGE_SIDE or w * h > limits.MAX_MODEL_IMAGE_PIXELS:
                    # (a header image_size could not read: PIL's numbers, still before any pixel)
                    raise _refuse(
                        self.fmt,
                        f"{where} ({name!r}) declares {w:,} × {h:,} pixels; at most "
                        f"{limits.MAX_MODEL_IMAGE_SIDE:,} a side (MAX_MODEL_IMAGE_SIDE)",
                    )
                factor = math.ceil(max(w, h) / limits.MAX_TEXTURE_SIDE)
                if factor > 1 and im.format == "JPEG":  # decoded at a fraction of its size directly
                    im.draft("RGB", (math.ceil(w / factor), math.ceil(h / factor)))
                # reduced before it is converted: a large image is held decoded once, at its size
                rgba = im if im.mode in ("RGBA", "RGB", "L", "LA") else im.convert("RGBA")
                if max(rgba.size) > limits.MAX_TEXTURE_SIDE:
                    rgba = rgba.reduce(math.ceil(max(rgba.size) / limits.MAX_TEXTURE_SIDE))
                if rgba.mode != "RGBA":
                    rgba = rgba.convert("RGBA")
                if factor > 1:
                    self.notices.append(
                        f"{where} ({name!r}) is {w:,} × {h:,}: reduced to {rgba.size[0]:,} × {rgba.size[1]:,} "
                        f"(MAX_TEXTURE_SIDE {limits.MAX_TEXTURE_SIDE:,})"
                    )
                return np.asarray(rgba, dtype=np.uint8)
        except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as e:
            if isinstance(e, SceneError):
                raise
            raise _refuse(self.fmt, f"{where} ({name!r}) is not a readable PNG or JPEG image ({e})") from None

    # ---- the model --------------------------------------------------------------------------------
    def model(self) -> Model:
        asset = self.doc.get("asset")
        if isinstance(asset, dict) and str(asset.get("version", "2")).strip().startswith("1"):
            raise _refuse(self.fmt, GLTF1)
        self._check_extensions()
        parts: list[ModelPart] = []
        total = 0
        singular = 0
        for node, m, world in self._instances():
            prims = self._item("meshes", m, f"nodes[{node}].mesh").get("primitives", [])
            if not isinstance(prims, list):
                raise _refuse(self.fmt, f"meshes[{m}].primitives must be a list")
            for j in range(len(prims)):
                got = self.primitive(m, j)
                if got is None:
                    continue
                if not abs(np.linalg.det(world[:3, :3])) > 0:
                    singular += 1  # a node scaled to nothing (hidden): no triangle of it can be seen
                    continue
                v, tri, normals, arrays, material = got
                if len(parts) >= limits.MAX_MODEL_PARTS:
                    raise _refuse(
                        self.fmt,
                        f"more than {limits.MAX_MODEL_PARTS:,} parts (primitives × the nodes that place them; "
                        "MAX_MODEL_PARTS): join the primitives of one material",
                    )
                total += len(tri)
                if total > self.max_triangles:
                    raise _refuse(
                        self.fmt,
                        f"the model has more than {self.max_triangles:,} triangles (each node's instance counted)",
                    )
                transform = None if np.array_equal(world, np.eye(4)) else world
                parts.append(ModelPart(v, tri, normals, arrays, self.material(material), m, node, transform))
        if singular:
            self.notices.append(f"{singular} part(s) under a node scaled to zero skipped")
        if not parts:
            raise _refuse(self.fmt, "the file holds no triangle mesh" + _why(self.notices))
        names = tuple(self.side.image_names()) if self.side is not None else ()
        textures = self._decoded_textures()
        said = list(dict.fromkeys(self.notices))
        if len(said) > limits.MAX_MODEL_NOTICES:
            more = len(said) - limits.MAX_MODEL_NOTICES + 1
            said = [*said[: limits.MAX_MODEL_NOTICES - 1], f"… and {more:,} more like these"]
        return Model(tuple(parts), tuple(self.materials), tuple(textures), names, tuple(said))


def _why(notices: list[str]) -> str:
    return f" ({'; '.join(notices[:3])})" if notices else ""


def _obj(value: Any, where: str, fmt: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise _refuse(fmt, f"{where} must be an object")
    return value


def _numbers(value: Any, n: int, where: str, fmt: str) -> tuple[float, ...]:
    if (
        not isinstance(value, (list, tuple))
        or len(value) != n
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)
    ):
        raise _refuse(fmt, f"{where} must be {n} finite numbers, got {value!r}")
    return tuple(float(x) for x in value)


def _rotation(q: np.ndarray) -> np.ndarray:
    """The 3 × 3 rotation of the quaternion (x, y, z, w), normalised."""
    norm = float(np.linalg.norm(q))
    if not norm > 0:
        return np.eye(3)
    x, y, z, w = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    """int64 (T, 3) of a primitive's index list: triangles (mode 4), a strip (5) or a fan (6), each
    wound as the specification orders its vertices."""
    n = len(idx)
    if mode == 4:
        return idx[: n - n % 3].reshape(-1, 3)
    if n < 3:
        return np.zeros((0, 3), np.int64)
    i = np.arange(n - 2)
    if mode == 5:  # p_i = (v_i, v_{i+1+i%2}, v_{i+2-i%2})
        return np.stack([idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]], axis=1)
    return np.stack([idx[i + 1], idx[i + 2], np.full(n - 2, idx[0])], axis=1)  # fan: (v_{i+1}, v_{i+2}, v_0)
