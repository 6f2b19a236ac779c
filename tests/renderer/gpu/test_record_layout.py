"""A record's layout declared once (renderer.gpu.record_layout): the packer, its inverse, the GLSL
accessors and the docs' table from one table of fields."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.gpu.gpu_layout import Binding
from renderer.gpu.record_layout import Field, RecordLayout

ARRAY = Binding("u_things", doc="test records", records=True)


def two_texel_record() -> RecordLayout:
    return RecordLayout(
        "thing",
        ARRAY,
        texels=2,
        fields=(
            Field("lo", 0, "xyz", "float", "a corner"),
            Field("kind", 0, "w", "uint", "the kind", bits=(31, 28)),
            Field("index", 0, "w", "uint", "an index", bits=(27, 0)),
            Field("weight", 1, "y", "float", "a weight"),
            Field("mask", 1, "z", "uint", "a mask", bits=(7, 0)),
        ),
        doc="a test record",
        notes=("a note",),
    )


def test_pack_puts_each_field_in_its_words_and_bits_and_unpack_reads_them_back():
    rec = two_texel_record()
    lo = np.array([[1.0, -2.5, 3.0], [0.0, 1e-30, -0.0]], dtype=np.float32)
    cols = dict(
        lo=lo,
        kind=np.array([15, 2]),
        index=np.array([(1 << 28) - 1, 7]),
        weight=np.array([0.5, -4.0]),
        mask=np.array([255, 0]),
    )
    out = rec.pack(2, **cols)
    assert out.dtype == np.uint32 and out.shape == (4, 4) and rec.bytes == 32
    # Written out by hand: record r at texels 2r (corner, kind | index) and 2r + 1 (0, weight, mask, 0).
    np.testing.assert_array_equal(out[0, :3], lo[0].view(np.uint32))
    assert out[0, 3] == (15 << 28) | ((1 << 28) - 1) and out[2, 3] == (2 << 28) | 7
    assert out[1, 0] == 0 and out[1, 1] == np.float32(0.5).view(np.uint32) and out[1, 2] == 255 and out[1, 3] == 0
    assert out[3, 1] == np.float32(-4.0).view(np.uint32) and out[3, 2] == 0
    back = rec.unpack(out)
    np.testing.assert_array_equal(back["lo"].view(np.uint32), lo.view(np.uint32))  # -0.0 kept
    for name in ("kind", "index", "mask"):
        np.testing.assert_array_equal(back[name], cols[name])
    np.testing.assert_array_equal(back["weight"], np.float32([0.5, -4.0]))


def test_a_value_too_wide_for_its_bits_or_a_missing_column_is_refused_naming_the_field():
    rec = two_texel_record()
    cols = dict(lo=np.zeros((1, 3)), kind=[16], index=[0], weight=[0.0], mask=[0])
    with pytest.raises(ValueError, match=r"thing\.kind: values 16 … 16 outside 0 … 15"):
        rec.pack(1, **cols)
    with pytest.raises(ValueError, match=r"thing\.mask"):
        rec.pack(1, **{**cols, "kind": [1], "mask": [-1]})
    with pytest.raises(ValueError, match=r"missing \['weight'\]"):
        rec.pack(1, **{k: v for k, v in cols.items() if k != "weight"})
    with pytest.raises(ValueError, match=r"thing\.lo: shape \(1, 2\)"):
        rec.pack(1, **{**cols, "kind": [1], "lo": np.zeros((1, 2))})


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ((Field("a", 0, "x", "uint", "", bits=(7, 0)), Field("b", 0, "x", "uint", "", bits=(8, 7))), "overlaps"),
        ((Field("a", 0, "xyz", "float", ""), Field("b", 0, "z", "uint", "")), "overlaps"),
        ((Field("a", 1, "x", "uint", ""),), "texel 1 outside"),
        ((Field("a", 0, "xz", "uint", ""),), "not a run"),
        ((Field("a", 0, "x", "float", "", bits=(15, 0)),), "only a one-component uint"),
        ((Field("a", 0, "x", "half", ""),), "kind 'half'"),
    ],
)
def test_a_declaration_that_cannot_be_packed_is_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        RecordLayout("bad", ARRAY, texels=1, fields=fields, doc="")


def test_the_glsl_accessors_read_each_field_of_record_i():
    # The expected text is written by hand from the declaration above.
    assert two_texel_record().glsl_accessors().splitlines() == [
        "#define thing_lo(i) uintBitsToFloat(u_things_at(2 * (i)).xyz)",
        "#define thing_kind(i) (u_things_at(2 * (i)).w >> 28u)",
        "#define thing_index(i) (u_things_at(2 * (i)).w & 268435455u)",
        "#define thing_weight(i) uintBitsToFloat(u_things_at(2 * (i) + 1).y)",
        "#define thing_mask(i) u_things_at(2 * (i) + 1).z",  # alone in its word: nothing to mask
    ]


def test_the_table_lists_every_word_in_order_with_the_unused_ones():
    rows = [line for line in two_texel_record().markdown().splitlines() if line.startswith("| ")]
    assert rows[1:] == [
        "| 0 | xyz | all | `lo` | vec3 (float32 bits) | a corner |",
        "| 0 | w | 31..28 | `kind` | uint | the kind |",
        "| 0 | w | 27..0 | `index` | uint | an index |",
        "| 1 | x | all | | | unused, 0 |",
        "| 1 | y | all | `weight` | float (float32 bits) | a weight |",
        "| 1 | z | 7..0 | `mask` | uint | a mask |",
        "| 1 | w | all | | | unused, 0 |",
    ]
    assert two_texel_record().markdown().rstrip().endswith("- a note")
