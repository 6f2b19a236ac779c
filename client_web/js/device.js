// On-device rendering (issue #10): the server's tracer, run by this browser in WebGL2.
//
// One shader, one tree layout: the fragment shader is the text the server compiles
// (GET /api/shader, assembled by renderer.shader_source.tracer_source), the textures
// and uniforms are what renderer.gpu_layout packs for moderngl, delivered as one
// binary blob (GET /api/sessions/{id}/device-data; its format is documented in
// server/device_data.py). The tree is still built by the server, per request.
//
//  - DeviceRenderer: WebGL2 context on an offscreen canvas; uploads the blob's
//    textures (RGBA32F → RGBA32F/FLOAT, R32UI → R32UI/RED_INTEGER, RGBA32UI →
//    RGBA32UI/RGBA_INTEGER: the tree's records and the sphere records, which a device
//    always gets as textures, never as the uniform blocks the server may choose; …;
//    NEAREST), sets the uniforms by the types the linked
//    program reports, draws two triangles into two RGBA32F targets (location 0:
//    rgb image + primary id, location 1: normal + t), then copies location 0,
//    clamped, to its canvas for display. readback() gives ids and uint8 colour
//    exactly as the server's npy frames (row 0 = top).
//  - DeviceView: the device mode of the client. Gestures move a local camera at
//    display rate (the Controller's math of server/controller.py, ported below)
//    and still go to the server's Model through the app's FrameScheduler (one
//    request in flight, merged: the throttle), so switching back to server mode
//    shows the same view. When the session or its render settings change the data
//    is fetched again. Anything missing (WebGL2, EXT_color_buffer_float, a texture
//    size the scene needs, a method that needs several passes) → the app falls
//    back to server mode with a notice.
//
// Test/URL flag: ?webgl2=0 makes the probe behave as if getContext('webgl2')
// returned null (to exercise the fallback).

import { previewSize } from './settings.js';

export const MIN_TARGET_DISTANCE = 1e-3;   // POCKETRAY_MIN_TARGET_DISTANCE's default
export const MAX_COORDINATE = 1e7;         // renderer.scene.MAX_COORDINATE

// ---- the Controller (server/controller.py), float64 like the server -------------------
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.sqrt(dot(a, a));
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const radians = (deg) => deg * (Math.PI / 180);   // as CPython's math.radians

// Camera.basis(): (right, true_up, forward), orthonormal.
export function cameraBasis(cam) {
  const d = sub(cam.target, cam.position);
  const n = norm(d);
  const forward = d.map((x) => x / n);
  const r = cross(forward, cam.up);
  const rn = norm(r);
  const right = r.map((x) => x / rn);
  return { right, up: cross(right, forward), forward };
}

export function targetDistance(cam) {
  return norm(sub(cam.target, cam.position));
}

function inRange(cam) {
  return [...cam.position, ...cam.target].every((x) => Number.isFinite(x) && Math.abs(x) <= MAX_COORDINATE);
}

// controller.pan: camera and target move by (−dx·right + dy·up)·world_per_pixel.
export function panCamera(cam, dx, dy, viewportHeight) {
  const { right, up } = cameraBasis(cam);
  const k = 2.0 * targetDistance(cam) * Math.tan(radians(cam.fov_y) / 2.0) / viewportHeight;
  const delta = [0, 1, 2].map((i) => (-dx * right[i] + dy * up[i]) * k);
  return {
    ...cam, position: cam.position.map((x, i) => x + delta[i]), target: cam.target.map((x, i) => x + delta[i]),
  };
}

// controller.pinch: along the view axis to distance d / scale (never closer than minDistance).
export function pinchCamera(cam, scale, minDistance = MIN_TARGET_DISTANCE) {
  const offset = sub(cam.position, cam.target);
  const distance = norm(offset);
  let nd = distance / scale;
  if (scale > 1) nd = Math.max(nd, Math.min(distance, minDistance));
  return { ...cam, position: cam.target.map((t, i) => t + offset[i] * (nd / distance)) };
}

// A gesture ({type: pan|pinch|reset}) applied to `cam`; out-of-range results leave it as it was
// (the server answers those with 422 and changes nothing).
export function applyGesture(cam, g, { viewportHeight, home }) {
  let out = cam;
  if (g.type === 'pan') out = panCamera(cam, g.dx || 0, g.dy || 0, viewportHeight);
  else if (g.type === 'pinch' && g.scale > 0 && Number.isFinite(g.scale)) out = pinchCamera(cam, g.scale);
  else if (g.type === 'reset' && home) out = structuredClone(home);
  return inRange(out) ? out : cam;
}

// ---- the blob ------------------------------------------------------------------------------
const MAGIC = 'PRDD';

// → {header, textures: [{name, width, height, components, dtype, internal_format, data}]}
export function parseDeviceData(buffer) {
  const bytes = new Uint8Array(buffer);
  const magic = String.fromCharCode(...bytes.subarray(0, 4));
  if (magic !== MAGIC) throw new Error('device data: bad magic');
  const view = new DataView(buffer);
  const version = view.getUint32(4, true);
  if (version !== 1) throw new Error(`device data: format ${version}, this client reads 1`);
  const n = view.getUint32(8, true);
  const header = JSON.parse(new TextDecoder().decode(bytes.subarray(12, 12 + n)));
  const textures = header.textures.map((t) => {
    const count = t.width * t.height * t.components;
    const Ctor = t.dtype === 'f4' ? Float32Array : Uint32Array;
    return { ...t, data: new Ctor(buffer, t.offset, count) };
  });
  return { header, textures };
}

// ---- WebGL2 -----------------------------------------------------------------------------
function simulatedNoWebGL2() {
  try {
    return new URLSearchParams(location.search).get('webgl2') === '0';
  } catch {
    return false;
  }
}

const DISPLAY_VS = `#version 300 es
in vec2 a_position;
void main() { gl_Position = vec4(a_position, 0.0, 1.0); }`;
// Location 0 of the tracer, clamped to [0, 1], onto the canvas (same orientation: both bottom-up).
const DISPLAY_FS = `#version 300 es
precision highp float;
precision highp sampler2D;
uniform highp sampler2D u_image;
out vec4 o_colour;
void main() { o_colour = vec4(clamp(texelFetch(u_image, ivec2(gl_FragCoord.xy), 0).rgb, 0.0, 1.0), 1.0); }`;

export class DeviceUnavailable extends Error {}

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
    this.programs = new Map();     // fragment source → {program, uniforms, logs}
    this.textures = [];            // [{name, tex, kind}]
    this.header = null;
    this.targets = null;           // {width, height, fbo, tex: [t0, t1]}
    const quad = new Float32Array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1]);
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, quad, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
    this.display = this.program(DISPLAY_VS, DISPLAY_FS);
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
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      gl.texImage2D(gl.TEXTURE_2D, 0, fmt.internal, t.width, t.height, 0, fmt.format, fmt.type, t.data);
      this.textures.push({ name: t.name, tex, integer: t.dtype === 'u4' });
    }
    gl.bindTexture(gl.TEXTURE_2D, null);
    this.header = parsed.header;
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new DeviceUnavailable(`texture upload failed (GL error 0x${err.toString(16)})`);
  }

  _targets(width, height) {
    const gl = this.gl;
    if (this.targets && this.targets.width === width && this.targets.height === height) return this.targets;
    if (this.targets) {
      gl.deleteFramebuffer(this.targets.fbo);
      this.targets.tex.forEach((t) => gl.deleteTexture(t));
    }
    const fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    const tex = [0, 1].map((i) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
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
    this.targets = { width, height, fbo, tex };
    return this.targets;
  }

  // Trace one frame of `width × height` with the compiled `prog` and `camera` (the scene JSON's camera, docs/FORMATS.md),
  // then show it on this.canvas. → timings {trace, display} in ms.
  render(prog, width, height, camera) {
    const gl = this.gl;
    if (this.lost || gl.isContextLost()) throw new DeviceUnavailable('the WebGL2 context was lost');
    const t0 = performance.now();
    const tg = this._targets(width, height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, tg.fbo);
    gl.viewport(0, 0, width, height);
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
    const values = { ...this.header.uniforms, ...cameraUniforms(camera, width, height) };
    for (const [name, value] of Object.entries(values)) {
      const u = prog.uniforms.get(name);
      if (u && !isSampler(gl, u.type)) setUniform(gl, u, value);
    }
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    // Wait for the trace: a one-pixel read-back is a true sync point (finish() may not be).
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, new Float32Array(4));
    const t1 = performance.now();
    // Display: location 0, clamped, onto the canvas (drawn by the app onto the visible one).
    if (this.canvas.width !== width || this.canvas.height !== height) {
      this.canvas.width = width;
      this.canvas.height = height;
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, width, height);
    gl.useProgram(this.display.program);
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_2D, tg.tex[0]);
    gl.uniform1i(this.display.uniforms.get('u_image').loc, unit);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.bindVertexArray(null);
    return { trace: t1 - t0, display: performance.now() - t1 };
  }

  // The last frame's targets, as the server's npy arrays: primid Int32Array (H×W, −1 miss),
  // colour Uint8Array (H×W×3, floor(255·clamp(c)+0.5)), row 0 = top.
  readback() {
    const gl = this.gl, { width: w, height: h, fbo } = this.targets;
    const px = new Float32Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const primid = new Int32Array(w * h), colour = new Uint8Array(w * h * 3);
    for (let y = 0; y < h; y++) {
      const src = (h - 1 - y) * w;   // GL row 0 is the bottom
      for (let x = 0; x < w; x++) {
        const i = (src + x) * 4, o = y * w + x;
        primid[o] = px[i + 3] | 0;
        for (let c = 0; c < 3; c++) colour[o * 3 + c] = Math.floor(255 * Math.min(1, Math.max(0, px[i + c])) + 0.5);
      }
    }
    return { width: w, height: h, primid, colour };
  }

  _dummy(type) {
    const gl = this.gl;
    this._dummies = this._dummies || new Map();
    if (this._dummies.has(type)) return this._dummies.get(type);
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    const [internal, format, kind, data] =
      type === gl.UNSIGNED_INT_SAMPLER_2D ? [gl.R32UI, gl.RED_INTEGER, gl.UNSIGNED_INT, new Uint32Array(1)]
        : type === gl.INT_SAMPLER_2D ? [gl.R32I, gl.RED_INTEGER, gl.INT, new Int32Array(1)]
          : [gl.RGBA32F, gl.RGBA, gl.FLOAT, new Float32Array(4)];
    gl.texImage2D(gl.TEXTURE_2D, 0, internal, 1, 1, 0, format, kind, data);
    this._dummies.set(type, t);
    return t;
  }
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

// renderer/gpu_layout.py's camera_uniforms and pass_uniforms, in float64 until the upload:
// the camera for a width × height grid, and the pass through the pixel centres (scale 1,
// offset 0.5) unless a sub-pixel pass of a scale × scale grid is asked for.
export function cameraUniforms(camera, width, height, scale = 1, sub = [0, 0]) {
  const { right, up, forward } = cameraBasis(camera);
  const s = Math.tan(radians(camera.fov_y) / 2.0);
  return {
    u_cam_pos: camera.position, u_cam_right: right, u_cam_up: up, u_cam_forward: forward,
    u_half_extent: [s * width / height, s], u_resolution: [width, height],
    u_target_distance: targetDistance(camera),
    u_pass_scale: scale, u_pass_offset: scale === 1 ? [0.5, 0.5] : [sub[0] + 0.5, sub[1] + 0.5],
  };
}

export function toBase64(typed) {
  const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

// ---- device mode ---------------------------------------------------------------------------
// options: api (api.js Api), getState() → {sessionId, render, client}, viewportHeight(),
//          display(frame, level) (the app's), onFallback(message) (switch to server mode).
export class DeviceView {
  constructor({ api, getState, viewportHeight, display, onFallback }) {
    this.api = api;
    this.getState = getState;
    this.viewportHeight = viewportHeight;
    this.displayFrame = display;
    this.onFallback = onFallback;
    this.renderer = null;          // DeviceRenderer once probed successfully
    this.unavailable = null;       // the reason, once probed unsuccessfully
    this.key = null;               // what the loaded data is for
    this.loading = null;           // {key, promise}
    this.camera = null;            // the local camera (camera JSON, docs/FORMATS.md)
    this.home = null;
    this.version = null;           // the session version the local camera builds on
    this.localSeq = 0;             // local gestures so far
    this.raf = null;
    this.refineTimer = null;
    this.lastGestureAt = -Infinity;
    this.busy = false;
    this.dataMs = { build: null, upload: null, fetch: null };
  }

  // Can this browser run the tracer? {ok, reason?, renderer?, maxTextureSize?, colorBufferFloat?}
  probe() {
    if (!this.renderer && !this.unavailable) {
      try {
        this.renderer = new DeviceRenderer();
      } catch (e) {
        this.unavailable = e.message || String(e);
      }
    }
    return this.renderer ? { ok: true, ...this.renderer.info } : { ok: false, reason: this.unavailable };
  }

  get idle() {
    return !this.raf && this.refineTimer === null && !this.loading && !this.busy;
  }

  _dataKey(s, params) {
    const r = { ...s.render, ...params };
    // An animated scene's data is posed by the server at the frame's time: a new time is new data.
    const t = params.time ?? (s.anim && s.anim.animated ? s.anim.time : '');
    return [params.session ?? s.sessionId, r.method, r.mode, r.max_prims, r.max_tree_depth, r.max_recursion_depth,
      params.max_texture_size ?? this.renderer.maxTextureSize, t].join('|');
  }

  // Fetch (when the key changed), upload and compile. `params` override the session's settings.
  async ensure(params = {}) {
    const s = this.getState();
    const key = this._dataKey(s, params);
    if (key === this.key && this.prog) return;
    if (this.loading && this.loading.key === key) return this.loading.promise;
    const session = params.session ?? s.sessionId;
    const seqAtStart = this.localSeq, sessionChanged = !this.key || this.key.split('|')[0] !== session;
    const promise = (async () => {
      const t0 = performance.now();
      const q = {
        max_texture_size: params.max_texture_size ?? this.renderer.maxTextureSize,
        float_textures: this.renderer.colorBufferFloat ? 'true' : 'false',
      };
      for (const k of ['method', 'mode', 'max_prims', 'max_tree_depth', 'max_recursion_depth']) {
        const v = params[k] ?? s.render[k];
        if (v !== undefined && v !== null) q[k] = v;
      }
      const t = params.time ?? (s.anim && s.anim.animated ? s.anim.time : undefined);
      if (t !== undefined) q.time = t;
      const res = await this.api.request('GET', `/api/sessions/${encodeURIComponent(session)}/device-data`, { params: q });
      const parsed = parseDeviceData(await res.arrayBuffer());
      const t1 = performance.now();
      const h = parsed.header;
      const [fs, vs] = await Promise.all([
        this._text(h.shader.url),
        this._text('/api/shader?stage=vertex'),
      ]);
      const t2 = performance.now();
      const prog = this.renderer.program(vs, fs);
      this.renderer.load(parsed);
      this.dataMs = { build: h.build_ms, fetch: t1 - t0, upload: performance.now() - t2 };
      this.prog = prog;
      this.key = key;
      this.stats = h.stats;
      this.method = h.method;
      this.home = h.home_camera;
      // The data's camera is the server's: adopt it unless local gestures happened meanwhile.
      if (sessionChanged || !this.camera || this.localSeq === seqAtStart) {
        this.camera = structuredClone(h.camera);
        this.version = h.session.version;
      }
    })();
    this.loading = { key, promise };
    try {
      await promise;
    } finally {
      if (this.loading && this.loading.promise === promise) this.loading = null;
    }
  }

  async _text(path) {
    const res = await this.api.request('GET', path);
    return res.text();
  }

  _size(level) {
    const { render, client } = this.getState();
    return level === 'full' ? { width: render.width, height: render.height }
      : previewSize(render.width, render.height, client.previewScale);
  }

  // Render the local camera now at `level` (the app's transport.frame in device mode). → a frame
  // for the app's display: {image: canvas, renderer: 'device', …}.
  async frame(level = 'full') {
    const p = this.probe();
    if (!p.ok) throw new DeviceUnavailable(p.reason);
    await this.ensure();
    return this._render(level);
  }

  _render(level) {
    const t0 = performance.now();
    const { width, height } = this._size(level);
    const fresh = this.dataMs;
    this.dataMs = { build: null, upload: null, fetch: null };   // reported once, with the frame after a load
    const ms = this.renderer.render(this.prog, width, height, this.camera);
    return {
      image: this.renderer.canvas, renderer: 'device', rendererInfo: `WebGL2 ${this.renderer.rendererName}`,
      version: this.version, method: this.method, stats: this.stats, contentType: 'webgl2', t0,
      timing: { build: fresh.build, upload: fresh.upload, trace: ms.trace, read: ms.display, network: fresh.fetch },
    };
  }

  // A user gesture: move the local camera now; the app also sends it to the server.
  gesture(g) {
    if (!this.camera) return;
    this.camera = applyGesture(this.camera, g, { viewportHeight: this.viewportHeight(), home: this.home });
    this.localSeq++;
    this.lastGestureAt = performance.now();
    this._cancelRefine();
    const { client } = this.getState();
    this._schedule(client.previewScale < 1 ? 'preview' : 'full');
  }

  // The server's answer to the last gesture request of a batch ({version, camera}). With no
  // local gesture since it was sent, the local camera becomes the server's (removes drift
  // from merging and rounding), so both sides show the same view.
  serverCamera(answer, localSeqAtSend) {
    if (!answer || !answer.camera) return;
    this.version = answer.version;
    if (this.localSeq === localSeqAtSend) this.camera = answer.camera;
  }

  _schedule(level) {
    this.level = this.level === 'preview' ? 'preview' : level;
    if (this.raf) return;
    this.raf = requestAnimationFrame(() => this._tick());
  }

  async _tick() {
    this.raf = null;
    const level = this.level || 'full';
    this.level = null;
    if (this.busy) return this._schedule(level);   // the previous frame is still being shown
    this.busy = true;
    try {
      await this.ensure();   // at once when the data is current
      await this.displayFrame(this._render(level), level);
    } catch (e) {
      if (e && e.status === 404) return;   // the session expired: the app's scheduler handles it
      this.onFallback(e.message || String(e));
      return;
    } finally {
      this.busy = false;
    }
    if (level === 'preview') this._scheduleRefine();
  }

  _cancelRefine() {
    if (this.refineTimer !== null) clearTimeout(this.refineTimer);
    this.refineTimer = null;
  }

  _scheduleRefine() {
    this._cancelRefine();
    const { client } = this.getState();
    const wait = Math.max(0, client.refineDelayMs - (performance.now() - this.lastGestureAt));
    this.refineTimer = setTimeout(() => {
      this.refineTimer = null;
      this._schedule('full');
    }, wait);
  }

  // Leaving device mode: nothing scheduled any more.
  stop() {
    this._cancelRefine();
    if (this.raf) cancelAnimationFrame(this.raf);
    this.raf = null;
    this.level = null;
  }

  // ---- test and benchmark hooks: window.pocketray.device -------------------------------------
  // bench({session, width, height, frames, budgetMs, method, mode, …}): load once, then render the
  // server camera `frames` times (within budgetMs). → {load, first, times} in ms; each time is
  // one trace (waited for with a one-pixel read-back) plus the display pass.
  async bench(params = {}) {
    const p = this.probe();
    if (!p.ok) throw new Error(p.reason);
    const { width, height, frames = 5, budgetMs = 20000, ...rest } = params;
    this.key = null;
    const t0 = performance.now();
    await this.ensure(rest);
    const load = { total: performance.now() - t0, ...this.dataMs };
    const camera = this.renderer.header.camera;
    const one = () => {
      const ms = this.renderer.render(this.prog, width, height, camera);
      return ms.trace + ms.display;
    };
    const first = one();           // some drivers compile lazily, at the first draw
    const times = [];
    let spent = first;
    while (times.length < frames && spent < budgetMs) {
      const t = one();
      times.push(t);
      spent += t;
    }
    this.key = null;
    return { load, first, times, renderer: this.renderer.rendererName };
  }

  // ---- test hook: window.pocketray.device ----------------------------------------------------
  // renderOnce({width, height, method, mode, max_prims, max_tree_depth, max_recursion_depth,
  // max_texture_size, session}) renders the session's current (server) camera and reads it back
  // (session: another session's id; default the page's).
  // → {width, height, primid: base64 Int32 H×W, colour: base64 uint8 H×W×3, infoLog, renderer,
  //    textures, shader, camera, basis, ms}
  async renderOnce(params = {}) {
    const p = this.probe();
    if (!p.ok) throw new Error(p.reason);
    const { width, height, ...rest } = params;
    this.key = null;                       // the live view reloads its own data afterwards
    await this.ensure(rest);
    const camera = this.renderer.header.camera;
    const ms = this.renderer.render(this.prog, width, height, camera);
    const rb = this.renderer.readback();
    this.key = null;
    const h = this.renderer.header;
    return {
      width: rb.width, height: rb.height, primid: toBase64(rb.primid), colour: toBase64(rb.colour),
      infoLog: this.prog.logs, renderer: `WebGL2 ${this.renderer.rendererName}`, textures: h.textures.map(
        ({ name, width: w, height: hh, internal_format }) => ({ name, width: w, height: hh, internal_format })),
      shader: h.shader, camera, basis: cameraBasis(camera), serverUniforms: h.uniforms, ms,
      maxTextureSize: this.renderer.maxTextureSize,
    };
  }
}
