"""Environment images (renderer/materials/envmap.py): the readers (valid and malformed files, made here),
the limits checked before allocation, the equirect convention and the sampling's pdf."""

from __future__ import annotations

import io

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.scene import Scene, SceneError
from renderer.materials.envmap import EnvironmentMap, image_ref, read_exr, read_hdr, read_image, write_hdr
from renderer.materials.sky import SUN_DIRECTION, sky_texels

RNG = np.random.default_rng(7)
TEXELS = (RNG.random((6, 10, 3)) * 5).astype(np.float32)


def exr_bytes(rgb: np.ndarray, compression=None) -> bytes:
    import OpenEXR

    buf = io.BytesIO()
    header = {"compression": compression or OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": rgb}).write(buf)
    return buf.getvalue()


def rle_hdr(rgbe: np.ndarray) -> bytes:
    """A run-length encoded Radiance file of RGBE bytes (H, W, 4): runs where bytes repeat."""
    h, w = rgbe.shape[:2]
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=2\n\n" + f"-Y {h} +X {w}\n".encode())
    for y in range(h):
        out += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            row = rgbe[y, :, c].tolist()
            x = 0
            while x < w:
                run = 1
                while x + run < w and run < 127 and row[x + run] == row[x]:
                    run += 1
                if run > 2:
                    out += bytes([128 + run, row[x]])
                    x += run
                else:
                    n = min(w - x, 2)
                    out += bytes([n, *row[x : x + n]])
                    x += n
    return bytes(out)


def test_hdr_flat_and_run_length_read_back():
    got = read_hdr(write_hdr(TEXELS))
    np.testing.assert_allclose(got, TEXELS, rtol=0.01, atol=TEXELS.max() / 128)
    rgbe = np.zeros((3, 12, 4), np.uint8)
    rgbe[..., :3] = 128
    rgbe[..., 3] = 129  # 128 · 2^(129 − 136) = 1
    rgbe[1, 4:, 0] = 64  # a run
    got = read_hdr(rle_hdr(rgbe))
    want = np.ones((3, 12, 3)) / 2  # EXPOSURE=2
    want[1, 4:, 0] = 0.25
    np.testing.assert_allclose(got, want)


@pytest.mark.parametrize("half", [True, False])
def test_exr_reads_half_and_float(half):
    import OpenEXR

    rgb = TEXELS.astype(np.float16 if half else np.float32)
    for comp in (OpenEXR.ZIP_COMPRESSION, OpenEXR.NO_COMPRESSION, OpenEXR.PIZ_COMPRESSION):
        np.testing.assert_array_equal(read_exr(exr_bytes(rgb, comp)), rgb.astype(np.float32))


@pytest.mark.parametrize(
    ("data", "fmt", "words"),
    [
        (b"P6 garbage", "hdr", "#?RADIANCE"),
        (b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 2 +X 2\n", "hdr", "32-bit_rle_rgbe"),
        (b"#?RADIANCE\n\n+Y 2 +X 2\n", "hdr", "-Y <height> +X <width>"),
        (b"#?RADIANCE\n\n-Y 2 +X 2\n\x00\x00", "hdr", "ends inside scanline 0"),
        (b"#?RADIANCE\n\n-Y 2 +X 8\n\x02\x02\x00\x08\x89\x00", "hdr", "a run passes"),
        (b"#?RADIANCE\n\n-Y 2 +X 8\n\x02\x02\x00\x09" + b"\x00" * 40, "hdr", "another width"),
        (b"not exr at all", "exr", "magic number"),
        (b"\x76\x2f\x31\x01\x02\x00\x00\x00channels\x00chlist\x00\xff\xff\x00\x00", "exr", "passes the end"),
        (b"anything", "png", "accepted: hdr, exr"),
        (b"", "hdr", "empty body"),
    ],
)
def test_malformed_files_are_refused_by_name(data, fmt, words):
    with pytest.raises(SceneError) as e:
        read_image(data, fmt)
    assert words in e.value.message
    assert e.value.field == ("format" if fmt == "png" else "body")


def test_the_declared_size_is_checked_before_allocation(monkeypatch):
    """A 40-byte header claiming 10^6 × 10^6 texels is refused by its numbers alone (nothing of
    that size is made: a numpy allocation of it would fail with MemoryError, not this)."""
    for data, fmt in (
        (b"#?RADIANCE\n\n-Y 1000000 +X 1000000\n", "hdr"),
        (exr_bytes(np.zeros((2, limits.MAX_ENV_WIDTH + 1, 3), np.float16)), "exr"),
        (write_hdr(np.zeros((1, 4, 3))), "hdr"),
    ):
        with pytest.raises(SceneError) as e:
            read_image(data, fmt)
        assert "accepted: 2–4096 wide, 2–2048 high" in e.value.message


def test_texel_values_are_checked():
    bad = TEXELS.copy()
    bad[2, 3, 1] = np.inf
    with pytest.raises(SceneError, match=r"row 2, column 3"):
        read_exr(exr_bytes(bad))
    bad[2, 3, 1] = -1.0
    with pytest.raises(SceneError, match=r"finite, 0–"):
        read_exr(exr_bytes(bad))


def test_convention_is_mitsubas():
    """u = 0 along −z, u = ¼ along +x, row 0 the zenith; the rotation turns about +y (right hand)."""
    m = EnvironmentMap("t", TEXELS)
    np.testing.assert_allclose(
        m.uv(np.array([[0, 0, -1.0], [1.0, 0, 0], [0, 1.0, 0]])), [[0, 0.5], [0.25, 0.5], [0.5, 0]], atol=1e-12
    )
    turned = EnvironmentMap("t", TEXELS, rotation_deg=90.0)
    # turning by +90° about +y carries what was seen along −z to −x
    np.testing.assert_allclose(turned.radiance(np.array([-1.0, 0, 0])), m.radiance(np.array([0, 0, -1.0])))
    # a texel's own direction gives the texel (column i at u = (i + ½)/W, row j at v = j/(H − 1))
    d = m.direction(np.array([(3 + 0.5) / 10, 2 / 5]))
    np.testing.assert_allclose(m.radiance(d), TEXELS[2, 3], rtol=1e-6)


def test_sampling_pdf_is_a_density_and_matches_the_samples():
    m = EnvironmentMap("t", TEXELS, scale=2.0)
    d = RNG.normal(size=(200_000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    np.testing.assert_allclose((m.pdf(d) * 4 * np.pi).mean(), 1.0, rtol=0.01)
    s = m.sample(RNG.random(200_000), RNG.random(200_000))
    want = (m.radiance(d) * 4 * np.pi).mean(axis=0)  # ∫ L dω by uniform directions
    np.testing.assert_allclose((m.radiance(s) / m.pdf(s)[:, None]).mean(axis=0), want, rtol=0.01)


def test_scene_json_names_the_image():
    images = {image_ref(TEXELS): TEXELS}
    env = {"image": image_ref(TEXELS), "scale": 2.0, "rotation_deg": 15.0}
    scene = Scene.from_json({"materials": [{}], "environment": env}, images=images)
    assert scene.to_json()["environment"] == env
    with pytest.raises(SceneError) as e:
        Scene.from_json({"materials": [{}], "environment": {"image": "image-0000"}})
    assert e.value.field == "environment.image"
    for bad, field in (
        ({"image": "sky", "scale": -1}, "environment.scale"),
        ({"image": "sky", "rotation_deg": 400}, "environment.rotation_deg"),
        ({"scale": 2}, "environment.scale"),
        ({"image": "sky", "color": [1, 1, 1]}, "environment"),
    ):
        with pytest.raises(SceneError) as e:
            Scene.from_json({"materials": [{}], "environment": bad})
        assert e.value.field == field


def test_the_sky_has_its_sun_where_it_says():
    sky = EnvironmentMap("sky", sky_texels())
    sun = sky.radiance(SUN_DIRECTION)
    assert sun.min() > 100 * sky.radiance(np.array([0.0, 1.0, 0.0])).max()
    assert sky_texels().shape == (128, 256, 3) and not sky_texels().flags.writeable


def test_only_a_scene_with_an_image_carries_its_define():
    from renderer.frame.features import scene_features
    from renderer.gpu.gpu_layout import Variant
    from renderer.scenes.scenarios import scenario

    assert "ENVIRONMENT_MAP" in scene_features(scenario(1, 8, sky=True)).defines()
    plain = scene_features(scenario(1, 8)).defines()
    assert not {"ENVIRONMENT_MAP", "ENVIRONMENT"} & set(plain)
    # Whitted reads the image; only the path integrator reads its sampling tables
    whitted = Variant("bih", "color", 3, ("ENVIRONMENT_MAP",))
    path = Variant("bih", "color", 3, ("PATH", "ENVIRONMENT_MAP"))
    assert whitted.reads("environment_map") and not whitted.reads("environment_sampling")
    assert path.reads("environment_map") and path.reads("environment_sampling")
    assert not Variant("bih", "depth", 3, ("ENVIRONMENT_MAP",)).reads("environment_map")


def test_an_exr_with_too_many_channels_is_refused_saying_so():
    rgb = {c: np.zeros((4, 4), np.float16) for c in "RGB"}
    extra = {f"aov{i}": np.zeros((4, 4), np.float16) for i in range(limits.MAX_ENV_CHANNELS - 2)}
    import OpenEXR

    def exr(channels: dict) -> bytes:
        buf = io.BytesIO()
        OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(buf)
        return buf.getvalue()

    with pytest.raises(SceneError) as e:
        read_image(exr({**rgb, **extra}), "exr")
    n = limits.MAX_ENV_CHANNELS + 1
    assert e.value.field == "body"
    assert f"has {n} channels; at most {limits.MAX_ENV_CHANNELS} are accepted" in e.value.message
    extra.pop("aov0")  # at the limit: read
    assert read_image(exr({**rgb, **extra}), "exr").shape == (4, 4, 3)
