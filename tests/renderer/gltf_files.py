"""Tiny glTF and GLB files built in the tests: a builder of buffers, views and accessors, and
PNG images of known pixels."""

from __future__ import annotations

import base64
import io
import json
import struct
from typing import Any

import numpy as np

COMPONENT = {np.dtype(np.int8): 5120, np.dtype(np.uint8): 5121, np.dtype(np.int16): 5122}
COMPONENT |= {np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125, np.dtype(np.float32): 5126}
TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def png(pixels: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(pixels, np.uint8), "RGBA" if pixels.shape[2] == 4 else "RGB").save(buf, "PNG")
    return buf.getvalue()


def data_uri(data: bytes, mime: str = "application/octet-stream") -> str:
    return f"data:{mime};base64," + base64.b64encode(data).decode()


class Gltf:
    """A glTF document under construction: ``accessor`` appends an array to the one buffer."""

    def __init__(self) -> None:
        self.binary = bytearray()
        self.doc: dict[str, Any] = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": []}

    def view(self, data: bytes) -> int:
        self.binary += b"\0" * (-len(self.binary) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.binary), "byteLength": len(data)})
        self.binary += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: Any, dtype: Any = np.float32, normalized: bool = False) -> int:
        a = np.asarray(array, dtype)
        a2 = a.reshape(len(a), -1)
        acc: dict[str, Any] = {
            "bufferView": self.view(a2.tobytes()),
            "componentType": COMPONENT[a.dtype],
            "count": len(a2),
            "type": TYPES[a2.shape[1]],
        }
        if normalized:
            acc["normalized"] = True
        if a.dtype == np.float32 and a2.shape[1] == 3:
            acc["min"], acc["max"] = a2.min(axis=0).tolist(), a2.max(axis=0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def add(self, key: str, item: dict) -> int:
        self.doc.setdefault(key, []).append(item)
        return len(self.doc[key]) - 1

    def mesh(self, *primitives: dict) -> int:
        return self.add("meshes", {"primitives": list(primitives)})

    def scene(self, *roots: int) -> None:
        self.doc["scenes"] = [{"nodes": list(roots)}]
        self.doc["scene"] = 0

    def _document(self, uri: str | None) -> dict:
        doc = json.loads(json.dumps(self.doc))
        if self.binary:
            doc["buffers"] = [{"byteLength": len(self.binary)} | ({"uri": uri} if uri is not None else {})]
        return doc

    def glb(self) -> bytes:
        j = json.dumps(self._document(None)).encode()
        j += b" " * (-len(j) % 4)
        b = bytes(self.binary) + b"\0" * (-len(self.binary) % 4)
        body = struct.pack("<I4s", len(j), b"JSON") + j
        if b:
            body += struct.pack("<I4s", len(b), b"BIN\0") + b
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body

    def gltf(self, bin_name: str | None = None) -> bytes:
        """The JSON: its buffer a data URI, or the side file ``bin_name``."""
        uri = bin_name if bin_name is not None else data_uri(bytes(self.binary))
        return json.dumps(self._document(uri)).encode()


def triangle(g: Gltf, **attributes: int) -> dict:
    """A primitive of one triangle in the xy plane, wound counter-clockwise seen from +z."""
    pos = g.accessor([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    return {"attributes": {"POSITION": pos, **attributes}}
