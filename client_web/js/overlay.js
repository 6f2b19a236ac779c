// The statistics overlay: frames/s, time to image (client total and the
// server's update (build) / upload / trace / encode from Server-Timing), BIH nodes and
// depth, method, n. The user can hide it; the choice is remembered.

const HIDDEN_KEY = 'pocketray.overlayHidden';

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

const fmtMs = (v) => (v == null || !Number.isFinite(v) ? '–' : v < 10 ? v.toFixed(1) : Math.round(v).toString());

export class Overlay {
  constructor(root, toggleButton) {
    this.root = root;
    this.toggle = toggleButton;
    this.meter = new FpsMeter();
    this.fields = {};
    for (const el of root.querySelectorAll('[data-field]')) this.fields[el.dataset.field] = el;
    let hidden = false;
    try {
      hidden = localStorage.getItem(HIDDEN_KEY) === '1';
    } catch { /* ignore */ }
    this.setHidden(hidden);
    toggleButton.addEventListener('click', () => this.setHidden(!this.hidden));
    this._timer = setInterval(() => this._set('fps', this._fpsText()), 500);
  }

  setHidden(hidden) {
    this.hidden = hidden;
    this.root.hidden = hidden;
    this.toggle.setAttribute('aria-pressed', String(!hidden));
    this.toggle.setAttribute('aria-label', hidden ? 'Show statistics' : 'Hide statistics');
    this.toggle.title = hidden ? 'Show statistics' : 'Hide statistics';
    try {
      localStorage.setItem(HIDDEN_KEY, hidden ? '1' : '0');
    } catch { /* ignore */ }
  }

  _set(name, text) {
    const el = this.fields[name];
    if (el && el.textContent !== text) el.textContent = text;
  }

  _fpsText() {
    const f = this.meter.fps(performance.now());
    return f == null ? '–' : f.toFixed(1);
  }

  // info: {level, width, height, clientMs, timing: {update, build, upload, trace, encode, total}, stats, method, n,
  //        version, time (an animation's scene time, s, or null), playing,
  //        renderedBy: 'server (<GL renderer>)' | 'device (WebGL2 <renderer>)'}
  frame(info) {
    this.meter.tick(performance.now());
    const t = info.timing || {};
    const s = info.stats || {};
    this._set('fps', this._fpsText());
    this._set('time', `${fmtMs(info.clientMs)} ms`);
    this._set('build', fmtMs(t.update ?? t.build));   // rebuild, refit or selective rebuild: the method's update
    this._set('upload', fmtMs(t.upload));
    this._set('trace', fmtMs(t.trace));
    this._set('encode', fmtMs(t.encode));
    const parts = ['build', 'upload', 'trace', 'encode'].map((k) => t[k]).filter(Number.isFinite);
    this._set('other', t.total != null ? fmtMs(Math.max(0, t.total - parts.reduce((x, y) => x + y, 0))) : '–');
    const net = info.clientMs != null && t.total != null ? Math.max(0, info.clientMs - t.total) : null;
    this._set('network', fmtMs(net));
    const nodes = s.inner_nodes != null || s.leaves != null
      ? `${s.inner_nodes ?? '–'} + ${s.leaves ?? '–'}` : '–';
    this._set('nodes', nodes);
    this._set('depth', s.depth_max != null ? String(s.depth_max) : '–');
    this._set('method', info.method || s.method || '–');
    this._set('n', info.n != null ? String(info.n) : '–');
    this._set('res', `${info.width}×${info.height} ${info.level === 'full' ? 'full' : 'preview'}`);
    this._set('version', info.version != null ? String(info.version) : '–');
    this._set('anim', info.time != null ? `${info.time.toFixed(2)} s${info.playing ? ' ▶' : ''}` : '–');
    const by = info.renderedBy || '–';   // long GPU names are cut here; the whole one is the title
    this._set('renderer', by.length > 34 ? `${by.slice(0, 33)}…)` : by);
    if (this.fields.renderer) this.fields.renderer.title = by;
  }
}
