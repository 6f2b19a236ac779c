// The frame scheduler's transport (frames.js): gestures and frame requests go to the service
// (api.js); in device mode this browser's tracer (device/device.js) draws the frames and the
// gestures still go to the service's Model. Each frame carries when it was asked for (t0) and
// with what (meta), which display.js shows.

import { ApiError } from './api.js';
import { sceneTime } from './clock.js';
import { previewSize } from './settings.js';
import { explain } from './ui/messages.js';

// The query of a frame at `level` ('full' | 'preview'); an animated scene's at the clock's time at `now`;
// a preview at `scale` of the full frame's width and height.
export function frameParams(state, level, now = performance.now(), scale = state.client.previewScale) {
  const r = state.render, c = state.client;
  const timed = state.anim.animated ? { time: sceneTime(state.anim, now) } : {};
  if (level === 'full') {
    const p = { width: r.width, height: r.height, format: c.fullFormat, ...timed };
    if (c.fullFormat === 'jpeg') p.quality = c.fullQuality;
    return p;
  }
  const { width, height } = previewSize(r.width, r.height, scale);
  const p = { width, height, format: c.previewFormat, ...timed };
  if (c.previewFormat === 'jpeg') p.quality = c.previewQuality;
  // The service's measured "interactive" profile (GET /api/info): cheaper rays while the finger moves.
  const fast = state.profiles && state.profiles.interactive;
  if (fast) {
    for (const k of ['max_recursion_depth', 'samples_per_pixel', 'min_weight']) {
      if (fast[k] === undefined) continue;
      p[k] = k === 'max_recursion_depth' ? Math.min(fast[k], r.max_recursion_depth || fast[k]) : fast[k];
    }
  }
  return p;
}

// What a frame asked for now will show (display.js describes the frame on screen with it).
export function requestMeta(state, level) {
  const r = state.render, fast = level === 'full' ? null : state.profiles && state.profiles.interactive;
  return {
    sessionId: state.sessionId, n: state.scene.n_spheres ?? state.scene.n, mode: r.mode, method: r.method,
    samples: (fast && fast.samples_per_pixel) ?? r.samples_per_pixel ?? 1, integrator: r.integrator ?? 'whitted',
    // the ray cut-off ε is Whitted's: a path's length is its depth and Russian roulette
    minWeight: r.integrator === 'path' ? null : (fast && fast.min_weight) ?? r.min_weight,
    scenario: state.scene.scenario, motion: state.scene.motion, triangles: state.scene.n_triangles || 0,
    meshes: state.scene.n_meshes || 0, shapes: state.scene.n_shapes || 0,
  };
}

// state, api, device (DeviceView); activity: the element lit while requests are out (after
// 250 ms); viewportHeight(): the frame's displayed height; pending(): whether gestures wait to
// be sent; onFallback(reason, redraw): device mode failed, the service draws from now on;
// sizer: the preview's scale from its measured rate (preview_size.js), used with client.previewAuto.
export class Transport {
  constructor({ state, api, device, activity, viewportHeight, pending, onFallback, sizer = null }) {
    Object.assign(this, { state, api, device, activity, viewportHeight, pending, onFallback, sizer });
    this.out = 0;
    this.activityTimer = null;
  }

  get deviceMode() {
    return this.state.client.renderer === 'device';
  }

  // The linear scale of the service's previews now.
  get previewScale() {
    const c = this.state.client;
    return c.previewAuto && this.sizer ? this.sizer.scale : c.previewScale;
  }

  // A preview at `scale` took `ms` from its request to the screen (the scheduler measures it).
  previewTaken(ms, frame) {
    if (this.sizer && this.state.client.previewAuto && !this.deviceMode && frame && frame.scale) this.sizer.observe(ms, frame.scale);
  }

  // Whether a new scene's (or page's) first frame should come as a small preview before the full
  // one: the service's previews are smaller than the frame (device mode draws its own).
  quickFirst() {
    return !this.deviceMode && this.previewScale < 1;
  }

  gesture(op, level) {
    const { state, api, device } = this;
    const body = op.type === 'pan' ? { ...op, viewport_height: this.viewportHeight() } : op;
    if (this.deviceMode) {  // the device draws; the server's Model follows (JSON answer, no frame)
      const seq = device.localSeq;
      return this.timed(() => api.gesture(state.sessionId, body, null)).then((r) => {
        if (level && !this.pending()) device.serverCamera(r, seq);
        return null;
      });
    }
    const meta = level ? requestMeta(state, level) : null;
    const scale = this.previewScale;
    return this.timed(() => api.gesture(state.sessionId, body, level ? frameParams(state, level, undefined, scale) : null), meta)
      .then((frame) => this.scaled(frame, level, scale));
  }

  // A preview frame is stamped with the scale it was asked at (what the sizer's time is of).
  scaled(frame, level, scale) {
    if (frame && level === 'preview') frame.scale = scale;
    return frame;
  }

  // Whether a frame in flight may be abandoned for a gesture: the service's may (the gesture's
  // request supersedes it there, latest wins); the device's tracer cancels its own bands.
  abortable() {
    return !this.deviceMode;
  }

  async frame(level, onPreview = null, signal = null) {
    const { state, api, device } = this;
    if (this.deviceMode) {
      if (state.anim.animated) sceneTime(state.anim, performance.now());   // the device's data is posed at state.anim.time
      try {
        return await device.frame(level, onPreview && level === 'full' ? onPreview : null);
      } catch (e) {
        if (e instanceof ApiError && e.status === 404) throw e;  // the session expired: handled as ever
        this.onFallback(e instanceof ApiError ? explain(e).text : (e.message || String(e)), false);  // frame below
      }
    }
    const meta = requestMeta(state, level);
    const scale = this.previewScale, params = frameParams(state, level, undefined, scale);
    // A path-traced view at rest starts from one sample per pixel, kept in the session's
    // accumulation: the refinement stream goes on from it, so the full-size image comes in the time
    // of one sample, not of the session's samples_per_pixel.
    if (level === 'full' && this.accumulates()) {
      Object.assign(params, { samples_per_pixel: 1, accumulate: 1 });
      meta.samples = 1;
    }
    // Full frames come progressively: the pixel centres first, then the supersampled image.
    const t0 = performance.now();
    const preview = onPreview && level === 'full' ? (f) => onPreview({ ...f, t0, meta }) : null;
    return this.timed(() => api.frame(state.sessionId, params, preview, signal), meta)
      .then((frame) => this.scaled(frame, level, scale));
  }

  // Whether the view at rest is refined by the service's stream (docs/API.md, "Refinement"): it
  // draws colour: the path integrator's, whose image gets better with every sample, or Whitted's,
  // whose edges do with every jittered slice of its sub-pixel grid.
  refinement() {
    const r = this.state.render;
    return !this.deviceMode && (r.mode ?? 'color') === 'color';
  }

  // Whether the full frame is the first sample of an accumulation the refinement stream goes on
  // with: the service's path-traced colour.
  accumulates() {
    const r = this.state.render;
    return this.refinement() && r.integrator === 'path';
  }

  // The refinement stream of the view on screen, at the full level: onPart(frame) for each of its
  // frames (frame.refine: the stream's progress); resolves when it ends, `signal` stops it.
  refinementStream(signal, onPart) {
    const { state, api } = this;
    const meta = requestMeta(state, 'full'), t0 = performance.now();
    const part = (f) => onPart({ ...f, t0, meta: { ...meta, samples: f.refine ? f.refine.samples : meta.samples } });
    return api.refine(state.sessionId, frameParams(state, 'full'), part, signal);
  }

  refineNeeded() {
    if (this.deviceMode) return false;
    const c = this.state.client;
    return this.previewScale < 1 || c.previewFormat !== c.fullFormat;
  }

  // fn() → a frame (or anything): stamped with t0 and meta, the activity indicator lit meanwhile.
  async timed(fn, meta) {
    const t0 = performance.now();
    if (this.out++ === 0) this.activityTimer = setTimeout(() => this.activity.classList.add('on'), 250);
    try {
      const frame = await fn();
      if (frame && frame.blob) {
        frame.t0 = t0;
        frame.meta = meta;
      }
      return frame;
    } finally {
      if (--this.out === 0) {
        clearTimeout(this.activityTimer);
        this.activity.classList.remove('on');
      }
    }
  }
}
