// The statistics overlay: one line (frames/s · time to image) that a tap opens into the
// details — who rendered, the time split (server: update / upload / trace / encode /
// queue+read / network from Server-Timing; device: update / upload / trace in bands /
// display / data fetch), the tree, method, n, frame size, samples. Everything describes
// the frame on screen (display.js passes what that frame was rendered with), never the
// request still on its way. The user can hide it; both choices are remembered.

const HIDDEN_KEY = 'pocketray.overlayHidden';
const EXPANDED_KEY = 'pocketray.overlayExpanded';

// Frames per second over the frames shown in the last `windowMs`.
export class FpsMeter {
  constructor(windowMs = 2000) {
    this.windowMs = windowMs;
    this.times = [];
  }

  tick(t) {
    this.times.push(t);
    while (this.times.length > 2 && t - this.times[0] > this.windowMs) this.times.shift();
  }

  fps(now) {
    const ts = this.times.filter((t) => now - t <= this.windowMs);
    if (ts.length < 2) return null;
    return (ts.length - 1) / ((ts[ts.length - 1] - ts[0]) / 1000);
  }
}

export const fmtMs = (v) => (v == null || !Number.isFinite(v) ? '–' : v < 10 ? v.toFixed(1) : Math.round(v).toString());

function remembered(key) {
  try {
    return localStorage.getItem(key) === '1';
  } catch {
    return false;
  }
}

function remember(key, on) {
  try {
    localStorage.setItem(key, on ? '1' : '0');
  } catch { /* private mode */ }
}

export class Overlay {
  constructor(root, toggleButton) {
    this.root = root;
    this.toggle = toggleButton;
    this.summary = root.querySelector('#overlay-summary');
    this.details = root.querySelector('#overlay-details');
    this.meter = new FpsMeter();
    this.fields = {};
    this.lastMs = null;
    for (const el of root.querySelectorAll('[data-field]')) this.fields[el.dataset.field] = el;
    this.setHidden(remembered(HIDDEN_KEY));
    this.setExpanded(remembered(EXPANDED_KEY));
    toggleButton.addEventListener('click', () => this.setHidden(!this.hidden));
    this.summary.addEventListener('click', () => this.setExpanded(!this.expanded));
    this._timer = setInterval(() => this._tickFps(), 500);
  }

  setHidden(hidden) {
    this.hidden = hidden;
    this.root.hidden = hidden;
    this.toggle.setAttribute('aria-pressed', String(!hidden));
    this.toggle.setAttribute('aria-label', hidden ? 'Show statistics' : 'Hide statistics');
    this.toggle.title = hidden ? 'Show statistics' : 'Hide statistics';
    remember(HIDDEN_KEY, hidden);
  }

  // Compact (one line) or with the details.
  setExpanded(expanded) {
    this.expanded = expanded;
    this.details.hidden = !expanded;
    this.summary.setAttribute('aria-expanded', String(expanded));
    this.summary.title = expanded ? 'Statistics: tap to fold' : 'Statistics: tap for details';
    remember(EXPANDED_KEY, expanded);
  }

  _set(name, text) {
    const el = this.fields[name];
    if (el && el.textContent !== text) el.textContent = text;
  }

  _fpsText() {
    const f = this.meter.fps(performance.now());
    return f == null ? '–' : f.toFixed(1);
  }

  _tickFps() {
    this._set('fps', this._fpsText());
    // (the samples of a resting view are the counter's, at the foot of the frame)
    this._set('summary', `${this._fpsText()} fps · ${fmtMs(this.lastMs)} ms`);
  }

  // The times the rows say: the latest first image (a preview: gesture or request → screen), the
  // latest full frame (request → screen), and the refinement of the view at rest (its samples and
  // how long it has refined); a new first image starts the story over.
  _times(info) {
    if (info.refine) this.refined = info.refine;
    else if (info.level === 'full') {
      this.fullMs = info.clientMs;
      this.refined = null;
      this.lastMs = info.clientMs;
    } else {
      this.firstMs = info.clientMs;
      this.fullMs = null;
      this.refined = null;
      this.lastMs = info.clientMs;
    }
    this._set('time', this.firstMs != null ? `${fmtMs(this.firstMs)} ms` : '–');
    this._set('full', this.fullMs != null ? `${fmtMs(this.fullMs)} ms` : '–');
    const r = this.refined;
    this._set('refined', r ? `${r.samples} spp · ${(r.ms / 1000).toFixed(1)} s` : '–');
    const row = this.details.querySelector('[data-refined]');
    if (row) row.hidden = !r;
  }

  // info: {level, width, height, clientMs, timing, stats, method, n, version, samples, minWeight,
  //        time (an animation's scene time, s, or null), playing, renderer: 'server' | 'device',
  //        renderedBy: 'server (<GL renderer>)' | 'device (WebGL2 <renderer>)'}
  frame(info) {
    this.meter.tick(performance.now());
    const t = info.timing || {};
    const s = info.stats || {};
    const device = info.renderer === 'device';
    this._times(info);
    for (const row of this.details.querySelectorAll('[data-for]')) row.hidden = row.dataset.for !== (device ? 'device' : 'server');
    this._tickFps();
    this._set('build', fmtMs(t.update ?? t.build));   // rebuild, refit or selective rebuild: the method's update
    this._set('upload', fmtMs(t.upload));
    this._set('trace', fmtMs(t.trace));
    if (device) {
      this._set('bands', t.bands != null ? String(t.bands) : '–');
      this._set('display', fmtMs(t.display));
      this._set('network', fmtMs(t.network));   // the data's fetch (with the server's build)
    } else {
      this._set('encode', fmtMs(t.encode));
      const parts = ['build', 'upload', 'trace', 'encode'].map((k) => t[k]).filter(Number.isFinite);
      this._set('other', t.total != null ? fmtMs(Math.max(0, t.total - parts.reduce((x, y) => x + y, 0))) : '–');
      // a refinement frame's clientMs is the stream's age: no network time can be told from it
      const net = !info.refine && info.clientMs != null && t.total != null ? Math.max(0, info.clientMs - t.total) : null;
      this._set('network', fmtMs(net));
    }
    const netLabel = this.details.querySelector('[data-label="network"]');
    if (netLabel) netLabel.textContent = device ? 'data fetch' : 'network';
    const nodes = s.inner_nodes != null || s.leaves != null ? `${s.inner_nodes ?? '–'} + ${s.leaves ?? '–'}` : '–';
    this._set('nodes', nodes);
    this._set('depth', s.depth_max != null ? String(s.depth_max) : '–');
    this._set('method', info.method || s.method || '–');
    this._set('n', info.n != null ? String(info.n) : '–');
    // A scene of triangles or shapes says their counts; its spheres only when it has some.
    const rows = (sel, show) => { const row = this.details.querySelector(sel); if (row) row.hidden = !show; };
    rows('[data-spheres]', !!info.n || !(info.triangles || info.shapes));
    rows('[data-meshes]', !!info.triangles);
    rows('[data-shapes]', !!info.shapes);
    this._set('triangles', info.triangles ? String(info.triangles) : '–');
    this._set('shapes', info.shapes ? String(info.shapes) : '–');
    this._set('res', `${info.width}×${info.height} ${info.level === 'full' ? 'full' : 'preview'}`);
    this._set('samples', info.samples != null
      ? `${info.samples} spp${info.minWeight != null ? `, ε ${info.minWeight}` : ''}` : '–');
    this._set('version', info.version != null ? String(info.version) : '–');
    this._set('anim', info.time != null ? `${info.time.toFixed(2)} s${info.playing ? ' ▶' : ''}` : '–');
    const by = info.renderedBy || '–';   // one short line; the whole name is the title
    this._set('renderer', info.renderedShort || by);
    if (this.fields.renderer) this.fields.renderer.title = by;
  }
}
