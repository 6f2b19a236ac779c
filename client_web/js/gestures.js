// Gestures: Pointer Events, wheel and keys → pan / pinch / orbit / reset (the thesis's View).
//
// The recogniser is pure (no DOM): feed it pointer down/move/up with coordinates
// and timestamps and it calls back with
//   onPan(dx, dy)        one pointer moved by (dx, dy) CSS pixels (right/down positive)
//   onOrbitDrag(dx, dy)  the same, when the drag orbits: dragMode 'orbit', or a pointer that
//                        went down with {orbit: true} (the mouse's right button, shift-drag)
//   onPinch(scale)       two pointers: new distance / old distance (> 1 = spread = forward)
//   onTwist(degrees)     two pointers turned by this much (clockwise on screen positive),
//                        once they have turned by twistSlop since they went down
//   onReset()            double tap
//   onStart() / onEnd()  a gesture began / all pointers are up
// `attach()` wires it to an element's DOM events; wheelScale() and keyGesture()
// are the desktop mappings. Everything here is unit-testable without a server.

export const DEFAULTS = Object.freeze({
  dragSlop: 4,          // CSS px a single pointer must travel before it pans (taps stay taps)
  tapMaxMs: 300,        // a tap is down→up within this …
  tapSlop: 12,          // … and moves less than this (CSS px)
  doubleTapMs: 350,     // two taps within this …
  doubleTapSlop: 40,    // … and this far apart → reset
  minPinchDistance: 8,  // below this the two pointers are too close to measure a ratio or an angle
  twistSlop: 4,         // degrees two fingers must turn before they orbit (a pinch wobbles a little)
});

function dist(a, b) {
  return Math.hypot(a.x - b.x, a.y - b.y);
}

// Angle of the line a → b on screen, degrees (y down: clockwise positive).
function angle(a, b) {
  return Math.atan2(b.y - a.y, b.x - a.x) * (180 / Math.PI);
}

// a − b folded into (−180, 180]: the shorter turn.
export function turn(a, b) {
  let d = (a - b) % 360;
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  return d;
}

export class GestureRecognizer {
  constructor(handlers = {}, options = {}) {
    this.h = handlers;
    this.o = { ...DEFAULTS, ...options };
    this.pointers = new Map();   // id → {x, y, x0, y0, t0, panning, orbit}
    this.pinchDistance = null;   // distance of the two pointers at the last pinch event
    this.twistAngle = null;      // angle of the two pointers at the last twist event
    this.twistTotal = 0;         // turned since the two went down (for the slop)
    this.twisting = false;
    this.lastTap = null;         // {x, y, t}
    this.multi = false;          // more than one pointer took part since the first went down
    this.dragMode = 'pan';       // what one pointer does: 'pan' | 'orbit' (the toolbar's toggle)
  }

  get active() {
    return this.pointers.size > 0;
  }

  down(id, x, y, t, { orbit = false } = {}) {
    if (this.pointers.size === 0) {
      this.multi = false;
      this.h.onStart?.();
    }
    this.pointers.set(id, { x, y, x0: x, y0: y, t0: t, panning: false, orbit });
    if (this.pointers.size >= 2) {
      this.multi = true;
      this._resetPinch();
      this.twistTotal = 0;
      this.twisting = false;
    }
  }

  move(id, x, y /* , t */) {
    const p = this.pointers.get(id);
    if (!p) return;
    const px = p.x, py = p.y;
    p.x = x; p.y = y;
    if (this.pointers.size === 1) {
      if (this.multi) return;  // the rest of a pinch: no pan until every pointer is up
      const drag = p.orbit || this.dragMode === 'orbit' ? this.h.onOrbitDrag : this.h.onPan;
      if (!p.panning) {
        if (Math.hypot(x - p.x0, y - p.y0) < this.o.dragSlop) return;
        p.panning = true;
        drag?.(x - p.x0, y - p.y0);  // include the travel inside the slop
        return;
      }
      if (x !== px || y !== py) drag?.(x - px, y - py);
    } else if (this.pointers.size >= 2) {
      const [a, b] = this._two();
      const d = dist(a, b);
      if (this.pinchDistance === null || this.pinchDistance < this.o.minPinchDistance) {
        this.pinchDistance = d;
        this.twistAngle = d >= this.o.minPinchDistance ? angle(a, b) : null;
        return;
      }
      if (d >= this.o.minPinchDistance && d !== this.pinchDistance) {
        this.h.onPinch?.(d / this.pinchDistance);
        this.pinchDistance = d;
      }
      this._twist(a, b, d);
    }
  }

  // Two fingers turning about each other: degrees since the last event, after the slop.
  _twist(a, b, d) {
    if (d < this.o.minPinchDistance) return;
    const now = angle(a, b);
    if (this.twistAngle === null) {
      this.twistAngle = now;
      return;
    }
    const step = turn(now, this.twistAngle);
    if (step === 0) return;
    this.twistAngle = now;
    if (!this.twisting) {
      this.twistTotal += step;
      if (Math.abs(this.twistTotal) < this.o.twistSlop) return;
      this.twisting = true;
      this.h.onTwist?.(this.twistTotal);   // include the turn inside the slop
      return;
    }
    this.h.onTwist?.(step);
  }

  up(id, x, y, t) {
    const p = this.pointers.get(id);
    if (!p) return;
    if (x !== undefined) this.move(id, x, y, t);
    this.pointers.delete(id);
    if (this.pointers.size >= 2) this._resetPinch();
    if (this.pointers.size === 1) this.pinchDistance = null;
    if (this.pointers.size > 0) return;
    const isTap = !this.multi && !p.panning && t - p.t0 <= this.o.tapMaxMs &&
      Math.hypot(p.x - p.x0, p.y - p.y0) < this.o.tapSlop;
    this.h.onEnd?.();
    if (isTap) this._tap(p.x, p.y, t);
    else this.lastTap = null;
  }

  cancel(id) {
    if (!this.pointers.delete(id)) return;
    this.lastTap = null;
    if (this.pointers.size >= 2) this._resetPinch();
    if (this.pointers.size === 1) this.pinchDistance = null;
    if (this.pointers.size === 0) this.h.onEnd?.();
  }

  _tap(x, y, t) {
    const last = this.lastTap;
    if (last && t - last.t <= this.o.doubleTapMs && Math.hypot(x - last.x, y - last.y) <= this.o.doubleTapSlop) {
      this.lastTap = null;
      this.h.onReset?.();
    } else {
      this.lastTap = { x, y, t };
    }
  }

  _two() {
    const it = this.pointers.values();
    return [it.next().value, it.next().value];
  }

  _resetPinch() {
    const [a, b] = this._two();
    this.pinchDistance = dist(a, b);
    this.twistAngle = this.pinchDistance >= this.o.minPinchDistance ? angle(a, b) : null;
  }
}

// Wheel → dolly scale (> 1 = forward). A mouse notch (~100 px) is ×/÷ 1.2; a
// trackpad pinch arrives as wheel events with ctrlKey and small deltas, made
// more sensitive so that the fingers' spread matches the motion.
export function wheelScale(deltaY, deltaMode = 0, ctrlKey = false) {
  const px = deltaMode === 1 ? deltaY * 16 : deltaMode === 2 ? deltaY * 800 : deltaY;
  const k = ctrlKey ? 0.01 : 0.0018;
  const clamped = Math.max(-500, Math.min(500, px));
  return Math.exp(-clamped * k);
}

// Keys → gesture (or null). Arrows move the camera the arrow's way, so the scene
// moves the other way: ArrowRight is the same as dragging left by `step` pixels.
// Shift + arrow orbits the camera the arrow's way by KEY_ORBIT degrees.
export const KEY_ZOOM = 1.25;
export const KEY_ORBIT = 5;
export function keyGesture(key, step = 40, shift = false) {
  if (shift) {
    switch (key) {
      case 'ArrowLeft': return { type: 'orbit', yaw: -KEY_ORBIT, pitch: 0 };
      case 'ArrowRight': return { type: 'orbit', yaw: KEY_ORBIT, pitch: 0 };
      case 'ArrowUp': return { type: 'orbit', yaw: 0, pitch: -KEY_ORBIT };
      case 'ArrowDown': return { type: 'orbit', yaw: 0, pitch: KEY_ORBIT };
      default: break;
    }
  }
  switch (key) {
    case 'ArrowLeft': return { type: 'pan', dx: step, dy: 0 };
    case 'ArrowRight': return { type: 'pan', dx: -step, dy: 0 };
    case 'ArrowUp': return { type: 'pan', dx: 0, dy: step };
    case 'ArrowDown': return { type: 'pan', dx: 0, dy: -step };
    case '+': case '=': case 'Add': return { type: 'pinch', scale: KEY_ZOOM };
    case '-': case '_': case 'Subtract': case '\u2212': return { type: 'pinch', scale: 1 / KEY_ZOOM };
    case '0': case 'Home': return { type: 'reset' };
    default: return null;
  }
}

function isFormControl(el) {
  if (!el || !el.tagName) return false;
  const tag = el.tagName.toLowerCase();
  return tag === 'input' || tag === 'select' || tag === 'textarea' ||
    el.isContentEditable || !!el.closest?.('[data-no-gesture-keys]');
}

// Wire a recogniser to `el` (the render surface; it needs CSS touch-action: none).
// handlers: those of GestureRecognizer, plus onWheel(scale) and onKey(gesture).
// Returns {detach(), recognizer} (set recognizer.dragMode to switch one-finger drags).
export function attach(el, handlers, options = {}) {
  const rec = new GestureRecognizer(handlers, options);
  let safariScale = 1;
  const win = el.ownerDocument.defaultView;
  const on = (target, type, fn, opts) => {
    target.addEventListener(type, fn, opts);
    return () => target.removeEventListener(type, fn, opts);
  };
  const offs = [
    on(el, 'pointerdown', (e) => {
      if (e.pointerType === 'mouse' && e.button !== 0 && e.button !== 2) return;
      try { el.setPointerCapture(e.pointerId); } catch { /* synthetic pointers */ }
      // On a desktop the right button or shift orbits, whatever the toolbar's mode.
      const orbit = e.pointerType === 'mouse' && (e.button === 2 || e.shiftKey);
      rec.down(e.pointerId, e.clientX, e.clientY, e.timeStamp, { orbit });
      e.preventDefault();  // (this also stops the mouse's focus change: done by hand below)
      if (e.pointerType === 'mouse') el.focus?.({ preventScroll: true, focusVisible: false });
    }),
    on(el, 'pointermove', (e) => {
      if (!rec.pointers.has(e.pointerId)) return;
      // Coalesced events only refine the path; the net motion is the same.
      rec.move(e.pointerId, e.clientX, e.clientY, e.timeStamp);
      e.preventDefault();
    }),
    on(el, 'pointerup', (e) => rec.up(e.pointerId, e.clientX, e.clientY, e.timeStamp)),
    on(el, 'pointercancel', (e) => rec.cancel(e.pointerId)),
    on(el, 'lostpointercapture', (e) => rec.cancel(e.pointerId)),
    // Safari's gesture events: on iOS they duplicate the touch pointers (ignored, but
    // prevented so the page does not zoom); on a Mac trackpad they are the pinch.
    on(el, 'gesturestart', (e) => {
      e.preventDefault();
      safariScale = 1;
    }),
    on(el, 'gesturechange', (e) => {
      e.preventDefault();
      if (rec.pointers.size > 0 || !(e.scale > 0)) return;
      handlers.onWheel?.(e.scale / safariScale);
      safariScale = e.scale;
    }),
    on(el, 'wheel', (e) => {
      e.preventDefault();
      if (e.deltaY === 0) return;
      handlers.onWheel?.(wheelScale(e.deltaY, e.deltaMode, e.ctrlKey));
    }, { passive: false }),
    on(el, 'contextmenu', (e) => e.preventDefault()),
    on(win, 'keydown', (e) => {
      if (e.altKey || e.metaKey || e.ctrlKey) return;  // leave the browser's own zoom alone
      if (isFormControl(e.target)) return;
      const g = keyGesture(e.key, options.keyStep ?? 40, e.shiftKey);
      if (!g) return;
      e.preventDefault();
      handlers.onKey?.(g);
    }),
  ];
  return { detach: () => offs.forEach((off) => off()), recognizer: rec };
}
