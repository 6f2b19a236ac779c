"""The .hdr run-length decoder (renderer/materials/envmap.py) against a packet-by-packet reference (the
reader's former loop, kept here as the oracle): the same texels for well-formed files, the same
refusal (message) for files cut short or with malformed packets, crafted here."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.geometry.scene import SceneError
from renderer.materials.envmap import check_texels, read_hdr


def reference_rgbe(data: bytes) -> np.ndarray:
    """The RGBE bytes (H, W, 4) of a file with the bare header this module writes, one packet at a
    time (SceneError as the reader's messages)."""
    head, _, rest = data.partition(b"\n\n")
    nl = rest.index(b"\n")
    _, h, _, w = rest[:nl].split()
    height, width = int(h), int(w)
    pos = len(head) + 2 + nl + 1
    n = len(data)
    out = np.empty((height, width, 4), dtype=np.uint8)
    for y in range(height):
        if 8 <= width < 32768 and data[pos : pos + 2] == b"\x02\x02" and pos + 4 <= n:
            if (data[pos + 2] << 8 | data[pos + 3]) != width:
                raise SceneError("body", f"scanline {y}: its run-length header says another width")
            pos += 4
            for c in range(4):
                row = bytearray()
                while len(row) < width:
                    if pos >= n:
                        raise SceneError("body", f"the file ends inside scanline {y}")
                    count = data[pos]
                    if count > 128:
                        count -= 128
                        if len(row) + count > width or pos + 1 >= n:
                            raise SceneError("body", f"scanline {y}: a run passes the end of the line")
                        row += data[pos + 1 : pos + 2] * count
                        pos += 2
                    else:
                        if count == 0 or len(row) + count > width or pos + 1 + count > n:
                            raise SceneError("body", f"scanline {y}: a run passes the end of the line")
                        row += data[pos + 1 : pos + 1 + count]
                        pos += 1 + count
                out[y, :, c] = np.frombuffer(bytes(row), dtype=np.uint8)
        else:
            if data[pos : pos + 3] == b"\x01\x01\x01":
                raise SceneError("body", "old-style run-length encoding is not read: save the file again")
            if pos + 4 * width > n:
                raise SceneError("body", f"the file ends inside scanline {y}")
            out[y] = np.frombuffer(data, dtype=np.uint8, count=4 * width, offset=pos).reshape(width, 4)
            pos += 4 * width
    return out


def rgbe_texels(rgbe: np.ndarray) -> np.ndarray:
    e = rgbe[..., 3].astype(np.int32)
    f = np.where(e > 0, np.ldexp(np.float32(1.0), e - 136), np.float32(0.0)).astype(np.float32)
    return rgbe[..., :3].astype(np.float32) * f[..., None]


def encode(rgbe: np.ndarray, rng: np.random.Generator, flat_rows: float = 0.0) -> bytes:
    """A Radiance file of ``rgbe``: each scanline flat (with probability ``flat_rows``) or run-length
    encoded with packets of random kinds and sizes (runs of 1–127, literals of 1–128)."""
    h, w = rgbe.shape[:2]
    out = bytearray(f"#?RADIANCE\n\n-Y {h} +X {w}\n".encode())
    for y in range(h):
        if rng.random() < flat_rows:
            out += rgbe[y].tobytes()
            continue
        out += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            row = rgbe[y, :, c].tolist()
            x = 0
            while x < w:
                same = 1
                while x + same < w and same < 127 and row[x + same] == row[x]:
                    same += 1
                if same > 1 and rng.random() < 0.8:
                    k = int(rng.integers(1, same + 1))
                    out += bytes([128 + k, row[x]])
                else:
                    k = int(rng.integers(1, min(128, w - x) + 1))
                    out += bytes([k, *row[x : x + k]])
                x += k
    return bytes(out)


def image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """RGBE bytes with stretches that repeat (runs) and stretches that do not."""
    rgbe = rng.integers(0, 4, (h, w, 4), dtype=np.uint8) * 60
    rgbe[..., 3] = np.where(rng.random((h, w)) < 0.5, 128, 131)
    for _ in range(3):
        x = int(rng.integers(0, w))
        rgbe[:, x:] = rgbe[:, x : x + 1]
    return rgbe


def outcome(data: bytes):
    try:
        return read_hdr(data)
    except SceneError as e:
        return e.message


def reference_outcome(data: bytes):
    try:
        return check_texels(rgbe_texels(reference_rgbe(data)))
    except SceneError as e:
        return e.message


def same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return isinstance(a, str) and isinstance(b, str) and a == b
    return a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("seed", range(8))
def test_well_formed_files_read_as_the_reference_reads_them(seed):
    """Widths that are multiples of 256 are read many scanlines at once, others one by one."""
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(2, 7)), [8, 9, 37, 300, 256, 512, 256, 768][seed]
    rgbe = image(rng, h, w)
    data = encode(rgbe, rng, flat_rows=0.3 if seed % 2 else 0.0)
    got = read_hdr(data)
    np.testing.assert_array_equal(got, rgbe_texels(rgbe))
    assert same(got, reference_outcome(data))


@pytest.mark.parametrize("seed", range(4))
def test_files_cut_short_are_refused_as_the_reference_refuses_them(seed):
    rng = np.random.default_rng(100 + seed)
    data = encode(image(rng, 4, 256 if seed % 2 else 40), rng, flat_rows=0.25 if seed < 2 else 0.0)
    start = data.index(b"\n\n-Y") + 1
    start = data.index(b"\n", start + 1) + 1
    cuts = sorted({*rng.integers(start, len(data), 40).tolist(), start, start + 1, len(data) - 1})
    for cut in cuts:
        got, want = outcome(data[:cut]), reference_outcome(data[:cut])
        assert same(got, want), (cut, got if isinstance(got, str) else "texels", want)
        assert isinstance(got, str)


@pytest.mark.parametrize("seed", range(6))
def test_malformed_packets_are_refused_as_the_reference_refuses_them(seed):
    """Bytes changed at random (a count of 0, a run or a literal passing its channel's end, a
    header of another width, packets shifted): whatever the reference does, the reader does."""
    rng = np.random.default_rng(200 + seed)
    data = bytearray(encode(image(rng, 3, 256 if seed % 2 else 24), rng, flat_rows=0.2 if seed > 3 else 0.0))
    start = data.index(b"\n", data.index(b"-Y")) + 1
    refused = 0
    for _ in range(60):
        bad = bytearray(data)
        for _ in range(int(rng.integers(1, 4))):
            bad[int(rng.integers(start, len(bad)))] = int(rng.choice([0, 1, 2, 127, 128, 129, 200, 255]))
        got, want = outcome(bytes(bad)), reference_outcome(bytes(bad))
        assert same(got, want), (got if isinstance(got, str) else "texels", want)
        refused += isinstance(want, str)
    assert refused > 3  # the changes do make malformed files


@pytest.mark.parametrize("w", [8, 256])
def test_one_byte_runs_and_crafted_edges(w):
    hdr = f"#?RADIANCE\n\n-Y 2 +X {w}\n".encode()
    line = bytes([2, 2, w >> 8, w & 255]) + bytes([0x81, 7]) * (4 * w)
    head = bytes([2, 2, w >> 8, w & 255])
    full = bytes([0x81, 7]) * (w - 8)  # all but the last 8 bytes of a channel
    cases = [
        hdr + line * 2,  # every packet a run of one
        hdr + line + head,  # the header, then nothing
        hdr + line + head + bytes([0x81]),  # a run without its byte
        hdr + line + head + full + bytes([8]) + bytes(7),  # a literal cut short
        hdr + line + head + full + bytes([0x89, 1]),  # a run of 9 in the last 8 of a channel
        hdr + line + head + full + bytes([0x84, 1, 5]) + bytes(5),  # a literal past its channel's end
        hdr + line + head + bytes([0]),  # a count of 0
        hdr + line + bytes([2, 2, w >> 8, (w + 1) & 255]),  # another width
        hdr + line + bytes([1, 1, 1, 0]) + bytes(4 * w - 4),  # old-style runs
        hdr + line + bytes([2, 2]) + bytes(4 * w - 2),  # a header of width 0
        hdr + line + line[:-1],  # the last byte missing
    ]
    for data in cases:
        assert same(outcome(data), reference_outcome(data)), data[-40:]
    np.testing.assert_array_equal(read_hdr(cases[0]), np.full((2, w, 3), 7 * 2.0**-129, np.float32))
