// The preview's size while a finger moves, from the measured rate (server mode): the client
// times each preview from its request to the image on screen and picks the linear scale of the
// next ones so that they keep coming at `targetMs` or faster (15 frames/s = 67 ms each; the
// default aims at 60 ms, a margin for the jitter of a shared machine and of a phone's network).
//
// The scale moves on a ladder of 2^(−1/4) steps (each one ≈ 0.71 × the pixels of the one above)
// between `min` and `max`, so that sizes do not wander from one frame to the next:
//  - down at once, as many steps as the measured time says (cost ∝ pixels ∝ scale²), when the
//    smoothed time is over the target;
//  - up one step at a time, only when the time predicted one step up is under `upShare` × the
//    target, after `settle` previews at the present step (hysteresis: a time just under the
//    target never toggles between two steps).
// A preview asked for at another scale than the present one (the scale changed meanwhile)
// is not counted. Pure (no DOM, no clock): the scheduler hands it the times.

export const LADDER_STEP = 2 ** -0.25;

export class PreviewSizer {
  constructor({ targetMs = 60, min = 0.125, max = 1, start = 0.25, upShare = 0.7, settle = 3, smoothing = 0.5 } = {}) {
    Object.assign(this, { targetMs, min, max, upShare, settle, smoothing });
    // Steps below 1: scale = 2^(−step/4) (exact at ½, ¼, ⅛).
    this.maxStep = Math.ceil(Math.log(min) / Math.log(LADDER_STEP) - 1e-9);
    this.minStep = Math.max(0, Math.floor(Math.log(max) / Math.log(LADDER_STEP) + 1e-9));
    this.step = this._clampStep(Math.round(Math.log(start) / Math.log(LADDER_STEP)));
    this.meanMs = null;   // smoothed time of the previews at this step
    this.count = 0;       // previews measured at this step
  }

  // The linear scale of the next preview (of the full frame's width and height).
  get scale() {
    return Math.max(this.min, Math.min(this.max, 2 ** (-this.step / 4)));
  }

  _clampStep(step) {
    return Math.max(this.minStep, Math.min(this.maxStep, step));
  }

  _move(step) {
    const next = this._clampStep(step);
    if (next === this.step) return false;
    this.step = next;
    this.meanMs = null;
    this.count = 0;
    return true;
  }

  // A preview at `scale` took `ms` from request to screen. Returns whether the scale changed.
  observe(ms, scale = this.scale) {
    if (!(ms > 0) || Math.abs(scale - this.scale) > 1e-9) return false;
    this.meanMs = this.meanMs === null ? ms : this.smoothing * ms + (1 - this.smoothing) * this.meanMs;
    this.count++;
    if (this.meanMs > this.targetMs) {
      // Pixels ∝ scale²: the steps down that bring the time to the target, at least one.
      const steps = Math.max(1, Math.ceil(Math.log(this.targetMs / this.meanMs) / (2 * Math.log(LADDER_STEP))));
      return this._move(this.step + steps);
    }
    if (this.count >= this.settle && this.meanMs / (LADDER_STEP * LADDER_STEP) < this.upShare * this.targetMs) {
      return this._move(this.step - 1);
    }
    return false;
  }
}
