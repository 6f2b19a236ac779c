// Latest-wins frame scheduling.
//
//  - At most one request in flight per client (gestures, frames, settings and
//    session changes all go through here, in order), with one exception: a gesture never waits
//    for a frame. When the transport's frames can be abandoned (transport.abortable(): the
//    service's, whose latest-wins cancels the frame a gesture supersedes), a gesture that arrives
//    while a frame is in flight aborts that frame and goes at once, so the first preview of a drag
//    follows the first touch as quickly as a preview of a resting view does. The abandoned frame's
//    answer is never shown; the gesture's own full frame follows it at rest.
//  - Gestures that arrive while one is in flight are merged: pan dx/dy add up,
//    pinch scales multiply, orbit yaw/pitch add up, a reset discards what came before it. When the
//    request returns, the merged gesture goes as one (one request per gesture
//    type that accumulated; only the last one asks for the frame).
//  - While the finger moves, frames come at the *preview* level (reduced
//    resolution, jpeg); `refineDelayMs` after the last gesture one *full* frame
//    (full resolution, png) replaces it.
//  - A new page or scene (`invalidate(true)`) shows a quick preview first, then the full frame,
//    when the transport says its previews are smaller (transport.quickFirst()).
//  - Each preview is timed from its request to the screen and the time handed to
//    transport.previewTaken(ms, frame) (the preview's size follows it: preview_size.js).
//  - While an animation plays, `animate()` asks for its next frame at the preview
//    level (gestures still go first); the full frame follows `refineDelayMs`
//    after the last one, when the animation is paused.
//  - Once the full frame is on screen and the transport says so (the path integrator), a
//    *refinement stream* follows: ever better frames of the resting view, each shown as it comes,
//    until its target; the next gesture, animation frame, full frame or task stops it first (it is
//    no request in flight: nothing waits for it).
//  - A frame is shown only when it is newer than the one on screen: a higher
//    request sequence number and a session version not lower than the shown one.
//
// No DOM and no fetch here: `transport` does the I/O, so this is unit-testable.
//   transport.gesture(op, level|null) → frame (level given) or anything (null)
//   transport.frame(level, onPreview, signal) → frame    level: 'preview' | 'full'; a progressive
//                                       frame hands its first image to onPreview first (optional);
//                                       `signal` aborts it (a gesture came)
//   transport.abortable()             → whether a frame in flight may be abandoned for a gesture (optional)
//   transport.refineNeeded()          → false when both levels are the same (optional)
//   transport.refinement()            → whether the view at rest is refined by a stream (optional)
//   transport.refinementStream(signal, onPart) → the stream's frames to onPart as they come; ends
//                                       when the stream does; `signal` stops it
//   onRefinement(progress|null)       → a stream's frame is on screen (its progress), or it stopped
//   transport.quickFirst()            → whether a first preview is worth it (optional)
//   transport.previewTaken(ms, frame) → a preview's time from request to screen (optional)
//   display(frame, level)             → shows it (may be async)
//   onError(error, what)              → what: 'gesture' | 'frame' | 'task'
// A frame is {version, ...anything display needs}.

export function emptyGesture() {
  return { reset: false, scale: 1, dx: 0, dy: 0, yaw: 0, pitch: 0 };
}

// Merge one gesture into an accumulated one (in place); returns it.
export function mergeGesture(acc, g) {
  if (g.type === 'reset') {
    acc.reset = true;
    acc.scale = 1;
    acc.dx = 0;
    acc.dy = 0;
    acc.yaw = 0;
    acc.pitch = 0;
  } else if (g.type === 'pinch') {
    if (Number.isFinite(g.scale) && g.scale > 0) acc.scale *= g.scale;
  } else if (g.type === 'pan') {
    acc.dx += g.dx || 0;
    acc.dy += g.dy || 0;
  } else if (g.type === 'orbit') {
    if (Number.isFinite(g.yaw)) acc.yaw += g.yaw;
    if (Number.isFinite(g.pitch)) acc.pitch += g.pitch;
  }
  return acc;
}

// The requests an accumulated gesture needs, in order (reset, orbit, pinch, pan). Yaw goes
// modulo a turn and pitch within ±180° (the service takes ±360° and clamps pitch at the poles).
export function gestureOps(acc, eps = 1e-6) {
  const ops = [];
  if (acc.reset) ops.push({ type: 'reset' });
  const yaw = ((acc.yaw % 360) + 540) % 360 - 180, pitch = Math.max(-180, Math.min(180, acc.pitch));
  if (Math.abs(yaw) > eps || Math.abs(pitch) > eps) ops.push({ type: 'orbit', yaw, pitch });
  if (Math.abs(acc.scale - 1) > eps) ops.push({ type: 'pinch', scale: acc.scale });
  if (Math.abs(acc.dx) > eps || Math.abs(acc.dy) > eps) ops.push({ type: 'pan', dx: acc.dx, dy: acc.dy });
  return ops;
}

export class FrameScheduler {
  constructor({
    transport, display, onError = () => {}, onIdle = () => {}, onRefinement = () => {}, refineDelayMs = 200, timers = null,
  }) {
    this.transport = transport;
    this.onRefinement = onRefinement;
    this.refining = null;       // the refinement stream on its way: its AbortController
    this.needStream = false;    // a refinement stream is due (the full frame is on screen)
    this.streamParts = 0;       // refinement frames shown
    this.display = display;
    this.onError = onError;
    this.onIdle = onIdle;
    this.refineDelayMs = refineDelayMs;
    this.timers = timers || {
      set: (fn, ms) => setTimeout(fn, ms),
      clear: (t) => clearTimeout(t),
      now: () => performance.now(),
    };
    this.pending = null;        // merged gestures not yet sent
    this.tasks = [];            // queued exclusive jobs (settings, sessions)
    this.needFull = false;      // a full frame is due
    this.needQuick = false;     // a quick preview is due before it (a new page or scene)
    this.needAnimation = false; // the next frame of a playing animation is due
    this.inFlight = false;
    this.flight = null;         // the frame in flight a gesture may abandon: {ctl}
    this.abandoned = 0;         // frames abandoned for a gesture
    this.refineTimer = null;
    this.lastGestureAt = -Infinity;
    this.seq = 0;               // sequence number of the last request made
    this.shownSeq = 0;          // … of the frame on screen
    this.shownVersion = null;   // session version of the frame on screen
    this.shownLevel = null;
    this.dropped = 0;           // late frames not shown
    this.requests = 0;
    this.paused = false;
  }

  get idle() {
    return !this.inFlight && !this.pending && this.tasks.length === 0 && !this.needFull && !this.needQuick &&
      !this.needAnimation && this.refineTimer === null;
  }

  // A gesture from the user: {type: 'pan', dx, dy} | {type: 'pinch', scale} | {type: 'orbit', yaw, pitch}
  // | {type: 'reset'}.
  gesture(g) {
    this.pending = mergeGesture(this.pending || emptyGesture(), g);
    if (gestureOps(this.pending).length === 0) this.pending = null;
    this.lastGestureAt = this.timers.now();
    this._cancelRefine();
    this._stopRefinement();
    if (this.pending) this._abandonFrame();
    this._pump();
  }

  // A gesture waits for no frame: the frame in flight (when the transport's frames may be
  // abandoned) is aborted and its place in flight given to the gesture.
  _abandonFrame() {
    const flight = this.flight;
    if (!flight || !(this.transport.abortable && this.transport.abortable())) return;
    this.flight = null;
    this.inFlight = false;
    this.abandoned++;
    flight.ctl.abort();
  }

  // The image on screen is out of date (settings changed, new session): render a full frame; with
  // `quick` (a new page or scene: nothing of it on screen yet) a preview first, when it is smaller.
  invalidate(quick = false) {
    this.needFull = true;
    if (quick && this.transport.quickFirst && this.transport.quickFirst()) this.needQuick = true;
    this._cancelRefine();
    this._stopRefinement();
    this._pump();
  }

  // A playing animation's next frame is due (preview level; the scene moved, not the camera).
  animate() {
    this.needAnimation = true;
    this.lastGestureAt = this.timers.now();
    this._cancelRefine();
    this._stopRefinement();
    this._pump();
  }

  // Run `fn` (async) when nothing else is in flight, before any later frame.
  // Resolves with fn's result (or rejects with its error, also given to onError).
  enqueue(fn) {
    return new Promise((resolve, reject) => {
      this.tasks.push({ fn, resolve, reject });
      this._stopRefinement();
      this._pump();
    });
  }

  // A new session: its versions start over, so forget the shown version.
  resetVersions() {
    this.shownVersion = null;
  }

  // Drop the gestures not sent yet (e.g. their session is gone).
  dropPending() {
    this.pending = null;
  }

  pause() {
    this.paused = true;
  }

  resume() {
    this.paused = false;
    this._pump();
  }

  _cancelRefine() {
    if (this.refineTimer !== null) {
      this.timers.clear(this.refineTimer);
      this.refineTimer = null;
    }
  }

  _scheduleRefine() {
    this._cancelRefine();
    const full = !this.transport.refineNeeded || this.transport.refineNeeded();
    if (!full && !this._streams()) return;
    const wait = Math.max(0, this.refineDelayMs - (this.timers.now() - this.lastGestureAt));
    this.refineTimer = this.timers.set(() => {
      this.refineTimer = null;
      if (full) this.needFull = true;
      else this.needStream = true;   // the preview is the full frame: the stream follows it at once
      this._pump();
    }, wait);
  }

  _streams() {
    return !!(this.transport.refinement && this.transport.refinement());
  }

  // The refinement stream of the view on screen: each frame shown as it comes (when nothing newer
  // is), until the stream ends or is stopped.
  _startRefinement() {
    this._stopRefinement();
    if (!this._streams()) return;
    const ctl = new AbortController();
    this.refining = ctl;
    const onPart = async (frame) => {
      if (ctl.signal.aborted) return;
      if (await this._offer(frame, ++this.seq, 'full')) {
        this.streamParts++;
        this.onRefinement(frame.refine || null);
      }
    };
    this.transport.refinementStream(ctl.signal, onPart).catch((e) => {
      if (!ctl.signal.aborted) this.onError(e, 'frame');
    }).finally(() => {
      if (this.refining === ctl) this.refining = null;
    });
  }

  _stopRefinement() {
    if (this.refining === null) return;
    this.refining.abort();
    this.refining = null;
    this.onRefinement(null);
  }

  // The first image of a progressive frame: shown when nothing newer is on screen, without
  // taking the request's place (its final image, same request, follows and replaces it).
  async _offerPreview(frame, seq, level) {
    if (seq <= this.shownSeq ||
        (frame.version != null && this.shownVersion != null && frame.version < this.shownVersion)) {
      this.dropped++;
      return false;
    }
    this.previews = (this.previews || 0) + 1;
    await this.display(frame, level);
    return true;
  }

  // Show `frame` if it is newer than the one on screen. Returns whether it was shown.
  async _offer(frame, seq, level) {
    if (seq <= this.shownSeq ||
        (frame.version != null && this.shownVersion != null && frame.version < this.shownVersion)) {
      this.dropped++;
      return false;
    }
    this.shownSeq = seq;
    if (frame.version != null) this.shownVersion = frame.version;
    this.shownLevel = level;
    await this.display(frame, level);
    return true;
  }

  // A preview asked for at `t0` is on screen: its time goes to the transport.
  _timed(t0, frame, shown) {
    if (shown && this.transport.previewTaken) this.transport.previewTaken(this.timers.now() - t0, frame);
  }

  // One frame at `level` (transport.frame), shown if it is still the newest; `timed`: a preview whose
  // time counts (a gesture's or an animation's, not a new scene's first one, which builds and compiles).
  // Returns false when a gesture abandoned it (the gesture holds the flight then).
  async _frame(level, timed = false) {
    this.inFlight = true;
    const flight = { ctl: new AbortController() };
    this.flight = flight;
    const seq = ++this.seq;
    try {
      this.requests++;
      const t0 = this.timers.now();
      const frame = await this.transport.frame(level, (preview) => !flight.ctl.signal.aborted && this._offerPreview(preview, seq, level), flight.ctl.signal);
      if (flight.ctl.signal.aborted) return false;
      if (frame) {   // null: cancelled by a gesture (device mode)
        const shown = await this._offer(frame, seq, level);
        if (timed) this._timed(t0, frame, shown);
      }
    } catch (e) {
      if (!flight.ctl.signal.aborted) this.onError(e, 'frame');
    } finally {
      if (this.flight === flight) {
        this.flight = null;
        this.inFlight = false;
      }
    }
    return !flight.ctl.signal.aborted;
  }

  async _pump() {
    if (this.inFlight || this.paused) return;
    if (this.tasks.length) {
      const { fn, resolve, reject } = this.tasks.shift();
      this.inFlight = true;
      try {
        resolve(await fn());
      } catch (e) {
        this.onError(e, 'task');
        reject(e);
      } finally {
        this.inFlight = false;
      }
      return this._pump();
    }
    if (this.pending) {
      const ops = gestureOps(this.pending);
      this.pending = null;
      this.needFull = false;  // the refine after this gesture will bring the full frame
      this.inFlight = true;
      const seq = ++this.seq;
      try {
        let frame = null;
        const t0 = this.timers.now();
        for (let i = 0; i < ops.length; i++) {
          const last = i === ops.length - 1;
          this.requests++;
          const r = await this.transport.gesture(ops[i], last ? 'preview' : null);
          if (last) frame = r;
        }
        if (frame) this._timed(t0, frame, await this._offer(frame, seq, 'preview'));   // null: nothing to show (device mode)
      } catch (e) {
        this.onError(e, 'gesture');
      } finally {
        this.inFlight = false;
      }
      if (!this.pending && !this.needAnimation) this._scheduleRefine();
      return this._pump();
    }
    if (this.needAnimation) {
      this.needAnimation = false;
      if (!(await this._frame('preview', true))) return undefined;   // a gesture took over
      if (!this.pending && !this.needAnimation) this._scheduleRefine();
      return this._pump();
    }
    if (this.needQuick) {
      this.needQuick = false;
      if (this.needFull && !(await this._frame('preview'))) return undefined;
      return this._pump();
    }
    if (this.needFull) {
      this.needFull = false;
      if (!(await this._frame('full'))) return undefined;
      if (!this.pending && !this.needAnimation && !this.needFull && !this.tasks.length) this.needStream = true;
      return this._pump();
    }
    if (this.needStream) {
      this.needStream = false;
      this._startRefinement();
    }
    if (this.idle) this.onIdle();
  }
}
