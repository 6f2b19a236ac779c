// How many rows the device traces per band (one band per requestAnimationFrame callback).
//
// A band is drawn and waited for (a one-pixel read-back) before the browser gets the main
// thread back, so its length is how long touch input can wait. The planner keeps a band
// near `budgetMs`: it learns the cost of a pixel from the bands drawn so far (an
// exponential average, since the cost changes with the view and the settings) and sizes
// the next band from it. Pure: no DOM, no GL (tests/browser/units/test_bands.mjs).

export const BAND_DEFAULTS = Object.freeze({
  budgetMs: 25,       // the longest a band should hold the main thread
  firstRows: 4,       // rows of the first band, before anything is known
  smoothing: 0.5,     // weight of the newest measurement
});

export class BandPlanner {
  constructor(options = {}) {
    this.o = { ...BAND_DEFAULTS, ...options };
    this.msPerPixel = null;
  }

  // Rows for the next band of a `width`-pixel-wide target with `remaining` rows to go.
  rows(width, remaining) {
    if (remaining <= 0) return 0;
    if (this.msPerPixel === null) return Math.min(this.o.firstRows, remaining);
    const rows = Math.floor(this.o.budgetMs / (this.msPerPixel * Math.max(1, width)));
    return Math.max(1, Math.min(remaining, rows));
  }

  // A band of `pixels` pixels took `ms`.
  record(pixels, ms) {
    if (!(pixels > 0) || !(ms >= 0)) return;
    const m = Math.max(ms, 0.01) / pixels;
    this.msPerPixel = this.msPerPixel === null ? m : this.o.smoothing * m + (1 - this.o.smoothing) * this.msPerPixel;
  }

  // The cost of a pixel changes with the data and settings (a new scene, depth, samples): start over.
  reset() {
    this.msPerPixel = null;
  }
}

// Whether a gesture should cancel the frame being traced ("latest wins"): a full frame
// always goes (a preview of the new view comes first); a preview that is past `keep` of
// its rows finishes, so a finger that never rests still sees frames.
export function cancelsFrame(job, keep = 0.5) {
  if (!job || job.done) return false;
  if (job.level !== 'preview') return true;
  return job.rowsDone < keep * job.rowsTotal;
}
