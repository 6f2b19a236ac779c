// Device mode: the server's tracer, run by this browser in WebGL2.
//
// One shader, one tree layout: the fragment shader is the text the server compiles
// (GET /api/shader), the textures and uniforms are what renderer.gpu.gpu_layout packs for
// moderngl, delivered as one binary blob (GET /api/sessions/{id}/device-data, format in
// server/frames/device_data.py). The tree is still built by the server, per data request.
//
// DeviceView, the device mode of the client:
//  - gestures move a local camera at once (camera.js: server/sessions/controller.py's math) and
//    still go to the server's Model through the app's FrameScheduler, so switching back
//    to server mode shows the same view;
//  - frames are traced in bands of rows, one band per requestAnimationFrame callback
//    (bands.js sizes them), so touch input waits at most one band; a gesture during a
//    frame cancels it and a frame of the new view starts (latest wins; see cancelsFrame);
//  - a frame is traced as the server traces it at the same profile: full frames with the
//    session's samples_per_pixel (√s × √s sub-pixels, box-filtered; ids from the centre
//    one) and ε cut-off (min_weight), preview frames with the service's 'interactive'
//    profile at the preview scale, as the server's previews;
//  - with integrator 'path' (colour frames) the same shader traces paths: samples_per_pixel
//    of them per pixel, in passes of the data's path.samples_per_pass, summed, their mean
//    shown tone-mapped (tone_map, exposure) as the server's png; the mean of the first
//    passes is the frame's preview;
//  - accumulation: while the view rests, full path-traced frames are steps of one pass each
//    (the next sample indices, added to the same sum), each mean shown as it grows, up to the
//    session's refinement target as the server's stream (the larger of samples_per_pixel and
//    refine_samples, for at most refine_time_ms); any change of camera, settings, data or size starts a new sum
//    (the step's signature, _accumulationKey). With a denoiser (denoise not off) the data's
//    variant writes the guides and every mean shown is filtered by the à-trous filter
//    (device_gl.js; the one filter a browser runs, whichever denoiser is named);
//  - anything missing (WebGL2, EXT_color_buffer_float, a texture size the scene needs, a
//    method that needs several passes) → the app falls back to server mode with a notice.
//
// Test/URL flag: ?webgl2=0 makes the probe behave as if getContext('webgl2') returned null.

import { BandPlanner, cancelsFrame } from './bands.js';
import { applyGesture, cameraBasis, targetDistance } from './camera.js';
import { DeviceRenderer, DeviceUnavailable } from './device_gl.js';
import { previewSize } from '../settings.js';

// The camera math lives in camera.js; these names stay importable from here (tests, tools).
export { applyGesture, cameraBasis, orbitCamera, panCamera, pinchCamera, targetDistance } from './camera.js';
export { DeviceRenderer, DeviceUnavailable } from './device_gl.js';


// ---- the blob ------------------------------------------------------------------------------
const MAGIC = 'PRDD';

// → {header, textures: [{name, width, height, components, dtype, internal_format, data}]}; a texture
// array (dtype 'u1', RGBA8: the scene's textures) has `layers` and `levels` [{width, height, data}], its
// mip levels (server/frames/device_data.py's encode_blob).
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
    if (t.levels) {
      const levels = t.levels.map((l) => ({ ...l, data: new Uint8Array(buffer, l.offset, l.nbytes) }));
      return { ...t, levels };
    }
    const count = t.width * t.height * t.components;
    const Ctor = t.dtype === 'f4' ? Float32Array : Uint32Array;
    return { ...t, data: new Ctor(buffer, t.offset, count) };
  });
  return { header, textures };
}

// renderer/gpu/gpu_layout.py's camera_uniforms and pass_uniforms, in float64 until the upload. width
// and height are the traced size: the sub-pixels' grid when supersampling, traced in one pass
// (scale 1, offset 0.5: every fragment one grid point, as the server's one-shot draw).
// renderer/modes.py's AVERAGED_MODES: the images that are the mean of their sub-pixels.
const AVERAGED_MODES = Object.freeze(['color', 'recursion', 'heat', 'cones']);

export function cameraUniforms(camera, width, height) {
  const { right, up, forward } = cameraBasis(camera);
  const s = Math.tan(camera.fov_y * (Math.PI / 180) / 2.0);
  return {
    u_cam_pos: camera.position, u_cam_right: right, u_cam_up: up, u_cam_forward: forward,
    u_half_extent: [s * width / height, s], u_resolution: [width, height],
    u_target_distance: targetDistance(camera),
    u_pass_scale: 1, u_pass_offset: [0.5, 0.5],
  };
}

// Sub-pixels per side for `samples` per pixel, fewer when the traced frame would not fit
// the device's textures (the server refuses beyond its own limit instead).
export function subpixels(samples, width, height, maxTextureSize = Infinity) {
  let k = Math.max(1, Math.round(Math.sqrt(samples)));   // the k × k grid of samples_per_pixel = k²
  while (k > 1 && k * Math.max(width, height) > maxTextureSize) k--;
  return k;
}

export function toBase64(typed) {
  const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

const nextAnimationFrame = () => new Promise((resolve) => requestAnimationFrame(() => resolve()));
// A task of its own, without waiting for the display's next frame (benchmarks compare the two).
const nextTask = () => new Promise((resolve) => {
  const ch = new MessageChannel();
  ch.port1.onmessage = () => resolve();
  ch.port2.postMessage(null);
});

// ---- device mode ---------------------------------------------------------------------------
// options: api (api.js Api), getState() → {sessionId, render, client, profiles, anim},
//          viewportHeight(), display(frame, level) (the app's), onFallback(message).
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
    this.camera = null;            // the local camera (SPEC JSON)
    this.home = null;
    this.version = null;           // the session version the local camera builds on
    this.localSeq = 0;             // local gestures so far
    this.raf = null;
    this.refineTimer = null;
    this.lastGestureAt = -Infinity;
    this.pendingInputAt = null;    // the first gesture not yet on screen (performance.now())
    this.job = null;               // the frame being traced, band by band
    this.jobSeq = 0;
    this.planner = new BandPlanner();
    this.dataMs = { build: null, upload: null, fetch: null };
    this.counts = { traced: 0, cancelled: 0, bands: 0, lastBands: 0, lastRows: 0 };
    this.accum = null;             // {key, trace, target, shown: [samples of each mean shown]} while resting
  }

  // The accumulation in progress (tests): samples summed, the target, the sample counts shown.
  get accumulation() {
    const a = this.accum;
    return a && { samples: a.trace.samplesDone, target: a.target, shown: [...a.shown] };
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
    return !this.raf && this.refineTimer === null && !this.loading && !this.job;
  }

  // The settings data for `params` starts from: the page's session's, or none for another session
  // (the server fills in that session's own).
  _base(s, params) {
    return params.session && params.session !== s.sessionId ? {} : s.render || {};
  }

  _dataKey(s, params) {
    const r = { ...this._base(s, params), ...params };
    // An animated scene's data is posed by the server at the frame's time: a new time is new data.
    const t = params.time ?? (s.anim && s.anim.animated ? s.anim.time : '');
    // sceneRev: the session's scene grew (a model was added, session.js): its data is new too.
    return [params.session ?? s.sessionId, r.method, r.mode, r.max_prims, r.max_tree_depth, r.max_recursion_depth,
      params.max_texture_size ?? this.renderer.maxTextureSize, t, s.sceneRev ?? 0, r.integrator ?? 'whitted',
      (r.denoise ?? 'off') !== 'off'].join('|');
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
        max_array_texture_layers: this.renderer.maxArrayTextureLayers,
        float_textures: this.renderer.colorBufferFloat ? 'true' : 'false',
      };
      // (samples_per_pixel, tone_map, exposure: the header's display settings; the live view
      // reads its own state's, so changing them needs no new data; denoise: on, the variant with
      // the guides, which changing it on or off needs.)
      for (const k of ['method', 'mode', 'max_prims', 'max_tree_depth', 'max_recursion_depth', 'integrator',
        'samples_per_pixel', 'tone_map', 'exposure', 'denoise']) {
        const v = params[k] ?? this._base(s, params)[k];
        if (v !== undefined && v !== null) q[k] = v;
      }
      const t = params.time ?? (s.anim && s.anim.animated ? s.anim.time : undefined);
      if (t !== undefined) q.time = t;
      const res = await this.api.request('GET', `/api/sessions/${encodeURIComponent(session)}/device-data`, { params: q });
      const parsed = parseDeviceData(await res.arrayBuffer());
      const t1 = performance.now();
      const h = parsed.header;
      const [fs, vs] = await Promise.all([this._text(h.shader.url), this._text('/api/shader?stage=vertex')]);
      const t2 = performance.now();
      if (this.job) this._cancel(this.job);   // its textures are about to be replaced
      const prog = this.renderer.program(vs, fs);
      this.renderer.load(parsed);
      this.planner.reset();
      this.dataMs = { build: h.build_ms, fetch: t1 - t0, upload: performance.now() - t2 };
      this.prog = prog;
      this.key = key;
      this.stats = h.stats;
      this.method = h.method;
      this.mode = h.shader.mode;
      this.path = h.path;   // {samples_per_pass, guides, atrous?} of a path-traced variant, else null
      this.n = h.uniforms.u_num_spheres;
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

  // What a level traces: size, sub-pixels and ε — the server's frames at the same profile.
  _profile(level) {
    const { render, client, profiles } = this.getState();
    const fast = (profiles && profiles.interactive) || {};
    const full = level === 'full';
    const { width, height } = full ? { width: render.width, height: render.height }
      : previewSize(render.width, render.height, client.previewScale);
    const samples = full ? render.samples_per_pixel ?? 1 : fast.samples_per_pixel ?? render.samples_per_pixel ?? 1;
    const minWeight = full ? render.min_weight ?? 0 : fast.min_weight ?? render.min_weight ?? 0;
    if (this.path) {   // paths: any count of samples, each over the whole pixel (no sub-pixel grid)
      return { width, height, k: 1, samples, minWeight, path: this._path(samples), display: this._display(render) };
    }
    // depth, primid and normal are one ray through each pixel centre at any samples per pixel
    // (docs/FORMATS.md); the averaged images trace the sub-pixels.
    const averaged = AVERAGED_MODES.includes(render.mode);
    const k = averaged ? subpixels(samples, width, height, this.renderer.maxTextureSize) : 1;
    return { width, height, k, samples: k * k, minWeight };
  }

  // A path-traced frame's passes: `samples` per pixel, the data's samples per pass and guides.
  _path(samples) {
    return this.path ? { samples, perPass: this.path.samples_per_pass, guides: !!this.path.guides } : null;
  }

  // How a path-traced frame is shown: `render`'s tone map, exposure and denoiser (else the data's);
  // atrous: the filter's parameters when a denoiser is on and the data's variant writes the guides.
  _display(render = {}) {
    const h = (this.renderer && this.renderer.header && this.renderer.header.settings) || {};
    const denoise = render.denoise ?? h.denoise ?? 'off';
    const atrous = denoise !== 'off' && this.path && this.path.guides ? this.path.atrous : null;
    return { toneMap: render.tone_map ?? h.tone_map ?? 'clamp', exposure: render.exposure ?? h.exposure ?? 0, atrous };
  }

  // What a resting frame's mean depends on: data, camera, size, ε, display. Equal → its sum grows.
  _accumulationKey(p) {
    return JSON.stringify([this.key, this.camera, p.width, p.height, p.minWeight, p.display]);
  }

  // Whether a preview differs from the full frame (else gestures trace full frames directly).
  previewDiffers() {
    const a = this._profile('preview'), b = this._profile('full');
    return a.width !== b.width || a.k !== b.k || a.minWeight !== b.minWeight || a.samples !== b.samples;
  }

  // Render the local camera at `level` (the app's transport.frame in device mode). → a frame
  // for the app's display ({image: canvas, renderer: 'device', …}), or null when a gesture
  // cancelled it (the gesture's own frame follows).
  // A frame at `level`; a supersampled one shows its pixel centres first and hands that image
  // to onPreview (refined as the server's progressive frames are).
  async frame(level = 'full', onPreview = null) {
    const p = this.probe();
    if (!p.ok) throw new DeviceUnavailable(p.reason);
    const t0 = performance.now();
    await this.ensure();
    return this._start(level, t0, onPreview);
  }

  // Start tracing a frame of the local camera (cancelling the one in progress). → Promise.
  _start(level, t0, onPreview = null) {
    if (this.job) this._cancel(this.job);
    const p = this._profile(level);
    const trace = this._accumulate(level, p) ?? this.renderer.beginTrace(this.prog, {
      width: p.width, height: p.height, k: p.k, path: p.path, display: p.display,
      uniforms: { ...cameraUniforms(this.camera, p.width * p.k, p.height * p.k), u_min_weight: p.minWeight },
    });
    if (this.accum && this.accum.trace === null) this.accum.trace = trace;
    const inputAt = this.pendingInputAt;
    this.pendingInputAt = null;
    const data = this.dataMs;
    this.dataMs = { build: null, upload: null, fetch: null };   // reported once, with the frame after a load
    const job = {
      id: ++this.jobSeq, level, trace, profile: p, camera: this.camera, version: this.version, data,
      t0: inputAt ?? t0, inputAt, rowsDone: 0, rowsTotal: trace.rowsTotal, done: false, cancelled: false, raf: null,
    };
    job.onPreview = onPreview;
    job.promise = new Promise((resolve, reject) => { job.resolve = resolve; job.reject = reject; });
    this.job = job;
    this._band(job);   // the first band now; the others one per animation frame
    return job.promise;
  }

  // A full path-traced frame at rest is one step of the accumulation: the next pass of the sum
  // kept (continueTrace) while nothing it depends on changed, else the first pass of a new sum
  // (→ null after setting p.path to that one pass: the caller begins that trace). Anything else
  // ends the accumulation. A step cancelled half-way loses that pass alone (the sum holds whole
  // passes).
  _accumulate(level, p) {
    if (!p.path || level !== 'full') {
      this.accum = null;
      return null;
    }
    const key = this._accumulationKey(p), a = this.accum;
    if (a && a.key === key && a.trace.samplesDone < a.target) {
      const step = Math.min(p.path.perPass, a.target - a.trace.samplesDone);
      const trace = this.renderer.continueTrace(a.trace, step);
      if (trace) return trace;
    }
    const { target, ms } = this._restTarget(p.samples);
    p.path = { ...p.path, samples: Math.min(p.path.perPass, target) };
    this.accum = { key, trace: null, target, shown: [], until: performance.now() + ms };
    return null;
  }

  // How far a resting view accumulates: the server's refinement targets (docs/API.md,
  // "Refinement"): refine_samples (at least the frame's own samples) within refine_time_ms.
  _restTarget(samples) {
    const { render } = this.getState();
    const target = Math.max(samples, Number(render.refine_samples) || 0);
    const ms = Number(render.refine_time_ms) > 0 ? Number(render.refine_time_ms) : Infinity;
    return { target, ms };
  }

  // Whether the accumulation wants another step (the last one was shown, the target and the time
  // not reached).
  _accumulating() {
    const a = this.accum;
    return !!(a && a.trace && !this.job && a.trace.samplesDone < a.target && a.trace.done && performance.now() < a.until);
  }

  _band(job) {
    job.raf = null;
    if (job.done) return;
    try {
      const t = job.trace;
      const rows = this.planner.rows(t.tw, t.th - t.rowsDone);
      const ms = this.renderer.traceBand(t, rows);
      this.planner.record(rows * t.tw, ms);
      this.counts.bands++;
      this.counts.lastRows = Math.max(this.counts.lastRows, rows);
      job.rowsDone = t.rowsDoneTotal;
      if (!job.previewed && job.onPreview && this.renderer.previewReady(t)) {
        // The pixel centres (or the first paths) are traced: show them while the rest follows.
        job.previewed = true;
        const displayMs = this.renderer.showCentre(t);
        job.onPreview({ ...this._frameOf(job, displayMs), part: 'preview' });
      }
      if (!t.done) {
        job.raf = requestAnimationFrame(() => this._band(job));
        return;
      }
      const displayMs = this.renderer.finishTrace(t);
      job.done = true;
      if (this.job === job) this.job = null;
      this.counts.traced++;
      this.counts.lastBands = t.bands;
      const a = this.accum;
      if (a && a.trace === t) a.shown.push(t.samplesDone);
      job.resolve(this._frameOf(job, displayMs));
      // At rest: the next step follows (its own frame), unless a gesture or new settings came first.
      if (this._accumulating()) this._schedule('full');
    } catch (e) {
      job.done = true;
      if (this.job === job) this.job = null;
      job.reject(e);
    }
  }

  _cancel(job) {
    if (job.done) return;
    job.done = job.cancelled = true;
    if (job.raf !== null) cancelAnimationFrame(job.raf);
    if (this.job === job) this.job = null;
    this.counts.cancelled++;
    // Its gestures are not on screen yet: the next frame answers for them.
    if (job.inputAt !== null) this.pendingInputAt = Math.min(job.inputAt, this.pendingInputAt ?? Infinity);
    if (job.data.fetch !== null && this.dataMs.fetch === null) this.dataMs = job.data;   // … and its data's timings
    job.resolve(null);
  }

  _frameOf(job, displayMs) {
    const t = job.trace, p = job.profile;
    return {
      image: this.renderer.canvas, renderer: 'device', rendererInfo: `WebGL2 ${this.renderer.rendererName}`,
      version: job.version, method: this.method, stats: this.stats, contentType: 'webgl2', t0: job.t0,
      camera: job.camera,
      meta: {
        sessionId: this.key ? this.key.split('|')[0] : null, n: this.n, mode: this.mode, method: this.method,
        // the ray cut-off ε is Whitted's alone: a path's length is its depth
        samples: t.path ? t.samplesDone : p.samples, minWeight: t.path ? null : p.minWeight,
      },
      timing: {
        build: job.data.build, upload: job.data.upload, network: job.data.fetch,
        trace: t.traceMs, bands: t.bands, display: displayMs,
      },
    };
  }

  // A user gesture: move the local camera now; the app also sends it to the server.
  gesture(g) {
    if (!this.camera) return;
    this.camera = applyGesture(this.camera, g, { viewportHeight: this.viewportHeight(), home: this.home });
    this.localSeq++;
    this.lastGestureAt = performance.now();
    if (this.pendingInputAt === null) this.pendingInputAt = this.lastGestureAt;
    if (cancelsFrame(this.job)) this._cancel(this.job);
    this._cancelRefine();
    this._schedule(this.previewDiffers() ? 'preview' : 'full');
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
    if (this.job || this.loading) return this._schedule(level);   // a frame past half-way finishes first
    let frame;
    try {
      await this.ensure();   // at once when the data is current
      frame = await this._start(level, performance.now());
      if (frame) await this.displayFrame(frame, level);
    } catch (e) {
      if (e && e.status === 404) return;   // the session expired: the app's scheduler handles it
      this.onFallback(e.message || String(e));
      return;
    }
    if (frame && level === 'preview' && !this.raf) this._scheduleRefine();
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

  // Leaving device mode: nothing scheduled or traced any more.
  stop() {
    this._cancelRefine();
    if (this.raf) cancelAnimationFrame(this.raf);
    this.raf = null;
    this.level = null;
    if (this.job) this._cancel(this.job);
    this.accum = null;
  }

  // The last frame shown, read back (tests): base64 of renderer.readback()'s arrays.
  readback() {
    const rb = this.renderer.readback();
    const out = { width: rb.width, height: rb.height };
    for (const k of ['primid', 'color', 'radiance', 'albedo', 'normal', 'denoised']) out[k] = rb[k] ? toBase64(rb[k]) : null;
    return out;
  }

  // ---- test and benchmark hooks: window.pocketray.device -------------------------------------
  // bench({session, width, height, frames, budgetMs, samples_per_pixel, min_weight, method, mode, …}):
  // load once, then render the server camera `frames` times (within budgetMs), each frame in one
  // band. → {load, first, times} in ms; each time is one trace (waited for with a one-pixel
  // read-back) plus the resolve and display passes.
  async bench(params = {}) {
    const p = this.probe();
    if (!p.ok) throw new Error(p.reason);
    const { width, height, frames = 5, budgetMs = 20000, samples_per_pixel: spp = 1, min_weight: eps = 0, ...rest } = params;
    this.stop();
    this.key = null;
    const t0 = performance.now();
    await this.ensure({ ...rest, samples_per_pixel: spp });
    const load = { total: performance.now() - t0, ...this.dataMs };
    const camera = this.renderer.header.camera;
    const path = this._path(spp), display = this._display(rest);
    const k = path ? 1 : subpixels(spp, width, height, this.renderer.maxTextureSize);
    const uniforms = { ...cameraUniforms(camera, width * k, height * k), u_min_weight: eps };
    const one = () => {
      const ms = this.renderer.render(this.prog, { width, height, k, uniforms, path, display });
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

  // renderOnce({width, height, samples_per_pixel, min_weight, method, mode, max_prims, max_tree_depth,
  // max_recursion_depth, max_texture_size, session, band_ms, between}) renders the session's current
  // (server) camera in bands, as a live frame is traced, and reads it back (session: another
  // session's id; default the page's; band_ms: the bands' budget; between: 'frame' (the next
  // animation frame, as live frames) or 'task' — for benchmarks). → {width, height, primid: base64 Int32 H×W, colour: base64 uint8 H×W×3, infoLog,
  //   renderer, textures, shader, camera, basis, bands, …}
  async renderOnce(params = {}) {
    const p = this.probe();
    if (!p.ok) throw new Error(p.reason);
    const { width, height, samples_per_pixel: spp = 1, min_weight: eps = 0, band_ms: bandMs, between = 'frame', ...rest } = params;
    this.stop();
    this.key = null;                       // the live view reloads its own data afterwards
    await this.ensure({ ...rest, samples_per_pixel: spp });
    const planner = bandMs ? new BandPlanner({ budgetMs: bandMs }) : this.planner;
    const wait = between === 'task' ? nextTask : nextAnimationFrame;
    const t0 = performance.now();
    const camera = this.renderer.header.camera;
    const path = this._path(spp), display = this._display(rest);
    const k = path ? 1 : subpixels(spp, width, height, this.renderer.maxTextureSize);
    const uniforms = { ...cameraUniforms(camera, width * k, height * k), u_min_weight: eps };
    const trace = this.renderer.beginTrace(this.prog, { width, height, k, uniforms, path, display });
    while (!trace.done) {
      const rows = planner.rows(trace.tw, trace.th - trace.rowsDone);
      planner.record(rows * trace.tw, this.renderer.traceBand(trace, rows));
      if (!trace.done) await wait();
    }
    this.renderer.finishTrace(trace);
    const ms = { total: performance.now() - t0, trace: trace.traceMs };
    const rb = this.renderer.readback();
    this.key = null;
    const h = this.renderer.header;
    return {
      width: rb.width, height: rb.height, primid: toBase64(rb.primid), color: toBase64(rb.color),
      radiance: rb.radiance ? toBase64(rb.radiance) : null, path, display,
      ...Object.fromEntries(['albedo', 'normal', 'denoised'].map((k) => [k, rb[k] ? toBase64(rb[k]) : null])),
      infoLog: this.prog.logs, renderer: `WebGL2 ${this.renderer.rendererName}`, textures: h.textures.map(
        ({ name, width: w, height: hh, internal_format }) => ({ name, width: w, height: hh, internal_format })),
      shader: h.shader, camera, basis: cameraBasis(camera), serverUniforms: h.uniforms, bands: trace.bands, ms,
      subpixels: k, maxTextureSize: this.renderer.maxTextureSize,
    };
  }
}
