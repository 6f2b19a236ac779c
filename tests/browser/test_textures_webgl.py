"""Textures in WebGL2 (headless Chromium, ANGLE on SwiftShader): shaders/pbr_inputs.glsl and
shaders/textures.glsl compile there and give the float64 reference's base colours at a textured
quad's hit points (the harness of tests/renderer/gl/texture_probe.py, its texture array uploaded
level by level as the client does), and the client's own upload (client_web/js/device/device_gl.js,
DeviceRenderer.load) of a device-data blob's texture array holds every layer and mip level the
server packed for the device's MAX_TEXTURE_SIZE."""

from __future__ import annotations

import base64
import dataclasses

import numpy as np
import pytest

from renderer.geometry.scene import Camera, Material, Scene, make_mesh
from renderer.gpu import gpu_layout, texture_layout
from renderer.materials.pbr import PbrMaterial
from renderer.materials.texture import Texture
from renderer.oracle import reference
from server.frames.device_data import encode_blob, surface_info
from tests.renderer.gl.texture_probe import PBR_TEXELS, VERTEX, fragment_source

pytestmark = pytest.mark.browser

PROBE = """([vs, fs, textures, uniforms, width, height, outputs]) => {
  const c = document.createElement('canvas');
  const gl = c.getContext('webgl2');
  if (!gl) return {error: 'no webgl2'};
  if (!gl.getExtension('EXT_color_buffer_float')) return {error: 'no EXT_color_buffer_float'};
  const sh = (type, src) => {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, sh(gl.VERTEX_SHADER, vs)); gl.attachShader(p, sh(gl.FRAGMENT_SHADER, fs));
  gl.bindAttribLocation(p, 0, 'a_position'); gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) return {error: gl.getProgramInfoLog(p)};
  gl.useProgram(p);
  const bytes = (b64) => Uint8Array.from(atob(b64), (ch) => ch.charCodeAt(0));
  textures.forEach((t, unit) => {
    const tex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit);
    if (t.levels) {   // as DeviceRenderer.load: RGBA8 layers, one texImage3D per mip level
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST_MIPMAP_NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, t.levels.length - 1);
      t.levels.forEach((l, i) => gl.texImage3D(gl.TEXTURE_2D_ARRAY, i, gl.RGBA8, l.width, l.height, t.layers, 0,
        gl.RGBA, gl.UNSIGNED_BYTE, bytes(l.data)));
    } else {
      gl.bindTexture(gl.TEXTURE_2D, tex);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      const raw = bytes(t.data);
      if (t.dtype === 'f4') {
        gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, t.width, t.height, 0, gl.RGBA, gl.FLOAT,
          new Float32Array(raw.buffer));
      } else {
        gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32UI, t.width, t.height, 0, gl.RGBA_INTEGER, gl.UNSIGNED_INT,
          new Uint32Array(raw.buffer));
      }
    }
    gl.uniform1i(gl.getUniformLocation(p, t.name), unit);
  });
  gl.uniform1i(gl.getUniformLocation(p, 'u_tri_base'), uniforms.u_tri_base);
  gl.uniform4fv(gl.getUniformLocation(p, 'u_probe_mats'), new Float32Array(uniforms.u_probe_mats));
  gl.activeTexture(gl.TEXTURE0 + textures.length);   // (the targets on a unit no sampler reads)
  const fb = gl.createFramebuffer(); gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  const bufs = [];
  for (let i = 0; i < outputs; i++) {
    const out = gl.createTexture(); gl.bindTexture(gl.TEXTURE_2D, out);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, width, height);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, out, 0);
    bufs.push(gl.COLOR_ATTACHMENT0 + i);
  }
  gl.drawBuffers(bufs);
  const buf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1,-1, 1,-1, -1,1, -1,1, 1,-1, 1,1]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  gl.viewport(0, 0, width, height); gl.drawArrays(gl.TRIANGLES, 0, 6);
  const res = [];
  for (let i = 0; i < outputs; i++) {
    gl.readBuffer(gl.COLOR_ATTACHMENT0 + i);
    const px = new Float32Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.FLOAT, px);
    res.push(Array.from(px));
  }
  return {outputs: res, error_code: gl.getError()};
}"""

READ_BACK = """async ([blob64]) => {
  const { DeviceRenderer, parseDeviceData } = await import('/js/device/device.js');
  const raw = Uint8Array.from(atob(blob64), (ch) => ch.charCodeAt(0));
  const parsed = parseDeviceData(raw.buffer);
  const r = new DeviceRenderer();
  r.load(parsed);
  const gl = r.gl;
  const entry = r.textures.find((t) => t.name === 'u_textures');
  const meta = parsed.textures.find((t) => t.name === 'u_textures');
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb);
  const levels = meta.levels.map((l, level) => {
    const layers = [];
    for (let k = 0; k < meta.layers; k++) {
      gl.framebufferTextureLayer(gl.READ_FRAMEBUFFER, gl.COLOR_ATTACHMENT0, entry.tex, level, k);
      const px = new Uint8Array(l.width * l.height * 4);
      gl.readPixels(0, 0, l.width, l.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
      layers.push(btoa(String.fromCharCode(...px)));
    }
    return layers;
  });
  gl.bindFramebuffer(gl.READ_FRAMEBUFFER, null);
  gl.deleteFramebuffer(fb);
  return {levels, target_is_array: entry.target === gl.TEXTURE_2D_ARRAY,
          max_layers: r.maxArrayTextureLayers, max_size: r.maxTextureSize, error_code: gl.getError()};
}"""

QUAD = ([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], [[0, 3, 2], [0, 2, 1]])
CAM = Camera((0.0, 3.0, 0.01), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)


def _scene(textures, **material) -> Scene:
    quad = make_mesh(*QUAD, uvs=[[-0.5, -0.5], [2.5, -0.5], [2.5, 2.5], [-0.5, 2.5]])
    mat = PbrMaterial(base_color_texture=0, **material)
    return Scene(
        CAM, (), (mat,), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), meshes=(quad,), textures=tuple(textures)
    )


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


@pytest.mark.parametrize("filter_, level", [("nearest", 0.0), ("linear", 0.0), ("linear", 1.6)])
def test_pbr_inputs_in_webgl2_gives_the_references_texels(webgl_page, filter_, level):
    """An sRGB texture repeated and mirrored over a quad: WebGL2's base colour at the reference's hits
    equals the float64 lookup (nearest away from texel edges; bilinear and a fractional level everywhere)."""
    rng = np.random.default_rng(5)
    tex = Texture(rng.integers(0, 256, (8, 8, 4), dtype=np.uint8), srgb=True, filter=filter_, wrap_t="mirror")
    scene = _scene([tex])
    o, d = reference.primary_rays(CAM, 24, 24)
    t, ids = reference.trace_rays(dataclasses.replace(scene, materials=(Material(),)), o, d)
    hit = ids >= 0
    p, prim = o[hit] + t[hit, None] * d[hit], ids[hit]
    tri = prim - scene.triangle_id_base
    uv = reference.hit_texcoords(scene, tri, reference.triangle_barycentrics(scene, tri, p))
    # The footprint whose level is `level` on this quad (Δ = ½·log2(9/4) for UVs 3 wide over 2 world units).
    lod = 0.5 * np.log2(9.0 / 4.0)
    footprint = np.exp2(level - lod - 0.5 * np.log2(64.0)) if level > 0 else 0.0
    expected = reference.texture_sample(texture_layout.mip_chain(tex.pixels, True), tex, uv, level)
    n = len(p)
    width, height = 32, -(-n // 32)

    def grid(cols: np.ndarray) -> str:
        out = np.zeros((width * height, 4), np.float32)
        out[:n] = cols
        return _b64(out)

    point = grid(np.concatenate([p, prim[:, None]], axis=1))
    normal = grid(np.concatenate([np.tile([0.0, 1.0, 0.0], (n, 1)), np.full((n, 1), footprint)], axis=1))
    surface = texture_layout.pack_surface_data(scene)
    packed = {
        gpu_layout.TRIANGLES.name: gpu_layout.wrap_rows(gpu_layout.triangle_records(scene)),
        **surface.packed.textures,
    }
    textures = []
    for name, tx in packed.items():
        if isinstance(tx, gpu_layout.PackedTextureArray):
            levels = [{"width": lv.shape[2], "height": lv.shape[1], "data": _b64(lv)} for lv in tx.levels]
            textures.append({"name": name, "layers": tx.layers, "levels": levels})
        else:
            w, h = tx.size
            textures.append({"name": name, "width": w, "height": h, "dtype": "u4", "data": _b64(tx.data)})
    textures += [
        {"name": "u_probe_point", "width": width, "height": height, "dtype": "f4", "data": point},
        {"name": "u_probe_normal", "width": width, "height": height, "dtype": "f4", "data": normal},
    ]
    from renderer.materials import pack_records

    mats = np.zeros((PBR_TEXELS * 4, 4), np.float32)
    mats[:PBR_TEXELS] = pack_records(scene.materials, PbrMaterial)
    uniforms = {"u_tri_base": scene.triangle_id_base, "u_probe_mats": mats.ravel().tolist()}
    res = webgl_page.evaluate(PROBE, [VERTEX, fragment_source(False, False), textures, uniforms, width, height, 5])
    assert "error" not in res, res.get("error")
    assert res["error_code"] == 0
    base = np.asarray(res["outputs"][0], dtype=np.float64).reshape(-1, 4)[:n]
    if filter_ == "nearest":
        f = uv * 8.0
        frac = f - np.floor(f)
        keep = ((frac > 0.02) & (frac < 0.98)).all(axis=1)
        assert keep.mean() > 0.8
        np.testing.assert_allclose(base[keep], expected[keep], atol=2e-6)
    else:
        np.testing.assert_allclose(base, expected, atol=2e-3)


def test_the_client_uploads_every_layer_and_level_resized_to_the_devices_size(device_page):
    """A blob packed for a device whose MAX_TEXTURE_SIZE is 16 (a 40 × 24 texture halved to 10 × 6, a
    notice saying so) and loaded by DeviceRenderer.load: a TEXTURE_2D_ARRAY whose every layer of every
    mip level reads back as the server packed it; the device reports its layer limit (sent as
    max_array_texture_layers)."""
    rng = np.random.default_rng(6)
    big = Texture(rng.integers(0, 256, (24, 40, 4), dtype=np.uint8), srgb=True, name="big.png")
    small = Texture(rng.integers(0, 256, (3, 5, 4), dtype=np.uint8))
    scene = _scene([big, small])
    surface = texture_layout.pack_surface_data(scene, 16)
    info = surface_info(surface)
    assert info["notices"] == [
        "textures[0] (big.png) 40 × 24 resized to 10 × 6 for the device's largest texture side, 16"
    ]
    array = surface.packed.textures["u_textures"]
    assert isinstance(array, gpu_layout.PackedTextureArray) and array.size == (16, 16) and array.layers == 2
    assert info["texture_bytes"] == texture_layout.texture_array_bytes(16, 16, 2) == array.nbytes
    blob = encode_blob({"uniforms": {}}, surface.packed.textures)
    res = device_page.page.evaluate(READ_BACK, [base64.b64encode(blob).decode("ascii")])
    assert res["error_code"] == 0 and res["target_is_array"]
    assert res["max_layers"] >= texture_layout.WEBGL2_MAX_ARRAY_LAYERS and res["max_size"] >= 2048
    assert len(res["levels"]) == len(array.levels) == 5
    for level, layers in zip(array.levels, res["levels"], strict=True):
        for k, b64 in enumerate(layers):
            got = np.frombuffer(base64.b64decode(b64), np.uint8).reshape(level.shape[1:])
            np.testing.assert_array_equal(got, level[k])
