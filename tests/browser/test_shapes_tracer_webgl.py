"""The tracer's variants with analytic shapes (shaders/shapes.glsl and shaders/shapes_tracer.glsl,
chunks compiled where FEATURE_SHAPES is 1, renderer/frame/shader_source.py) compile and link as GLSL ES 3.00 in WebGL2
(headless Chromium, ANGLE on SwiftShader): the text a device would get from GET /api/shader.
(Device frames of such scenes wait for the service to accept the shapes' JSON keys.)"""

from __future__ import annotations

import pytest

from renderer.frame.shader_source import variant_source, vertex_source
from renderer.gpu.gpu_layout import Variant

COMPILE = """([vs, fs]) => {
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) return {error: 'no webgl2'};
  const log = {};
  const sh = (type, src, name) => {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    log[name] = gl.getShaderParameter(s, gl.COMPILE_STATUS) ? '' : (gl.getShaderInfoLog(s) || 'failed');
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, sh(gl.VERTEX_SHADER, vs, 'vertex'));
  gl.attachShader(p, sh(gl.FRAGMENT_SHADER, fs, 'fragment'));
  gl.linkProgram(p);
  log.program = gl.getProgramParameter(p, gl.LINK_STATUS) ? '' : (gl.getProgramInfoLog(p) || 'failed');
  return log;
}"""

VARIANTS = [
    Variant("bih", "color", 3, ("SHAPES",)),
    Variant("bruteforce", "primid", 1, ("EQUAL_RADII", "SHAPES")),
    Variant("kdtree", "color", 4, ("TRIANGLES", "SHAPES", "ENVIRONMENT", "PATH")),
    Variant("twolevel", "normal", 1, ("MATERIAL_TEXTURE", "TRIANGLES", "SMOOTH_TRIANGLES", "SHAPES")),
]


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: f"{v.method}-{v.mode}-{'+'.join(v.features)}")
def test_a_variant_with_shapes_compiles_and_links_in_webgl2(webgl_page, variant):
    fs = variant_source(variant)
    assert "test_shape(" in fs and "//@SHAPES" not in fs
    log = webgl_page.evaluate(COMPILE, [vertex_source(), fs])
    assert log == {"vertex": "", "fragment": "", "program": ""}, log
