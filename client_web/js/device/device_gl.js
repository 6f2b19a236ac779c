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

// Up to 4 × 4 sub-pixels (16 samples per pixel, the server's largest).
const RESOLVE_FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform highp sampler2D u_trace0;
uniform highp sampler2D u_trace1;
uniform highp sampler2D u_centre0;   // the pixel-centre pass (k > 1; else the trace itself)
uniform highp sampler2D u_centre1;
uniform int u_k;
layout(location = 0) out vec4 o_image;
layout(location = 1) out vec4 o_hit;
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
  o_image = vec4(sum / float(u_k * u_k), texelFetch(u_centre0, c, 0).a);
  o_hit = texelFetch(u_centre1, c, 0);
}`;

const DISPLAY_FS = `#version 300 es
precision highp float;
precision highp sampler2D;
uniform highp sampler2D u_image;
out vec4 o_color;
void main() { o_color = vec4(clamp(texelFetch(u_image, ivec2(gl_FragCoord.xy), 0).rgb, 0.0, 1.0), 1.0); }`;

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
    this.resolveProgram = this.program(QUAD_VS, RESOLVE_FS);
    this.displayProgram = this.program(QUAD_VS, DISPLAY_FS);
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
      const fmt = textureFormat(gl, t.dtype, t.components);
      const tex = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, tex);
      nearest(gl);
      gl.texImage2D(gl.TEXTURE_2D, 0, fmt.internal, t.width, t.height, 0, fmt.format, fmt.type, t.data);
      this.textures.push({ name: t.name, tex });
    }
    gl.bindTexture(gl.TEXTURE_2D, null);
    this.header = parsed.header;
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new DeviceUnavailable(`texture upload failed (GL error 0x${err.toString(16)})`);
  }

  // Two RGBA32F targets of width × height for `role` ('trace' or 'resolve': never the same
  // textures, even at one sample per pixel, since the resolve reads the trace's), cached.
  _targets(width, height, role = 'trace') {
    const gl = this.gl, key = `${role}:${width}x${height}`;
    if (this.targets.has(key)) return this.targets.get(key);
    if (this.targets.size >= 8) {   // bound the cache: release the oldest size
      const [oldKey, old] = this.targets.entries().next().value;
      gl.deleteFramebuffer(old.fbo);
      old.tex.forEach((t) => gl.deleteTexture(t));
      this.targets.delete(oldKey);
    }
    const fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    const tex = [0, 1].map((i) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      nearest(gl);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, width, height);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0);
      return t;
    });
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
    const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
    if (status !== gl.FRAMEBUFFER_COMPLETE) {
      throw new DeviceUnavailable(`two RGBA32F render targets are not supported here (0x${status.toString(16)})`);
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
  beginTrace(prog, { width, height, k = 1, uniforms }) {
    this._check();
    const phases = [];
    if (k > 1) phases.push({ role: 'centre', tw: width, th: height, uniforms: { ...uniforms, u_resolution: [width, height] } });
    phases.push({ role: 'trace', tw: width * k, th: height * k, uniforms });
    phases.forEach((p) => this._targets(p.tw, p.th, p.role));
    const trace = {
      prog, width, height, k, phases, phase: 0, rowsDone: 0, rowsDoneTotal: 0, bands: 0, traceMs: 0,
      rowsTotal: phases.reduce((n, p) => n + p.th, 0),
      get tw() { return this.phases[Math.min(this.phase, this.phases.length - 1)].tw; },
      get th() { return this.phases[Math.min(this.phase, this.phases.length - 1)].th; },
      get done() { return this.phase >= this.phases.length; },
    };
    return trace;
  }

  // Bind the tracer, its textures and uniforms (every band: other passes change the state between).
  _bindTrace(trace) {
    const gl = this.gl, prog = trace.prog, phase = trace.phases[trace.phase];
    gl.bindFramebuffer(gl.FRAMEBUFFER, this._targets(trace.tw, trace.th, phase.role).fbo);
    gl.viewport(0, 0, trace.tw, trace.th);
    gl.useProgram(prog.program);
    // Textures: one unit each; samplers the data does not fill get a 1×1 dummy of their kind.
    let unit = 0;
    const bound = new Set();
    for (const t of this.textures) {
      const u = prog.uniforms.get(t.name);
      if (!u) continue;
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, t.tex);
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
      trace.phase++;
      trace.rowsDone = 0;
    }
    return ms;
  }

  // All bands traced: resolve the sub-pixels and show the frame on this.canvas. → ms.
  finishTrace(trace) {
    this._check();
    const gl = this.gl, t0 = performance.now();
    const grid = trace.phases[trace.phases.length - 1];
    const src = this._targets(grid.tw, grid.th, grid.role);
    const centre = trace.k > 1 ? this._targets(trace.width, trace.height, 'centre') : src;
    const dst = this._targets(trace.width, trace.height, 'resolve');
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, dst.fbo);
    gl.viewport(0, 0, trace.width, trace.height);
    const r = this.resolveProgram;
    gl.useProgram(r.program);
    [...src.tex, ...centre.tex].forEach((t, i) => {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(gl.TEXTURE_2D, t);
    });
    // (u_trace1 is not read: the normal and t come from the pixel centres.)
    [['u_trace0', 0], ['u_trace1', 1], ['u_centre0', 2], ['u_centre1', 3]].forEach(([name, unit]) => {
      const u = r.uniforms.get(name);
      if (u) gl.uniform1i(u.loc, unit);
    });
    gl.uniform1i(r.uniforms.get('u_k').loc, trace.k);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    if (this.canvas.width !== trace.width || this.canvas.height !== trace.height) {
      this.canvas.width = trace.width;
      this.canvas.height = trace.height;
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, trace.width, trace.height);
    const d = this.displayProgram;
    gl.useProgram(d.program);
    gl.activeTexture(gl.TEXTURE0 + 4);
    gl.bindTexture(gl.TEXTURE_2D, dst.tex[0]);
    gl.uniform1i(d.uniforms.get('u_image').loc, 4);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    [0, 1, 2, 3, 4].forEach((i) => {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(gl.TEXTURE_2D, null);
    });
    gl.bindVertexArray(null);
    this.last = { width: trace.width, height: trace.height };
    return performance.now() - t0;
  }

  // The pixel-centre phase of a supersampled frame onto this.canvas (its preview). → ms.
  showCentre(trace) {
    this._check();
    const gl = this.gl, t0 = performance.now();
    const centre = this._targets(trace.width, trace.height, 'centre');
    if (this.canvas.width !== trace.width || this.canvas.height !== trace.height) {
      this.canvas.width = trace.width;
      this.canvas.height = trace.height;
    }
    gl.bindVertexArray(this.vao);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, trace.width, trace.height);
    const d = this.displayProgram;
    gl.useProgram(d.program);
    gl.activeTexture(gl.TEXTURE0 + 4);
    gl.bindTexture(gl.TEXTURE_2D, centre.tex[0]);
    gl.uniform1i(d.uniforms.get('u_image').loc, 4);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.bindVertexArray(null);
    return performance.now() - t0;
  }

  // A whole frame at once (benchmarks): one band of every row. → {trace, display} ms.
  render(prog, { width, height, k = 1, uniforms }) {
    const trace = this.beginTrace(prog, { width, height, k, uniforms });
    let ms = 0;
    while (!trace.done) ms += this.traceBand(trace, trace.th);
    return { trace: ms, display: this.finishTrace(trace) };
  }

  // The last frame as the server's npy arrays: primid Int32Array (H×W, −1 miss), colour
  // Uint8Array (H×W×3, floor(255·clamp(c)+0.5)), row 0 = top.
  readback() {
    const gl = this.gl, { width: w, height: h } = this.last;
    const px = new Float32Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this._targets(w, h, 'resolve').fbo);
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const primid = new Int32Array(w * h), color = new Uint8Array(w * h * 3);
    for (let y = 0; y < h; y++) {
      const src = (h - 1 - y) * w;   // GL row 0 is the bottom
      for (let x = 0; x < w; x++) {
        const i = (src + x) * 4, o = y * w + x;
        primid[o] = px[i + 3] | 0;
        for (let c = 0; c < 3; c++) color[o * 3 + c] = Math.floor(255 * Math.min(1, Math.max(0, px[i + c])) + 0.5);
      }
    }
    return { width: w, height: h, primid, color };
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
