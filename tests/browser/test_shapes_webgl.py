"""shaders/shapes.glsl in WebGL2 (headless Chromium, ANGLE on SwiftShader): the text compiles
and links as GLSL ES 3.00 there, and a few rays of the stability cases (tests/renderer/accel/
shapes_cases.py) give the float64 oracle's hits and depths."""

from __future__ import annotations

import numpy as np
import pytest

from tests.renderer.accel.shapes_cases import BY_NAME, DEPTH_REL, reference
from tests.renderer.gl.shapes_gl import VERTEX, fragment_source

SIDE = 8  # 64 rays per case

RUN = """([vs, fs, o, d, v, side]) => {
  const c = document.createElement('canvas');
  c.width = side; c.height = side;
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
  const tex = (unit, data) => {
    const t = gl.createTexture(); gl.activeTexture(gl.TEXTURE0 + unit); gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, side, side, 0, gl.RGBA, gl.FLOAT, new Float32Array(data));
    return t;
  };
  tex(0, o); tex(1, d);
  gl.uniform1i(gl.getUniformLocation(p, 'u_o'), 0); gl.uniform1i(gl.getUniformLocation(p, 'u_d'), 1);
  for (let i = 0; i < 3; i++) gl.uniform4fv(gl.getUniformLocation(p, 'u_v' + i), v.slice(4 * i, 4 * i + 4));
  gl.uniform1f(gl.getUniformLocation(p, 'u_tmax'), 1e30);
  const out = gl.createTexture(); gl.activeTexture(gl.TEXTURE2); gl.bindTexture(gl.TEXTURE_2D, out);
  gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, side, side);
  const fb = gl.createFramebuffer(); gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, out, 0);
  const buf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1,-1, 1,-1, -1,1, -1,1, 1,-1, 1,1]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  gl.viewport(0, 0, side, side); gl.drawArrays(gl.TRIANGLES, 0, 6);
  const px = new Float32Array(side * side * 4);
  gl.readPixels(0, 0, side, side, gl.RGBA, gl.FLOAT, px);
  return {t: Array.from(px).filter((_, i) => i % 4 === 3)};
}"""

CASE_NAMES = ("torus_grazing", "torus_thin_grazing", "torus_hole", "cylinder_grazing", "cone_apex_view", "disk_view")


@pytest.mark.parametrize("name", CASE_NAMES)
def test_shapes_glsl_compiles_in_webgl2_and_meets_the_oracle(webgl_page, name):
    case = BY_NAME[name]
    n = SIDE * SIDE
    t_all = reference(name)[0]
    rng = np.random.default_rng(0)  # half of the rays among the oracle's hits, half among its misses
    idx = np.concatenate(
        [rng.choice(np.flatnonzero(m), n // 2, replace=False) for m in (np.isfinite(t_all), ~np.isfinite(t_all))]
    )
    o = np.concatenate([case.o[idx], np.zeros((n, 1), np.float32)], 1)
    d = np.concatenate([case.d[idx], np.zeros((n, 1), np.float32)], 1)
    res = webgl_page.evaluate(
        RUN,
        [
            VERTEX,
            fragment_source("intersect_shape"),
            o.ravel().tolist(),
            d.ravel().tolist(),
            case.shape.ravel().tolist(),
            SIDE,
        ],
    )
    assert "error" not in res, res.get("error")
    t = np.asarray(res["t"], dtype=np.float64)
    t_ref = t_all[idx]
    hit, ref = t < 1e38, np.isfinite(t_ref)
    assert (hit == ref).all(), name
    np.testing.assert_array_less(np.abs(t[hit] - t_ref[hit]) / t_ref[hit], DEPTH_REL)
