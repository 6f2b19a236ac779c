"""A model as its author hands it over: one model file and its side files (a glTF's ``.bin``
buffers and images, an OBJ's ``.mtl`` and textures), from a zipped folder or a folder on disk.

:func:`open_archive` reads a zip held in memory without trusting it. Before one byte is
inflated, the end record's entry count and every central-directory entry are checked: the
number of entries (``MAX_ARCHIVE_ENTRIES``), each entry's declared size and compression ratio
(``MAX_ARCHIVE_ENTRY_BYTES``, ``MAX_ARCHIVE_RATIO``), their total (``MAX_ARCHIVE_BYTES``), the
names (absolute, a drive letter, ``..``), symbolic links, encryption, compression methods other
than stored and deflate, and archives inside the archive. Inflating then never yields more than
an entry declares (``zipfile`` stops at the declared size and checks the CRC), so the bounds hold
whatever the compressed stream says. Every refusal is ``SceneError("file", ...)`` naming the
entry and the limit; nothing is written to disk.

:class:`SideFiles` answers a model's references (``buffers[i].uri``, ``mtllib``, image names)
by name relative to the model file's folder, never outside it: from the archive's entries
(:class:`ArchiveFiles`) or from the folder of a model given by path (:class:`FolderFiles`, the
command line's). Names are matched as exporters write them: percent-escapes, Windows
separators, a different case, and, for an absolute path of the author's machine, the file's
own name. The images among the side files (:meth:`SideFiles.images`) are kept by name for the
materials that will read them; today only the geometry is parsed.

GL-free and server-free, like the rest of the core.
"""

from __future__ import annotations

import posixpath
import re
import stat
import struct
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from urllib.parse import unquote

from .. import limits
from ..geometry.scene import SceneError

MODEL_SUFFIXES = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".glb": "glb", ".gltf": "gltf"}
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
IMAGE_MAGIC = (b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff")
# Archives and compressed files inside an archive: refused (each would need bounds of its own).
_NESTED_SUFFIXES = (".zip", ".gz", ".tgz", ".tar", ".bz2", ".xz", ".7z", ".rar", ".zst", ".lzma", ".z")
# Their signatures, 3 bytes or more (a buffer of floats starts with two given bytes 1 time in 65,536).
_NESTED_MAGIC = (b"PK\x03\x04", b"\x1f\x8b\x08", b"7z\xbc\xaf\x27\x1c", b"Rar!\x1a\x07", b"\xfd7zXZ\x00", b"(\xb5/\xfd")
_BZIP2 = re.compile(rb"BZh[1-9]1AY&SY")
# What operating systems add to a zip of a folder: skipped, never read.
_JUNK = re.compile(r"(^|/)(__MACOSX/|\._[^/]*$|\.DS_Store$|Thumbs\.db$|desktop\.ini$)", re.IGNORECASE)


def _refuse(message: str) -> SceneError:
    return SceneError("file", f"ZIP: {message}")


class SideFiles:
    """The files beside a model file: its references resolved against its folder (``base``,
    posix, relative to the root the files come from), never outside that root."""

    base: str = ""

    def _lookup(self, name: str) -> bytes | None:  # a normalised name relative to the root
        raise NotImplementedError

    def _names(self) -> list[str]:  # every name there is, relative to the root
        raise NotImplementedError

    def resolve(self, reference: str) -> str:
        """The side file's name (relative to the root) for a reference as the model writes it
        (``textures%20a.png``, ``..\\maps\\a.png``); SceneError when it points outside the root."""
        name = unquote(str(reference)).replace("\\", "/").strip()
        if name.startswith("/") or re.match(r"^[A-Za-z]:/", name):
            name = posixpath.basename(name)  # the author's own machine: only the file's name can match here
        name = posixpath.normpath(posixpath.join(self.base, name))
        if name == ".." or name.startswith("../"):
            raise SceneError("file", f"the side file {reference!r} lies outside the model's folder")
        names = self._names()
        if name in names:
            return name
        folded = [n for n in names if n.lower() == name.lower()]
        if len(folded) == 1:
            return folded[0]
        own = posixpath.basename(name).lower()
        same = [n for n in names if posixpath.basename(n).lower() == own]
        return same[0] if len(same) == 1 else name

    def get(self, reference: str) -> bytes:
        """The side file's bytes; SceneError naming it when there is none."""
        data = self._lookup(self.resolve(reference))
        if data is None:
            raise SceneError("file", f"the model refers to {reference!r}, which is not beside it")
        return data

    def size(self, reference: str) -> int | None:
        """The side file's length in bytes, None when there is none; SceneError when the
        reference points outside the root."""
        data = self._lookup(self.resolve(reference))
        return None if data is None else len(data)

    def image_names(self) -> list[str]:
        """The names (relative to the root: :meth:`read` takes them) of the PNG and JPEG files
        among the side files, for the materials that will read them; not decoded here."""
        return [n for n in self._names() if n.lower().endswith(IMAGE_SUFFIXES)]

    def read(self, name: str) -> bytes | None:
        """The bytes of the side file ``name`` as :meth:`image_names` gives it (relative to the
        root, not resolved from the model's folder), None when there is none."""
        name = posixpath.normpath(name)
        return None if name == ".." or name.startswith(("../", "/")) else self._lookup(name)


@dataclass(frozen=True)
class ArchiveFiles(SideFiles):
    """Side files from an archive's entries (names relative to the archive's root), the model
    in the archive's folder ``base``."""

    entries: Mapping[str, bytes]
    base: str = ""

    def _names(self) -> list[str]:
        return list(self.entries)

    def _lookup(self, name: str) -> bytes | None:
        return self.entries.get(name)

    def image_names(self) -> list[str]:
        """Every PNG and JPEG entry, by its name or by its first bytes."""
        return [n for n, d in self.entries.items() if n.lower().endswith(IMAGE_SUFFIXES) or d.startswith(IMAGE_MAGIC)]


@dataclass(frozen=True)
class FolderFiles(SideFiles):
    """Side files from the folder of a model given by path (the root; read when asked for)."""

    folder: Path
    _listing: list[str] = field(default_factory=list, compare=False)

    def _names(self) -> list[str]:
        if not self._listing:
            try:
                self._listing.extend(p.name for p in self.folder.iterdir() if p.is_file())
            except OSError:
                pass
        return self._listing

    def _path(self, name: str) -> Path | None:
        path = self.folder / name
        try:
            return path if path.resolve().is_relative_to(self.folder.resolve()) and path.is_file() else None
        except OSError:
            return None

    def _lookup(self, name: str) -> bytes | None:
        path = self._path(name)
        try:
            return None if path is None else path.read_bytes()
        except OSError:
            return None

    def size(self, reference: str) -> int | None:
        path = self._path(self.resolve(reference))
        try:
            return None if path is None else path.stat().st_size
        except OSError:
            return None


NO_SIDE_FILES = ArchiveFiles({})


@dataclass(frozen=True)
class ModelFiles:
    """A model file (``name``, ``format`` one of the model formats, its bytes) and its side files."""

    name: str
    format: str
    data: bytes
    side: SideFiles = NO_SIDE_FILES


# ---- the zip ------------------------------------------------------------------------------------
def _declared_entries(data: bytes) -> int:
    """The entries the archive holds, as many as it says anywhere: the end-of-central-directory
    record's count (the zip64 one when it defers) or its central-directory headers, counted by
    their signature (``zipfile`` reads the directory by its size, whatever the count says)."""
    at = data.rfind(b"PK\x05\x06", max(0, len(data) - 22 - 0xFFFF))
    if at < 0 or at + 22 > len(data):
        raise _refuse("not a zip archive (no end-of-central-directory record)")
    entries = struct.unpack_from("<H", data, at + 10)[0]
    if entries == 0xFFFF and at >= 20 and data[at - 20 : at - 16] == b"PK\x06\x07":
        where = struct.unpack_from("<Q", data, at - 12)[0]
        if where + 56 <= len(data) and data[where : where + 4] == b"PK\x06\x06":
            entries = struct.unpack_from("<Q", data, where + 32)[0]
    return max(int(entries), data.count(b"PK\x01\x02", 0, at))


def _check_entry(info: zipfile.ZipInfo) -> str | None:
    """The entry's normalised name, None for a directory or an operating system's extra; refuses
    a name, link, method or size that is not a model folder's."""
    raw = info.filename
    name = raw.replace("\\", "/")
    if name.startswith("/") or re.match(r"^[A-Za-z]:", name):
        raise _refuse(f"the entry {raw!r} has an absolute name; names must be relative to the archive")
    parts = name.split("/")
    if ".." in parts:
        raise _refuse(f"the entry {raw!r} names a parent folder ('..'); names must stay inside the archive")
    if info.create_system == 3 and stat.S_ISLNK(info.external_attr >> 16):
        raise _refuse(f"the entry {raw!r} is a symbolic link; only files and folders are read")
    if name.endswith("/") or info.is_dir():
        return None
    if _JUNK.search(name):
        return None
    if info.flag_bits & 0x1:
        raise _refuse(f"the entry {raw!r} is encrypted")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise _refuse(f"the entry {raw!r} uses compression method {info.compress_type}; only stored and deflate")
    if name.lower().endswith(_NESTED_SUFFIXES):
        raise _refuse(f"the entry {raw!r} is an archive inside the archive; put its files in the zip itself")
    if info.file_size > limits.MAX_ARCHIVE_ENTRY_BYTES:
        raise _refuse(
            f"the entry {raw!r} inflates to {info.file_size:,} bytes; at most "
            f"{limits.MAX_ARCHIVE_ENTRY_BYTES:,} allowed (MAX_ARCHIVE_ENTRY_BYTES)"
        )
    if info.file_size > limits.MAX_ARCHIVE_RATIO_FREE_BYTES and info.file_size > limits.MAX_ARCHIVE_RATIO * max(
        info.compress_size, 1
    ):
        raise _refuse(
            f"the entry {raw!r} inflates {info.compress_size:,} bytes to {info.file_size:,}, more than "
            f"{limits.MAX_ARCHIVE_RATIO}:1 (MAX_ARCHIVE_RATIO): a zip bomb, not a model"
        )
    return posixpath.normpath(name)


def open_archive(data: bytes) -> ModelFiles:
    """The model file inside a zip of a model's folder and its side files (the other entries).
    SceneError ``file`` for an archive that is not a zip, breaks a bound of
    :mod:`renderer.limits` (``MAX_ARCHIVE_*``), holds an unsafe entry, or holds no model file or
    more than one (the message names them)."""
    data = bytes(data)
    declared = _declared_entries(data)
    if declared > limits.MAX_ARCHIVE_ENTRIES:
        raise _refuse(f"{declared:,} entries; at most {limits.MAX_ARCHIVE_ENTRIES:,} allowed (MAX_ARCHIVE_ENTRIES)")
    try:
        archive = zipfile.ZipFile(BytesIO(data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError, struct.error) as e:
        raise _refuse(f"not a readable zip archive ({e})") from None
    infos = archive.infolist()
    if len(infos) > limits.MAX_ARCHIVE_ENTRIES:
        raise _refuse(f"{len(infos):,} entries; at most {limits.MAX_ARCHIVE_ENTRIES:,} allowed (MAX_ARCHIVE_ENTRIES)")
    chosen: list[tuple[str, zipfile.ZipInfo]] = []
    total = 0
    for info in infos:
        name = _check_entry(info)
        if name is None:
            continue
        total += info.file_size
        if total > limits.MAX_ARCHIVE_BYTES:
            raise _refuse(
                f"its entries inflate to more than {limits.MAX_ARCHIVE_BYTES:,} bytes together (MAX_ARCHIVE_BYTES)"
            )
        chosen.append((name, info))
    models = [name for name, _ in chosen if posixpath.splitext(name)[1].lower() in MODEL_SUFFIXES]
    if not models:
        raise _refuse(
            "no model file in the archive; it must hold one of "
            + ", ".join(sorted(MODEL_SUFFIXES))
            + f" ({len(chosen)} other file(s))"
        )
    if len(models) > 1:
        shown = ", ".join(repr(m) for m in models[:5]) + (" …" if len(models) > 5 else "")
        raise _refuse(f"{len(models)} model files ({shown}); the archive must hold one model")
    entries: dict[str, bytes] = {}
    for name, info in chosen:
        try:
            with archive.open(info) as f:
                content = f.read(info.file_size + 1)
        except (zipfile.BadZipFile, ValueError, EOFError, OSError, NotImplementedError) as e:
            raise _refuse(f"the entry {info.filename!r} cannot be read ({e})") from None
        if len(content) != info.file_size:
            raise _refuse(
                f"the entry {info.filename!r} holds {len(content):,} bytes, not the {info.file_size:,} declared"
            )
        if content.startswith(_NESTED_MAGIC) or _BZIP2.match(content):
            raise _refuse(
                f"the entry {info.filename!r} is an archive inside the archive; put its files in the zip itself"
            )
        entries[name] = content
    model = models[0]
    folder = posixpath.dirname(model)
    body = entries.pop(model)
    suffix = posixpath.splitext(model)[1].lower()
    return ModelFiles(posixpath.basename(model), MODEL_SUFFIXES[suffix], body, ArchiveFiles(entries, folder))


def folder_files(path: Path, format: str) -> ModelFiles:
    """A model file on disk and the files of its folder (read when the model refers to them)."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SceneError("file", f"cannot read {str(path)!r} ({e.strerror or e})") from None
    return ModelFiles(path.name, format, data, FolderFiles(path.parent))
