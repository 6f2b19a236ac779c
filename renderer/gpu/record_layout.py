"""A GPU record's layout declared once: its fields → the packer, the GLSL accessors, the docs.

A record array (a :class:`renderer.gpu.gpu_layout.Binding` with ``records=True``) holds 16-byte
``uvec4`` texels; a record is ``texels`` of them in a row, record ``i`` starting at texel
``texels · i``. A :class:`RecordLayout` lists its :class:`Field` s — name, texel, components,
type, the bits of the word a field shares with others, meaning — and from that one table
come:

- :meth:`RecordLayout.pack`: the columns of ``n`` records (one array per field) → uint32
  ``(n · texels, 4)``, float32 fields as their bits, a value too wide for its bits refused;
- :meth:`RecordLayout.unpack`: the inverse, for the CPU mirrors of a traversal and the tests;
- :meth:`RecordLayout.glsl_accessors`: one accessor macro per field, ``<record>_<field>(i)`` for record
  ``i`` (``bvh_node_left_min(i)``), over the binding's ``NAME_at(i)`` whatever its storage
  (texture or uniform block). Macros, not functions: the method's header precedes the
  shader's default precision statements, and a macro expands to the very expression a
  hand-written read would be, so the compiled program does not change;
- :meth:`RecordLayout.markdown`: its table in ``docs/FORMATS.md``.

GL-free: NumPy and text only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gpu_layout import Binding

COMPONENTS = "xyzw"
KINDS = ("float", "uint")
WORD_BITS = 32
TEXEL_BYTES = 16  # one uvec4


@dataclass(frozen=True)
class Field:
    """One field of a record: ``components`` (a run of ``"xyzw"``) of texel ``texel``, each a
    32-bit word holding a float32 (``kind`` ``"float"``) or an unsigned integer (``"uint"``).
    A one-component uint field may take only ``bits`` = (high, low) of its word (inclusive),
    beside other fields in the rest of it."""

    name: str
    texel: int
    components: str
    kind: str
    doc: str
    bits: tuple[int, int] = (WORD_BITS - 1, 0)

    @property
    def width(self) -> int:
        """Bits of each component the field takes."""
        return self.bits[0] - self.bits[1] + 1

    @property
    def glsl_type(self) -> str:
        n = len(self.components)
        if self.kind == "float":
            return "float" if n == 1 else f"vec{n}"
        return "uint" if n == 1 else f"uvec{n}"

    @property
    def words(self) -> list[tuple[int, int]]:
        """(texel, component index) of each word the field is in."""
        return [(self.texel, COMPONENTS.index(c)) for c in self.components]


@dataclass(frozen=True)
class RecordLayout:
    """One kind of record in a record array (``binding``): ``texels`` uvec4 per record and
    its ``fields``; words no field names are zero. ``name`` prefixes the GLSL accessors;
    ``notes``: lines the documentation adds under the table (how a field's values read)."""

    name: str
    binding: Binding
    texels: int
    fields: tuple[Field, ...]
    doc: str
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.binding.records:
            raise ValueError(f"{self.name}: {self.binding.name} is not a record array")
        taken: dict[tuple[int, int], int] = {}
        for f in self.fields:
            where = f"{self.name}.{f.name}"
            if f.kind not in KINDS:
                raise ValueError(f"{where}: kind {f.kind!r} is not one of {KINDS}")
            if not 0 <= f.texel < self.texels:
                raise ValueError(f"{where}: texel {f.texel} outside 0 … {self.texels - 1}")
            if not f.components or f.components not in COMPONENTS:
                raise ValueError(f"{where}: components {f.components!r} are not a run of {COMPONENTS!r}")
            high, low = f.bits
            if not 0 <= low <= high < WORD_BITS:
                raise ValueError(f"{where}: bits {f.bits} are not (high, low) of a 32-bit word")
            if f.width < WORD_BITS and (f.kind != "uint" or len(f.components) != 1):
                raise ValueError(f"{where}: only a one-component uint field takes part of a word")
            mask = ((1 << f.width) - 1) << low
            for w in f.words:
                if taken.get(w, 0) & mask:
                    raise ValueError(f"{where}: overlaps another field in texel {w[0]}.{COMPONENTS[w[1]]}")
                taken[w] = taken.get(w, 0) | mask
        if len({f.name for f in self.fields}) != len(self.fields):
            raise ValueError(f"{self.name}: two fields of one name")

    @property
    def bytes(self) -> int:
        """Bytes per record."""
        return TEXEL_BYTES * self.texels

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")

    def _shares_above(self, f: Field) -> bool:
        """Whether another field takes bits above ``f``'s in its word (a read must mask them)."""
        return any(g is not f and g.words == f.words and g.bits[1] > f.bits[0] for g in self.fields)

    # ---- NumPy -----------------------------------------------------------------------------
    def pack(self, n: int, **columns: np.ndarray) -> np.ndarray:
        """``n`` records from one column per field (``(n,)`` for one component, ``(n, k)`` for
        ``k``): uint32 ``(n · texels, 4)``. Every field must be given; a uint value outside its
        bits is a ValueError naming the field (never silently cut)."""
        names = {f.name for f in self.fields}
        if set(columns) != names:
            missing, extra = sorted(names - set(columns)), sorted(set(columns) - names)
            raise ValueError(f"{self.name}: columns missing {missing}, unknown {extra}")
        out = np.zeros((n, self.texels, 4), dtype=np.uint32)
        for f in self.fields:
            col = np.asarray(columns[f.name])
            shape = (n,) if len(f.components) == 1 else (n, len(f.components))
            if col.shape != shape:
                raise ValueError(f"{self.name}.{f.name}: shape {col.shape}, expected {shape}")
            c0 = COMPONENTS.index(f.components[0])
            dst = out[:, f.texel, c0 : c0 + len(f.components)]
            if f.kind == "float":
                dst[...] = np.ascontiguousarray(col, dtype=np.float32).view(np.uint32).reshape(dst.shape)
                continue
            wide = col.astype(np.int64)
            if wide.size and (wide.min() < 0 or wide.max() >= 1 << f.width):
                raise ValueError(
                    f"{self.name}.{f.name}: values {wide.min()} … {wide.max()} outside 0 … {(1 << f.width) - 1}"
                )
            dst |= (wide.astype(np.uint32) << np.uint32(f.bits[1])).reshape(dst.shape)
        return out.reshape(n * self.texels, 4)

    def unpack(self, records: np.ndarray) -> dict[str, np.ndarray]:
        """The columns of packed ``records`` (uint32 ``(n · texels, 4)``): float fields as
        float32, uint fields as uint32 (each field's bits only)."""
        rec = np.ascontiguousarray(records, dtype=np.uint32).reshape(-1, self.texels, 4)
        out: dict[str, np.ndarray] = {}
        for f in self.fields:
            c0 = COMPONENTS.index(f.components[0])
            words = rec[:, f.texel, c0 : c0 + len(f.components)]
            if len(f.components) == 1:
                words = words[:, 0]
            if f.kind == "float":
                out[f.name] = np.ascontiguousarray(words).view(np.float32)
            else:
                out[f.name] = (words >> np.uint32(f.bits[1])) & np.uint32((1 << f.width) - 1)
        return out

    # ---- GLSL ------------------------------------------------------------------------------
    def accessor(self, f: Field) -> str:
        """The GLSL expression of field ``f`` of record ``(i)``."""
        at = f"{self.binding.name}_at"
        index = "i" if self.texels == 1 else f"{self.texels} * (i)" + (f" + {f.texel}" if f.texel else "")
        word = f"{at}({index}).{f.components}"
        if f.kind == "float":
            return f"uintBitsToFloat({word})"
        high, low = f.bits
        if low:
            word = f"({word} >> {low}u)"
        if self._shares_above(f):
            word = f"({word} & {(1 << f.width) - 1}u)"
        return word

    def glsl_accessors(self) -> str:
        """One ``#define <name>_<field>(i)`` per field: the field of record ``i``."""
        return "".join(f"#define {self.name}_{f.name}(i) {self.accessor(f)}\n" for f in self.fields)

    # ---- documentation ---------------------------------------------------------------------
    def markdown(self) -> str:
        """The record's table for docs/FORMATS.md: each texel's words, in order, with the unused
        ones as 0."""
        lines = [
            f"**`{self.binding.name}`**: {self.doc}; {self.texels} texel{'s' if self.texels > 1 else ''}, "
            f"{self.bytes} bytes per record, read in GLSL as `{self.name}_<field>(i)`",
            "",
            "| texel | component | bits | field | GLSL type | meaning |",
            "|---|---|---|---|---|---|",
        ]
        by_word: dict[tuple[int, int], list[Field]] = {}
        for f in self.fields:
            by_word.setdefault(f.words[0], []).append(f)
        covered = {w for f in self.fields for w in f.words}
        for t in range(self.texels):
            for c in range(4):
                for f in sorted(by_word.get((t, c), []), key=lambda g: -g.bits[0]):
                    bits = "all" if f.width == WORD_BITS else f"{f.bits[0]}..{f.bits[1]}"
                    kind = f"{f.glsl_type} (float32 bits)" if f.kind == "float" else f.glsl_type
                    lines.append(f"| {t} | {f.components} | {bits} | `{f.name}` | {kind} | {f.doc} |")
                if (t, c) not in covered:
                    lines.append(f"| {t} | {COMPONENTS[c]} | all | | | unused, 0 |")
        if self.notes:
            lines.append("")
            lines += [f"- {n}" for n in self.notes]
        return "\n".join(lines) + "\n"
