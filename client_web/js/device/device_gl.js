// The device's WebGL2 tracer: the server's fragment shader, textures and uniforms, drawn
// in bands of rows so that the main thread (touch input) waits at most one band.
//
// A frame is these passes, as renderer/gl/frame.py does it on the server:
//  1. trace: raytrace.frag into two RGBA32F targets (location 0: rgb + primary id,
//     location 1: normal + t), in bands: a scissor rectangle of rows per draw, each waited
//     for with a one-pixel read-back (a true sync point). At k × k samples per pixel
//     (k = √samples_per_pixel > 1) first the pixel centres (W × H: the ids, normals and
//     t of every mode, docs/FORMATS.md), then the k·W × k·H grid of sub-pixels;
//  2. resolve: W × H, two RGBA32F targets: the box filter of the k×k sub-pixels' colour,
//     and the id, normal and t of the pixel centres;
//  3. display: location 0 of the resolve, clamped to [0, 1], onto this.canvas.
// readback() returns the resolve targets as the server's npy arrays.
//
// The path integrator (a PATH variant, integrator=path) instead traces passes of W × H, each
// u_sample_count samples of every pixel from u_sample_start on (the shader's o_image.rgb is
// their SUM), in bands as above; after each pass an accumulate draw adds it to a float sum
// (ping-pong between two RGBA32F targets: blending into float targets needs EXT_float_blend,
// which phones often lack), which keeps the first pass's id, normal and t. The resolve divides
// the sum by the samples traced (the mean, as renderer/gl/frame.py's float64 sum / count), and
// the display scales it by 2^exposure, tone-maps and sRGB-encodes it exactly as
// renderer/image/tonemap.py's display_u8 does (DISPLAY_FS: the tone map's one GLSL copy).
// A variant with GUIDES (a denoiser named) also writes the sums of the first hit's albedo and
// normal (locations 2 and 3): the trace, sum and resolve targets then have four attachments, and
// before the display the edge-avoiding à-trous filter (ATROUS_FS, renderer/image/atrous.py's GLSL copy,
// its parameters from the data's header) runs its passes on the mean, guided by their means.
// continueTrace adds passes to a path-traced frame already shown (the sum kept: the device's
// accumulation while the view rests).
//
// Texture formats: the blob's (dtype, components) → RGBA32F/FLOAT, R32UI/RED_INTEGER, …,
// NEAREST filtering, as server/frames/device_data.py documents.

export class DeviceUnavailable extends Error {}

// Test/URL flag: ?webgl2=0 makes the probe behave as if getContext('webgl2') returned null.
function simulatedNoWebGL2() {
  try {
    return new URLSearchParams(location.search).get('webgl2') === '0';
  } catch {
    return false;
  }
}

const QUAD_VS = `#version 300 es
in vec2 a_position;
void main() { gl_Position = vec4(a_position, 0.0, 1.0); }`;

// A fragment shader's text with its switch GUIDES after the version line: 1 in the guides' variant,
// else 0 (the shader tests it with #if, as the server's shaders test their switches: always defined).
function withGuides(src, on) {
  return src.replace('#version 300 es\n', `#version 300 es\n#define GUIDES ${on ? 1 : 0}\n`);
}

// Up to 4 × 4 sub-pixels (16 samples per pixel, the server's largest). GUIDES (paths only): the
// albedo and normal sums divided by the samples too.
const RESOLVE_FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform highp sampler2D u_trace0;
uniform highp sampler2D u_trace1;
uniform highp sampler2D u_centre0;   // the pixel-centre pass (k > 1; else the trace itself)
uniform highp sampler2D u_centre1;
uniform int u_k;
uniform float u_scale;               // 1 / (k·k); the path integrator's: 1 / samples traced
layout(location = 0) out vec4 o_image;
layout(location = 1) out vec4 o_hit;
#if GUIDES
uniform highp sampler2D u_trace2;
uniform highp sampler2D u_trace3;
layout(location = 2) out vec4 o_albedo;
layout(location = 3) out vec4 o_normal;
#endif
void main() {
  ivec2 base = ivec2(gl_FragCoord.xy) * u_k;
  vec3 sum = vec3(0.0);
  for (int j = 0; j < 4; j++) {
    if (j >= u_k) break;
    for (int i = 0; i < 4; i++) {
      if (i >= u_k) break;
      sum += texelFetch(u_trace0, base + ivec2(i, j), 0).rgb;
    }
  }
  ivec2 c = ivec2(gl_FragCoord.xy);
  o_image = vec4(sum * u_scale, texelFetch(u_centre0, c, 0).a);
  o_hit = texelFetch(u_centre1, c, 0);
#if GUIDES
  o_albedo = vec4(texelFetch(u_trace2, c, 0).rgb * u_scale, 0.0);
  o_normal = vec4(texelFetch(u_trace3, c, 0).rgb * u_scale, 0.0);
#endif
}`;

// The path integrator's sum: this pass's samples added to the sum so far (u_first: the first
// pass, whose id, normal and t the frame keeps, as the server keeps its first pass's). GUIDES: the
// albedo and normal sums are added up as the radiance.
const ACCUMULATE_FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform highp sampler2D u_pass0;
uniform highp sampler2D u_pass1;
uniform highp sampler2D u_sum0;
uniform highp sampler2D u_sum1;
uniform int u_first;
layout(location = 0) out vec4 o_image;
layout(location = 1) out vec4 o_hit;
#if GUIDES
uniform highp sampler2D u_pass2;
uniform highp sampler2D u_pass3;
uniform highp sampler2D u_sum2;
uniform highp sampler2D u_sum3;
layout(location = 2) out vec4 o_albedo;
layout(location = 3) out vec4 o_normal;
#endif
void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  vec4 p = texelFetch(u_pass0, c, 0);
#if GUIDES
  o_albedo = texelFetch(u_pass2, c, 0);
  o_normal = texelFetch(u_pass3, c, 0);
  if (u_first == 0) {
    o_albedo += texelFetch(u_sum2, c, 0);
    o_normal += texelFetch(u_sum3, c, 0);
  }
#endif
  if (u_first == 1) {
    o_image = p;
    o_hit = texelFetch(u_pass1, c, 0);
  } else {
    vec4 s = texelFetch(u_sum0, c, 0);
    o_image = vec4(s.rgb + p.rgb, s.a);
    o_hit = texelFetch(u_sum1, c, 0);
  }
}`;

// renderer/image/atrous.py's filter. ATROUS_PRE_FS demodulates the resolved mean by the albedo guide (at
// least u_albedo_floor) and measures each pixel's compressed luminance over the alike pixels around
// it (weight exp(−|Δn|²/σ_n² − |Δa|²/σ_a²), itself left out, about its own value): the variance, the
// least of the four 3 × 3 quadrants meeting at it, and a firefly scaled down to μ + k·√v of the whole
// 5 × 5: → (lighting, variance). ATROUS_FS is one pass (step u_step): the 5 × 5 B3-spline kernel with
// holes, each tap weighted by exp(−|Δn|²/σ_n² − |Δa|²/σ_a² − |l_p−l_q| / (σ_l·√v_p)) (σ_l narrowed
// past noise_samples samples), taps outside the image left out, Σ w·d / Σ w and the variance
// Σ w²·v / (Σ w)²; the last pass multiplies the albedo back. The σ's (1/σ² and 1/σ_l here), the
// kernel and the floors come from the data's header (path.atrous): declared once.
const ATROUS_COMMON = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform highp sampler2D u_albedo;
uniform highp sampler2D u_normal;
uniform float u_inv_normal;
uniform float u_inv_albedo;
uniform float u_albedo_floor;
uniform vec3 u_luminance;
layout(location = 0) out vec4 o_color;
float compressed_luminance(vec3 d) {
  float y = dot(max(d, vec3(0.0)), u_luminance);
  return y / (1.0 + y);
}
float guide_distance(ivec2 p, ivec2 q) {
  vec3 dn = texelFetch(u_normal, q, 0).rgb - texelFetch(u_normal, p, 0).rgb;
  vec3 da = texelFetch(u_albedo, q, 0).rgb - texelFetch(u_albedo, p, 0).rgb;
  return dot(dn, dn) * u_inv_normal + dot(da, da) * u_inv_albedo;
}
vec3 demodulated(sampler2D color, ivec2 q) {
  return texelFetch(color, q, 0).rgb / max(texelFetch(u_albedo, q, 0).rgb, vec3(u_albedo_floor));
}
`;
const ATROUS_PRE_FS = `${ATROUS_COMMON}
uniform highp sampler2D u_color;
uniform float u_firefly_sigmas;
uniform float u_quadrant_pixels;
float moments_variance(vec3 m) {
  if (m.x <= 0.0) return 0.0;
  float n = max(m.x, 1e-30), mean = m.y / n;
  return max(m.z / n - mean * mean, 0.0);
}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 size = textureSize(u_color, 0);
  vec3 d = demodulated(u_color, p);
  float lp = compressed_luminance(d);
  // (Σw, Σw·l, Σw·l²) of the 3 × 3 quadrants meeting at p (bit 1: dx ≥ 0, bit 2: dy ≥ 0), and their
  // pixels inside the image
  vec3 quadrant[4];
  float inside[4];
  for (int k = 0; k < 4; k++) { quadrant[k] = vec3(0.0); inside[k] = 0.0; }
  vec3 every = vec3(0.0);
  for (int dy = -2; dy <= 2; dy++) {
    for (int dx = -2; dx <= 2; dx++) {
      ivec2 q = p + ivec2(dx, dy);
      if ((dx == 0 && dy == 0) || q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) continue;
      float w = exp(-guide_distance(p, q));
      float l = compressed_luminance(demodulated(u_color, q)) - lp;
      vec3 term = vec3(w, w * l, w * l * l);
      for (int k = 0; k < 4; k++) {
        if (dy * ((k & 2) != 0 ? 1 : -1) >= 0 && dx * ((k & 1) != 0 ? 1 : -1) >= 0) {
          quadrant[k] += term;
          inside[k] += 1.0;
        }
      }
      every += term;
    }
  }
  // (a quadrant the border cuts to fewer than u_quadrant_pixels pixels is no candidate; with none,
  // the whole neighbourhood's)
  float variance = -1.0;
  for (int k = 0; k < 4; k++) {
    if (inside[k] >= u_quadrant_pixels) {
      float v = moments_variance(quadrant[k]);
      variance = variance < 0.0 ? v : min(variance, v);
    }
  }
  if (variance < 0.0) variance = moments_variance(every);
  float offset = every.x > 0.0 ? every.y / max(every.x, 1e-30) : 0.0;
  float top = min(lp + offset + u_firefly_sigmas * sqrt(moments_variance(every)), 0.999);
  if (lp > top) d *= (top / (1.0 - top)) / max(lp / (1.0 - lp), 1e-30);
  o_color = vec4(d, variance);
}`;
const ATROUS_FS = `${ATROUS_COMMON}
uniform highp sampler2D u_lighting;
uniform int u_step;
uniform int u_last;
uniform float u_inv_luminance;
uniform float u_sqrt_variance_floor;
uniform float u_kernel[5];
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 size = textureSize(u_lighting, 0);
  vec4 dp = texelFetch(u_lighting, p, 0);
  float lp = compressed_luminance(dp.rgb);
  float scale = u_inv_luminance / (sqrt(dp.a) + u_sqrt_variance_floor);
  vec3 total = vec3(0.0);
  float weights = 0.0, variance = 0.0;
  for (int j = 0; j < 5; j++) {
    for (int i = 0; i < 5; i++) {
      ivec2 q = p + ivec2(i - 2, j - 2) * u_step;
      if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) continue;
      vec4 dq = texelFetch(u_lighting, q, 0);
      float e = guide_distance(p, q) + abs(compressed_luminance(dq.rgb) - lp) * scale;
      float w = u_kernel[j] * u_kernel[i] * exp(-e);
      total += w * dq.rgb;
      weights += w;
      variance += w * w * dq.a;
    }
  }
  vec3 d = total / weights;
  if (u_last == 1) {
    o_color = vec4(d * max(texelFetch(u_albedo, p, 0).rgb, vec3(u_albedo_floor)), 1.0);
  } else {
    o_color = vec4(d, variance / (weights * weights));
  }
}`;

// renderer/image/tonemap.py's operators by name → u_tone_map (the display's branch).
export const TONE_MAPS = Object.freeze({ clamp: 0, reinhard: 1, aces: 2 });

// Whitted's image is display values already: clamped. The path integrator's mean radiance is
// renderer/image/tonemap.py's display_u8: max(L, 0) · 2^exposure, the operator, clamp to [0, 1], the
// sRGB transfer function, then floor(255·c + 0.5) / 255 (the canvas stores k / 255 as k exactly).
const DISPLAY_FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform highp sampler2D u_image;
uniform int u_path;
uniform int u_tone_map;
uniform float u_exposure_scale;
out vec4 o_color;
vec3 tone_map(vec3 x) {
  if (u_tone_map == 1) return x / (1.0 + x);
  if (u_tone_map == 2) return (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
  return x;
}
vec3 srgb_encode(vec3 c) {
  vec3 curve = 1.055 * pow(max(c, vec3(0.0031308)), vec3(1.0 / 2.4)) - 0.055;
  return mix(curve, 12.92 * c, lessThanEqual(c, vec3(0.0031308)));
}
void main() {
  vec3 v = texelFetch(u_image, ivec2(gl_FragCoord.xy), 0).rgb;
  if (u_path == 1) {
    vec3 c = clamp(tone_map(max(v, vec3(0.0)) * u_exposure_scale), 0.0, 1.0);
    o_color = vec4(floor(srgb_encode(c) * 255.0 + 0.5) / 255.0, 1.0);
  } else {
    o_color = vec4(clamp(v, 0.0, 1.0), 1.0);
  }
}`;

export class DeviceRenderer {
  // Throws DeviceUnavailable (with a message for the notice) when this browser cannot run the tracer.
  constructor() {
    this.canvas = document.createElement('canvas');
    this.canvas.width = 1;
    this.canvas.height = 1;
    const gl = simulatedNoWebGL2() ? null : this.canvas.getContext('webgl2', {
      preserveDrawingBuffer: true, antialias: false, depth: false, stencil: false, alpha: false,
      powerPreference: 'high-performance',
    });
    if (!gl) throw new DeviceUnavailable('this browser offers no WebGL2');
    this.gl = gl;
    this.colorBufferFloat = !!gl.getExtension('EXT_color_buffer_float');
    if (!this.colorBufferFloat) {
      throw new DeviceUnavailable('WebGL2 here cannot render to 32-bit float textures (EXT_color_buffer_float)');
    }
    const dbg = gl.getExtension('WEBGL_debug_renderer_info');
    this.rendererName = String(gl.getParameter(dbg ? dbg.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    this.maxTextureSize = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    this.maxArrayTextureLayers = gl.getParameter(gl.MAX_ARRAY_TEXTURE_LAYERS);
    this.lost = false;
    this.canvas.addEventListener('webglcontextlost', (e) => { e.preventDefault(); this.lost = true; });
    this.programs = new Map();     // sources → {program, uniforms, logs}
    this.textures = [];            // [{name, tex}]
    this.header = null;
    this.targets = new Map();      // 'WxH' → {width, height, fbo, tex: [t0, t1]} (trace and resolve sizes)
    this.sync = new Float32Array(4);
    const quad = new Float32Array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1]);
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, quad, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
    this.resolveProgram = this.program(QUAD_VS, withGuides(RESOLVE_FS, false));
    this.displayProgram = this.program(QUAD_VS, DISPLAY_FS);
    this.accumulateProgram = this.program(QUAD_VS, withGuides(ACCUMULATE_FS, false));
    this.sumOwner = null;          // the path-traced trace whose sum the 'sum0'/'sum1' targets hold
  }

  get info() {
    return { renderer: this.rendererName, maxTextureSize: this.maxTextureSize, colorBufferFloat: this.colorBufferFloat };
  }

  // Compile and link (cached by source). → {program, uniforms: name → {loc, type, size}, logs}
  program(vsSrc, fsSrc) {
    const key = vsSrc + '\u0000' + fsSrc;
    if (this.programs.has(key)) return this.programs.get(key);
    const gl = this.gl;
    const shader = (type, src) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      return s;
    };
    const vs = shader(gl.VERTEX_SHADER, vsSrc), fs = shader(gl.FRAGMENT_SHADER, fsSrc);
    const p = gl.createProgram();
    gl.attachShader(p, vs);
    gl.attachShader(p, fs);
    gl.bindAttribLocation(p, 0, 'a_position');
    gl.linkProgram(p);
    const logs = {
      vertex: gl.getShaderInfoLog(vs) || '', fragment: gl.getShaderInfoLog(fs) || '', program: gl.getProgramInfoLog(p) || '',
    };
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) {
      const why = logs.fragment || logs.vertex || logs.program || 'unknown reason';
      throw new DeviceUnavailable(`the tracer's shader does not compile on this device: ${why.slice(0, 300)}`);
    }
    const uniforms = new Map();
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const u = gl.getActiveUniform(p, i);
      uniforms.set(u.name.replace(/\[0\]$/, ''), { loc: gl.getUniformLocation(p, u.name), type: u.type, size: u.size });
    }
    const entry = { program: p, uniforms, logs };
    this.programs.set(key, entry);
    return entry;
  }

  // Upload a parsed blob's textures (replacing the previous ones) and keep its uniforms.
  load(parsed) {
    const gl = this.gl;
    for (const t of this.textures) gl.deleteTexture(t.tex);
    this.textures = [];
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    for (const t of parsed.textures) {
      if (t.levels) {   // the scene's textures: RGBA8 layers with their mip levels, read by texelFetch
        const tex = gl.createTexture();
        gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
        gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, t.levels.length > 1 ? gl.NEAREST_MIPMAP_NEAREST : gl.NEAREST);
        gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
        gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, t.levels.length - 1);
        t.levels.forEach((l, i) => gl.texImage3D(
          gl.TEXTURE_2D_ARRAY, i, gl.RGBA8, l.width, l.height, t.layers, 0, gl.RGBA, gl.UNSIGNED_BYTE, l.data));
        gl.bindTexture(gl.TEXTURE_2D_ARRAY, null);
        this.textures.push({ name: t.name, tex, target: gl.TEXTURE_2D_ARRAY });
        continue;
      }
      const fmt = textureFormat(gl, t.dtype, t.components);
      const tex = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, tex);
      nearest(gl);
      gl.texImage2D(gl.TEXTURE_2D, 0, fmt.internal, t.width, t.height, 0, fmt.format, fmt.type, t.data);
      this.textures.push({ name: t.name, tex, target: gl.TEXTURE_2D });
    }
    gl.bindTexture(gl.TEXTURE_2D, null);
    this.header = parsed.header;
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new DeviceUnavailable(`texture upload failed (GL error 0x${err.toString(16)})`);
  }

  // `n` RGBA32F targets (1, 2 or 4: with the guides) of width × height for `role` ('trace',
  // 'resolve', …: never the same textures, even at one sample per pixel, since the resolve reads
  // the trace's), cached.
  _targets(width, height, role = 'trace', n = 2) {
    const gl = this.gl, key = `${role}:${n}:${width}x${height}`;
    if (this.targets.has(key)) return this.targets.get(key);
    if (this.targets.size >= 24) {   // bound the cache (roles × the full and preview sizes): release the oldest
      const [oldKey, old] = this.targets.entries().next().value;
      gl.deleteFramebuffer(old.fbo);
      old.tex.forEach((t) => gl.deleteTexture(t));
      this.targets.delete(oldKey);
    }
    const fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    const tex = [...Array(n).keys()].map((i) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      nearest(gl);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, width, height);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0);
      return t;
    });
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.drawBuffers(tex.map((_, i) => gl.COLOR_ATTACHMENT0 + i));
    const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
    if (status !== gl.FRAMEBUFFER_COMPLETE) {
      throw new DeviceUnavailable(`${n} RGBA32F render targets are not supported here (0x${status.toString(16)})`);
    }
    const entry = { width, height, fbo, tex };
    this.targets.set(key, entry);
    return entry;
  }

  _check() {
    if (this.lost || this.gl.isContextLost()) throw new DeviceUnavailable('the WebGL2 context was lost');
  }

  // A frame of width × height at k × k sub-pixels per pixel, to be traced band by band.
  // uniforms: the camera's and the per-frame ones (u_min_weight), on top of the data's.
  // At k > 1 the pixel centres are a phase of their own, traced first (W × H, their camera).
  // path ({samples, perPass, guides}: a PATH variant, guides: it has GUIDES): phases of W × H of
  // at most perPass samples each, summed (k is 1). display: {toneMap, exposure, atrous}, how a
  // path-traced frame is shown (atrous: the filter's parameters, the data's path.atrous, or null).
  beginTrace(prog, { width, height, k = 1, uniforms, path = null, display = null }) {
    this._check();
    const n = path && path.guides ? 4 : 2;   // attachments of the trace, sum and resolve targets
    let phases = [];
    if (path) {
      phases = this._passes(0, path.samples, path.perPass, width, height, uniforms);
      k = 1;
    } else {
      if (k > 1) phases.push({ role: 'centre', tw: width, th: height, uniforms: { ...uniforms, u_resolution: [width, height] } });
      phases.push({ role: 'trace', tw: width * k, th: height * k, uniforms });
    }
    phases.forEach((p) => this._targets(p.tw, p.th, p.role, n));
    const trace = {
      prog, width, height, k, phases, phase: 0, rowsDone: 0, rowsDoneTotal: 0, bands: 0, traceMs: 0, n,
      path: !!path, display: display || { toneMap: 'clamp', exposure: 0 }, sum: null, samplesDone: 0,
      samplesAtStart: 0, perPass: path ? path.perPass : 0, uniforms,
      rowsTotal: phases.reduce((n, p) => n + p.th, 0),
      get tw() { return this.phases[Math.min(this.phase, this.phases.length - 1)].tw; },
      get th() { return this.phases[Math.min(this.phase, this.phases.length - 1)].th; },
      get done() { return this.phase >= this.phases.length; },
    };
    return trace;
  }

  // Passes of `count` samples from sample `start` on, at most perPass each (W × H each).
  _passes(start, count, perPass, width, height, uniforms) {
    const phases = [];
    for (let s = start; s < start + count; s += perPass) {
      const c = Math.min(perPass, start + count - s);
      phases.push({ role: 'trace', tw: width, th: height, samples: [s, c],
        uniforms: { ...uniforms, u_sample_start: s, u_sample_count: c } });
    }
    return phases;
  }

  // `samples` more of a path-traced frame (its sum kept, the next sample indices: what one frame of
  // all of them traces), band by band again. → the trace, or null when its sum is gone (another
  // path-traced frame summed into the targets since): trace a new frame then.
  continueTrace(trace, samples) {
    this._check();
    if (!trace.path || this.sumOwner !== trace || trace.samplesDone === 0) return null;
    trace.phases = this._passes(trace.samplesDone, samples, trace.perPass, trace.width, trace.height, trace.uniforms);
    Object.assign(trace, { phase: 0, rowsDone: 0, rowsDoneTotal: 0, bands: 0, traceMs: 0,
      samplesAtStart: trace.samplesDone, rowsTotal: trace.phases.length * trace.height });
    return trace;
  }

  // The path integrator: add the pass just traced to the frame's sum (ping-pong 'sum0'/'sum1').
  _accumulate(trace, phase) {
    const gl = this.gl;
    const first = trace.sum === null, n = trace.n;
    const dstRole = trace.sum === 'sum0' ? 'sum1' : 'sum0', srcRole = dstRole === 'sum0' ? 'sum1' : 'sum0';
    const pass = this._targets(trace.width, trace.height, 'trace', n);
    const src = this._targets(trace.width, trace.height, srcRole, n);
    const dst = this._targets(trace.width, trace.height, dstRole, n);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fbo);
    gl.viewport(0, 0, trace.width, trace.height);
    const a = n === 4 ? this.program(QUAD_VS, withGuides(ACCUMULATE_FS, true)) : this.accumulateProgram;
    gl.useProgram(a.program);
    const units = [...pass.tex.map((t, i) => [`u_pass${i}`, t]), ...src.tex.map((t, i) => [`u_sum${i}`, t])];
    this._bindUnits(a, units);
    gl.uniform1i(a.uniforms.get('u_first').loc, first ? 1 : 0);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    this._unbindUnits(units.length);
    gl.bindVertexArray(null);
    trace.sum = dstRole;
    this.sumOwner = trace;
    trace.samplesDone += phase.samples[1];
  }

  // [[sampler name, texture], …] on units 0, 1, … of `prog` (a name it lacks is skipped).
  _bindUnits(prog, units) {
    const gl = this.gl;
    units.forEach(([name, t], i) => {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(gl.TEXTURE_2D, t);
      const u = prog.uniforms.get(name);
      if (u) gl.uniform1i(u.loc, i);
    });
  }

  _unbindUnits(count) {
    const gl = this.gl;
    for (let i = 0; i < count; i++) {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(gl.TEXTURE_2D, null);
    }
  }

  // Bind the tracer, its textures and uniforms (every band: other passes change the state between).
  _bindTrace(trace) {
    const gl = this.gl, prog = trace.prog, phase = trace.phases[trace.phase];
    gl.bindFramebuffer(gl.FRAMEBUFFER, this._targets(trace.tw, trace.th, phase.role, trace.n).fbo);
    gl.viewport(0, 0, trace.tw, trace.th);
    gl.useProgram(prog.program);
    // Textures: one unit each; samplers the data does not fill get a 1×1 dummy of their kind.
    let unit = 0;
    const bound = new Set();
    for (const t of this.textures) {
      const u = prog.uniforms.get(t.name);
      if (!u) continue;
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(t.target, t.tex);
      gl.uniform1i(u.loc, unit++);
      bound.add(t.name);
    }
    for (const [name, u] of prog.uniforms) {
      if (bound.has(name) || !isSampler(gl, u.type)) continue;
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, this._dummy(u.type));
      gl.uniform1i(u.loc, unit++);
    }
    const values = { ...this.header.uniforms, ...phase.uniforms };
    for (const [name, value] of Object.entries(values)) {
      const u = prog.uniforms.get(name);
      if (u && !isSampler(gl, u.type)) setUniform(gl, u, value);
    }
    gl.bindVertexArray(this.vao);
  }

  // Trace the next `rows` rows (from the top) and wait for them. → ms the band took.
  traceBand(trace, rows) {
    this._check();
    const gl = this.gl;
    rows = Math.max(1, Math.min(rows, trace.th - trace.rowsDone));
    const t0 = performance.now();
    this._bindTrace(trace);
    const y0 = trace.th - trace.rowsDone - rows;     // GL row 0 is the bottom
    gl.enable(gl.SCISSOR_TEST);
    gl.scissor(0, y0, trace.tw, rows);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    gl.disable(gl.SCISSOR_TEST);
    // A one-pixel read-back inside the band: returns once the band is traced (finish() may not wait).
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.readPixels(0, y0, 1, 1, gl.RGBA, gl.FLOAT, this.sync);
    gl.bindVertexArray(null);
    const ms = performance.now() - t0;
    trace.rowsDone += rows;
    trace.rowsDoneTotal += rows;
    trace.bands++;
    trace.traceMs += ms;
    if (trace.rowsDone >= trace.th) {   // this phase is traced: the next one starts at its top
      const phase = trace.phases[trace.phase];
      if (phase.samples) this._accumulate(trace, phase);
      trace.phase++;
      trace.rowsDone = 0;
    }
    return ms;
  }

  // All bands traced: resolve the sub-pixels (or the paths' sum), filter (the path integrator's mean,
  // with a denoiser) and show the frame on this.canvas. → ms.
  finishTrace(trace) {
    this._check();
    const t0 = performance.now();
    this._resolve(trace);
    const filtered = this._filter(trace);
    this._display(trace, filtered ?? this._targets(trace.width, trace.height, 'resolve', trace.n).tex[0], trace.path);
    this.last = { width: trace.width, height: trace.height, path: trace.path, n: trace.n, filtered };
    return performance.now() - t0;
  }

  // The à-trous filter on the resolved mean, guided by the resolved albedo and normal: its first
  // pass (demodulation, variance, fireflies) then its wavelet passes (ping-pong 'atrous0'/'atrous1').
  // → the filtered texture, or null (no guides or no filter).
  _filter(trace) {
    const f = trace.display.atrous;
    if (!trace.path || trace.n !== 4 || !f) return null;
    const gl = this.gl, { width: w, height: h } = trace;
    const resolved = this._targets(w, h, 'resolve', 4);
    const guides = [['u_albedo', resolved.tex[2]], ['u_normal', resolved.tex[3]]];
    const common = (prog) => {
      gl.useProgram(prog.program);
      gl.uniform1f(prog.uniforms.get('u_inv_normal').loc, 1 / (f.sigma_normal * f.sigma_normal));
      gl.uniform1f(prog.uniforms.get('u_inv_albedo').loc, 1 / (f.sigma_albedo * f.sigma_albedo));
      gl.uniform1f(prog.uniforms.get('u_albedo_floor').loc, f.albedo_floor);
      gl.uniform3fv(prog.uniforms.get('u_luminance').loc, new Float32Array(f.luminance));
    };
    gl.bindVertexArray(this.vao);
    gl.viewport(0, 0, w, h);
    const pre = this.program(QUAD_VS, ATROUS_PRE_FS);
    common(pre);
    gl.uniform1f(pre.uniforms.get('u_firefly_sigmas').loc, f.firefly_sigmas);
    gl.uniform1f(pre.uniforms.get('u_quadrant_pixels').loc, f.quadrant_pixels);
    let dst = this._targets(w, h, 'atrous0', 1);
    gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fbo);
    let units = [['u_color', resolved.tex[0]], ...guides];
    this._bindUnits(pre, units);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    this._unbindUnits(units.length);
    let src = dst.tex[0];
    const prog = this.program(QUAD_VS, ATROUS_FS);
    common(prog);
    gl.uniform1fv(prog.uniforms.get('u_kernel').loc, new Float32Array(f.kernel));
    // renderer/image/atrous.py's luminance_sigma: σ_l·√(noise_samples / samples) past noise_samples.
    const sigma = f.sigma_luminance * Math.min(1, Math.sqrt(f.noise_samples / Math.max(1, trace.samplesDone)));
    gl.uniform1f(prog.uniforms.get('u_inv_luminance').loc, 1 / sigma);
    gl.uniform1f(prog.uniforms.get('u_sqrt_variance_floor').loc, Math.sqrt(f.variance_floor));
    for (let i = 0; i < f.iterations; i++) {
      dst = this._targets(w, h, `atrous${(i + 1) % 2}`, 1);
      gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fbo);
      units = [['u_lighting', src], ...guides];
      this._bindUnits(prog, units);
      gl.uniform1i(prog.uniforms.get('u_step').loc, 1 << i);
      gl.uniform1i(prog.uniforms.get('u_last').loc, i === f.iterations - 1 ? 1 : 0);
      gl.drawArrays(gl.TRIANGLES, 0, 6);
      this._unbindUnits(units.length);
      src = dst.tex[0];
    }
    gl.bindVertexArray(null);
    return src;
  }

  // The resolve targets: the box filter of the sub-pixels, or the mean of the paths traced so far.
  _resolve(trace) {
    const gl = this.gl;
    let src, centre, k = trace.k, scale;
    if (trace.path) {
      src = centre = this._targets(trace.width, trace.height, trace.sum, trace.n);
      k = 1;
      scale = 1 / trace.samplesDone;
    } else {
      const grid = trace.phases[trace.phases.length - 1];
      src = this._targets(grid.tw, grid.th, grid.role);
      centre = trace.k > 1 ? this._targets(trace.width, trace.height, 'centre') : src;
      scale = 1 / (trace.k * trace.k);
    }
    const dst = this._targets(trace.width, trace.height, 'resolve', trace.n);
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fbo);
    gl.viewport(0, 0, trace.width, trace.height);
    const r = trace.n === 4 ? this.program(QUAD_VS, withGuides(RESOLVE_FS, true)) : this.resolveProgram;
    gl.useProgram(r.program);
    // (u_trace1 is not read: the normal and t come from the pixel centres.)
    const units = [...src.tex.map((t, i) => [`u_trace${i}`, t]), ['u_centre0', centre.tex[0]], ['u_centre1', centre.tex[1]]];
    this._bindUnits(r, units);
    gl.uniform1i(r.uniforms.get('u_k').loc, k);
    gl.uniform1f(r.uniforms.get('u_scale').loc, scale);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    this._unbindUnits(units.length);
    gl.bindVertexArray(null);
  }

  // `image` (an RGBA32F texture of the frame's size) onto this.canvas: clamped, or (path) tone-mapped.
  _display(trace, image, path) {
    const gl = this.gl;
    if (this.canvas.width !== trace.width || this.canvas.height !== trace.height) {
      this.canvas.width = trace.width;
      this.canvas.height = trace.height;
    }
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, trace.width, trace.height);
    const d = this.displayProgram;
    gl.useProgram(d.program);
    gl.activeTexture(gl.TEXTURE0 + 6);
    gl.bindTexture(gl.TEXTURE_2D, image);
    gl.uniform1i(d.uniforms.get('u_image').loc, 6);
    gl.uniform1i(d.uniforms.get('u_path').loc, path ? 1 : 0);
    const op = TONE_MAPS[trace.display.toneMap];
    if (op === undefined) throw new Error(`unknown tone map ${trace.display.toneMap}`);
    gl.uniform1i(d.uniforms.get('u_tone_map').loc, op);
    gl.uniform1f(d.uniforms.get('u_exposure_scale').loc, Math.pow(2, Number(trace.display.exposure) || 0));
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.bindVertexArray(null);
  }

  // Whether a traced phase can be shown before the frame is done: the pixel centres of a
  // supersampled frame, or the mean of a path-traced frame's first passes (of this trace's: a
  // continued frame's mean before them is on screen already).
  previewReady(trace) {
    return !trace.done && (trace.path ? trace.samplesDone > trace.samplesAtStart : trace.k > 1 && trace.phase >= 1);
  }

  // The preview of a frame in progress onto this.canvas (previewReady). → ms.
  showCentre(trace) {
    this._check();
    const t0 = performance.now();
    if (trace.path) {
      this._resolve(trace);
      const filtered = this._filter(trace);
      this._display(trace, filtered ?? this._targets(trace.width, trace.height, 'resolve', trace.n).tex[0], true);
    } else {
      this._display(trace, this._targets(trace.width, trace.height, 'centre').tex[0], false);
    }
    return performance.now() - t0;
  }

  // A whole frame at once (benchmarks): one band of every row. → {trace, display} ms.
  render(prog, { width, height, k = 1, uniforms, path = null, display = null }) {
    const trace = this.beginTrace(prog, { width, height, k, uniforms, path, display });
    let ms = 0;
    while (!trace.done) ms += this.traceBand(trace, trace.th);
    return { trace: ms, display: this.finishTrace(trace) };
  }

  // The last frame as the server's npy arrays: primid Int32Array (H×W, −1 miss), colour
  // Uint8Array (H×W×3, floor(255·clamp(c)+0.5)), row 0 = top. A path-traced frame's colour is
  // the canvas's tone-mapped sRGB bytes (what the server's png holds), and radiance
  // (Float32Array H×W×3) its linear mean (what the server's npy holds); with the guides also
  // albedo and normal (their means) and, filtered, denoised (the à-trous filter's output), H×W×3.
  readback() {
    const gl = this.gl, { width: w, height: h, path, n, filtered } = this.last;
    const resolved = this._targets(w, h, 'resolve', n);
    const px = new Float32Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, resolved.fbo);
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
    const extra = {};
    if (n === 4) {
      extra.albedo = this._rgbRows(resolved.fbo, 2, w, h);
      extra.normal = this._rgbRows(resolved.fbo, 3, w, h);
    }
    if (filtered) {
      const fbo = [0, 1].map((i) => this._targets(w, h, `atrous${i}`, 1)).find((t) => t.tex[0] === filtered).fbo;
      extra.denoised = this._rgbRows(fbo, 0, w, h);
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    let shown = null;
    if (path) {
      shown = new Uint8Array(w * h * 4);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, shown);
    }
    const primid = new Int32Array(w * h), color = new Uint8Array(w * h * 3);
    const radiance = path ? new Float32Array(w * h * 3) : null;
    for (let y = 0; y < h; y++) {
      const src = (h - 1 - y) * w;   // GL row 0 is the bottom
      for (let x = 0; x < w; x++) {
        const i = (src + x) * 4, o = y * w + x;
        primid[o] = px[i + 3] | 0;
        for (let c = 0; c < 3; c++) {
          if (path) {
            radiance[o * 3 + c] = px[i + c];
            color[o * 3 + c] = shown[i + c];
          } else {
            color[o * 3 + c] = Math.floor(255 * Math.min(1, Math.max(0, px[i + c])) + 0.5);
          }
        }
      }
    }
    return { width: w, height: h, primid, color, radiance, ...extra };
  }

  // Attachment `i` of `fbo` (w × h, RGBA32F) as a Float32Array H×W×3, row 0 = top.
  _rgbRows(fbo, i, w, h) {
    const gl = this.gl, px = new Float32Array(w * h * 4), out = new Float32Array(w * h * 3);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.readBuffer(gl.COLOR_ATTACHMENT0 + i);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
    for (let y = 0; y < h; y++) {
      for (let x = 0; x < w; x++) {
        const s = ((h - 1 - y) * w + x) * 4, o = (y * w + x) * 3;
        out[o] = px[s]; out[o + 1] = px[s + 1]; out[o + 2] = px[s + 2];
      }
    }
    return out;
  }

  _dummy(type) {
    const gl = this.gl;
    this._dummies = this._dummies || new Map();
    if (this._dummies.has(type)) return this._dummies.get(type);
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    nearest(gl);
    const [internal, format, kind, data] =
      type === gl.UNSIGNED_INT_SAMPLER_2D ? [gl.R32UI, gl.RED_INTEGER, gl.UNSIGNED_INT, new Uint32Array(1)]
        : type === gl.INT_SAMPLER_2D ? [gl.R32I, gl.RED_INTEGER, gl.INT, new Int32Array(1)]
          : [gl.RGBA32F, gl.RGBA, gl.FLOAT, new Float32Array(4)];
    gl.texImage2D(gl.TEXTURE_2D, 0, internal, 1, 1, 0, format, kind, data);
    this._dummies.set(type, t);
    return t;
  }
}

function nearest(gl) {
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
}

// gpu_layout's (dtype, components) → WebGL2's (internal format, format, type).
function textureFormat(gl, dtype, components) {
  const f = dtype === 'f4';
  const internal = f ? [gl.R32F, gl.RG32F, gl.RGB32F, gl.RGBA32F] : [gl.R32UI, gl.RG32UI, gl.RGB32UI, gl.RGBA32UI];
  const format = f ? [gl.RED, gl.RG, gl.RGB, gl.RGBA] : [gl.RED_INTEGER, gl.RG_INTEGER, gl.RGB_INTEGER, gl.RGBA_INTEGER];
  return { internal: internal[components - 1], format: format[components - 1], type: f ? gl.FLOAT : gl.UNSIGNED_INT };
}

function isSampler(gl, type) {
  return type === gl.SAMPLER_2D || type === gl.UNSIGNED_INT_SAMPLER_2D || type === gl.INT_SAMPLER_2D;
}

// A uniform's value (number or nested lists) by the type the program reports.
function setUniform(gl, u, value) {
  const flat = [value].flat(3).map(Number);
  const T = {
    [gl.FLOAT]: ['1fv', 1], [gl.FLOAT_VEC2]: ['2fv', 2], [gl.FLOAT_VEC3]: ['3fv', 3], [gl.FLOAT_VEC4]: ['4fv', 4],
    [gl.INT]: ['1iv', 1], [gl.INT_VEC2]: ['2iv', 2], [gl.INT_VEC3]: ['3iv', 3], [gl.INT_VEC4]: ['4iv', 4],
    [gl.BOOL]: ['1iv', 1], [gl.UNSIGNED_INT]: ['1uiv', 1], [gl.UNSIGNED_INT_VEC2]: ['2uiv', 2],
    [gl.UNSIGNED_INT_VEC3]: ['3uiv', 3], [gl.UNSIGNED_INT_VEC4]: ['4uiv', 4],
  }[u.type];
  if (!T) return;
  const [fn, n] = T;
  const data = flat.slice(0, n * u.size);
  if (data.length < n) return;
  const arr = fn.endsWith('fv') ? new Float32Array(data) : fn.endsWith('uiv') ? new Uint32Array(data) : new Int32Array(data);
  gl[`uniform${fn}`](u.loc, arr);
}
