// Settings: the lists the client offers (kept here, in one place), URL
// parameters, the client-side levels (preview / full), and the settings panel.
//
// Scene parameters (scenario, n, seed, radius) are fixed when a session is made,
// so changing them makes a new session; render settings are PATCHed onto the
// session; the preview/refine levels live in the client (localStorage).

// Used when the server does not offer its list (GET /api/info: methods).
export const FALLBACK_METHODS = Object.freeze(['bih', 'bruteforce']);
export const METHOD_LABELS = Object.freeze({
  bih: 'BIH (thesis)', bruteforce: 'Brute force', auto: 'Auto (brute force below the crossover, else BIH)',
  rayengine: 'Ray engine (Carr)', hre: 'Hierarchical ray engine (Szécsi)', bvh: 'BVH (binned SAH)',
  kdtree: 'kd-tree (SAH)', twolevel: 'Two levels (kd-tree + BVH)',
});
export const MODES = Object.freeze(['color', 'depth', 'primid', 'normal', 'recursion', 'heat']);
export const MODE_LABELS = Object.freeze({
  color: 'Colour (Whitted)', depth: 'Depth', primid: 'Primitive id', normal: 'Normal',
  recursion: 'Recursion depth (Fig. 4.2f)', heat: 'Traversal heat (Fig. 4.3)', cones: 'Tile cones (hre only)',
});
export const SCENARIOS = Object.freeze([
  { value: 1, label: '1 — grid' },
  { value: 2, label: '2 — eight corner clusters' },
  { value: 3, label: '3 — half grid, half clusters' },
  { value: 'museum', label: 'Museum — animated (Reiter)' },
]);
// Motions of the animated museum (POST /api/sessions {museum: {n, kind}}); GET /api/info lists them too.
export const MUSEUM_KINDS = Object.freeze([
  { value: 'deformable', label: 'Deformable (a travelling wave)' },
  { value: 'rigid', label: 'Rigid groups' },
  { value: 'incoherent', label: 'Incoherent (spheres appear and vanish)' },
  { value: 'mixed', label: 'Mixed (a third each)' },
]);
// How bvh and twolevel follow an animation from one frame to the next (Reiter §3).
export const UPDATE_SCHEMES = Object.freeze([
  { value: 'rebuild', label: 'Rebuild every frame (thesis)' },
  { value: 'refit', label: 'Refit the tree' },
  { value: 'selective', label: 'Selective rebuild (+30 %)' },
]);
export const RESOLUTIONS = Object.freeze([
  { value: 'fit', label: 'Fit the screen' },
  { value: '640x1088', label: '640 × 1088 (thesis)' },
  { value: '320x544', label: '320 × 544' },
  { value: '1280x720', label: '1280 × 720' },
  { value: 'custom', label: 'Custom…' },
]);
export const PREVIEW_SCALES = Object.freeze([
  { value: 1, label: 'Full (no preview)' },
  { value: 0.5, label: '½' },
  { value: 1 / 3, label: '⅓' },
  { value: 0.25, label: '¼' },
]);

export const DEFAULT_SCENE = Object.freeze({ scenario: 1, n: 512, seed: 1, radius: 1, motion: 'deformable' });
export const DEFAULT_CLIENT = Object.freeze({
  resolution: 'fit',       // 'fit' | 'WxH' | 'custom'
  previewScale: 0.5,       // preview resolution = full × this, while a gesture goes on
  previewFormat: 'jpeg',
  previewQuality: 70,
  fullFormat: 'png',
  fullQuality: 90,
  refineDelayMs: 200,      // full frame this long after the last gesture
  maxFitSide: 1088,        // 'fit': the long side at most this many pixels
  renderer: 'server',      // 'server' | 'device' (the same tracer in WebGL2, issue #10)
});
export const RENDER_KEYS = Object.freeze(['method', 'mode', 'max_prims', 'max_tree_depth', 'max_recursion_depth', 'width', 'height',
  'update']);
const INT_KEYS = new Set(['scenario', 'n', 'seed', 'max_prims', 'max_tree_depth', 'max_recursion_depth', 'width', 'height']);

const CLIENT_KEY = 'pocketray.client';

export function loadClientSettings() {
  try {
    return { ...DEFAULT_CLIENT, ...JSON.parse(localStorage.getItem(CLIENT_KEY) || '{}') };
  } catch {
    return { ...DEFAULT_CLIENT };
  }
}

export function saveClientSettings(c) {
  try {
    localStorage.setItem(CLIENT_KEY, JSON.stringify(c));
  } catch { /* ignore */ }
}

// URL parameters → {scene, render, client}: e.g. ?scenario=2&n=128&width=320&height=544&preview_scale=0.5
export function readUrlParams(search) {
  const q = new URLSearchParams(search);
  const scene = {}, render = {}, client = {};
  const num = (k) => (INT_KEYS.has(k) ? parseInt(q.get(k), 10) : parseFloat(q.get(k)));
  for (const k of ['scenario', 'n', 'seed', 'radius']) if (q.has(k) && Number.isFinite(num(k))) scene[k] = num(k);
  if (q.get('scenario') === 'museum') scene.scenario = 'museum';
  if (MUSEUM_KINDS.some((m) => m.value === q.get('motion'))) scene.motion = q.get('motion');
  if (UPDATE_SCHEMES.some((m) => m.value === q.get('update'))) render.update = q.get('update');
  for (const k of ['max_prims', 'max_tree_depth', 'max_recursion_depth', 'width', 'height']) {
    if (q.has(k) && Number.isFinite(num(k))) render[k] = num(k);
  }
  for (const k of ['method', 'mode']) if (q.get(k)) render[k] = q.get(k);
  if (render.width && render.height) client.resolution = `${render.width}x${render.height}`;
  const f = (k) => parseFloat(q.get(k));
  if (q.has('preview_scale') && f('preview_scale') > 0 && f('preview_scale') <= 1) client.previewScale = f('preview_scale');
  if (['jpeg', 'png'].includes(q.get('preview_format'))) client.previewFormat = q.get('preview_format');
  if (q.has('preview_quality') && f('preview_quality') >= 1) client.previewQuality = Math.min(100, Math.round(f('preview_quality')));
  if (q.has('refine_ms') && f('refine_ms') >= 0) client.refineDelayMs = f('refine_ms');
  if (q.has('overlay')) client.overlay = q.get('overlay') !== '0';
  if (['server', 'device'].includes(q.get('renderer'))) client.renderer = q.get('renderer');
  return { scene, render, client };
}

// 'fit': the frame has the aspect of the screen area, at device pixels, long side ≤ maxSide.
export function fitResolution(cssW, cssH, dpr = 1, maxSide = 1088) {
  if (!(cssW > 0 && cssH > 0)) return { width: 640, height: 1088 };
  const k = Math.min(dpr || 1, maxSide / Math.max(cssW, cssH));
  return { width: Math.max(16, Math.round(cssW * k)), height: Math.max(16, Math.round(cssH * k)) };
}

export function parseResolution(value) {
  const m = /^(\d+)x(\d+)$/.exec(value || '');
  return m ? { width: Number(m[1]), height: Number(m[2]) } : null;
}

// The preview level's size: full × scale, at least 8 pixels a side.
export function previewSize(width, height, scale) {
  const s = scale > 0 && scale <= 1 ? scale : 1;
  return { width: Math.max(8, Math.round(width * s)), height: Math.max(8, Math.round(height * s)) };
}

function fillSelect(select, items, labelOf = (v) => v) {
  const cur = select.value;
  select.replaceChildren(...items.map((it) => {
    const o = document.createElement('option');
    const value = typeof it === 'object' ? it.value : it;
    o.value = String(value);
    o.textContent = typeof it === 'object' ? it.label : labelOf(it);
    return o;
  }));
  if (cur) select.value = cur;
}

// The panel. callbacks: onScene(scene), onRender(partial), onClient(partial).
export class SettingsPanel {
  constructor(root, openButton, callbacks) {
    this.root = root;
    this.openButton = openButton;
    this.cb = callbacks;
    this.form = root.querySelector('form');
    this.el = (name) => this.form.elements.namedItem(name);
    fillSelect(this.el('scenario'), SCENARIOS);
    fillSelect(this.el('motion'), MUSEUM_KINDS);
    fillSelect(this.el('update'), UPDATE_SCHEMES);
    fillSelect(this.el('method'), FALLBACK_METHODS, (m) => METHOD_LABELS[m] || m);
    fillSelect(this.el('mode'), MODES, (m) => MODE_LABELS[m] || m);
    fillSelect(this.el('resolution'), RESOLUTIONS);
    fillSelect(this.el('previewScale'), PREVIEW_SCALES);

    openButton.addEventListener('click', () => this.setOpen(!this.open));
    root.querySelector('[data-close]').addEventListener('click', () => this.setOpen(false));
    root.addEventListener('keydown', (e) => {
      if (e.key === 'Escape') this.setOpen(false);
    });
    this.form.addEventListener('submit', (e) => e.preventDefault());
    this.form.addEventListener('change', (e) => this._changed(e.target));
    this.setOpen(false);
  }

  setOpen(open) {
    this.open = open;
    this.root.hidden = !open;
    this.openButton.setAttribute('aria-expanded', String(open));
    if (open) this.el('scenario').focus({ preventScroll: true });
  }

  setMethods(list) {
    fillSelect(this.el('method'), list, (m) => METHOD_LABELS[m] || m);
  }

  setModes(list) {
    fillSelect(this.el('mode'), list, (m) => MODE_LABELS[m] || m);
  }

  // The service's limits (GET /api/info) as the form's bounds.
  setLimits(limits) {
    if (limits.max_spheres) this.el('n').max = String(limits.max_spheres);
    if (limits.max_image_side) {
      this.el('width').max = String(limits.max_image_side);
      this.el('height').max = String(limits.max_image_side);
    }
  }

  // Show the current state: {scene, render, client}.
  show({ scene, render, client }) {
    const set = (name, v) => {
      const el = this.el(name);
      if (el && v !== undefined && v !== null && document.activeElement !== el) el.value = String(v);
    };
    for (const k of ['scenario', 'n', 'seed', 'radius', 'motion']) set(k, scene[k]);
    this._museumVisible();
    for (const k of ['method', 'mode', 'max_prims', 'max_tree_depth', 'max_recursion_depth', 'update']) set(k, render[k]);
    const known = RESOLUTIONS.some((r) => r.value === client.resolution);
    set('resolution', known ? client.resolution : 'custom');
    set('width', render.width);
    set('height', render.height);
    this._customVisible();
    const scale = PREVIEW_SCALES.find((p) => Math.abs(p.value - client.previewScale) < 1e-6);
    if (!scale) {
      const o = document.createElement('option');
      o.value = String(client.previewScale);
      o.textContent = `×${client.previewScale}`;
      this.el('previewScale').append(o);
    }
    set('previewScale', scale ? scale.value : client.previewScale);
    set('previewFormat', client.previewFormat);
    set('previewQuality', client.previewQuality);
    set('refineDelayMs', client.refineDelayMs);
    set('renderer', client.renderer);
  }

  _museumVisible() {
    const museum = this.el('scenario').value === 'museum';
    for (const el of this.root.querySelectorAll('[data-museum]')) el.hidden = !museum;
  }

  _customVisible() {
    const custom = this.el('resolution').value === 'custom';
    for (const el of this.root.querySelectorAll('[data-custom-resolution]')) el.hidden = !custom;
  }

  _changed(target) {
    const name = target.name;
    if (!name || !target.checkValidity()) {
      target.reportValidity?.();
      return;
    }
    const v = target.value;
    const int = () => parseInt(v, 10);
    if (['scenario', 'n', 'seed', 'radius', 'motion'].includes(name)) {
      const f = this.form.elements;
      this._museumVisible();
      this.cb.onScene({
        scenario: f.scenario.value === 'museum' ? 'museum' : parseInt(f.scenario.value, 10), n: parseInt(f.n.value, 10),
        seed: parseInt(f.seed.value, 10), radius: parseFloat(f.radius.value), motion: f.motion.value,
      });
    } else if (['method', 'mode', 'update'].includes(name)) {
      this.cb.onRender({ [name]: v });
    } else if (['max_prims', 'max_tree_depth', 'max_recursion_depth'].includes(name)) {
      this.cb.onRender({ [name]: int() });
    } else if (name === 'resolution') {
      this._customVisible();
      if (v === 'custom') {
        this.cb.onClient({ resolution: 'custom' });
      } else {
        this.cb.onClient({ resolution: v });
      }
    } else if (name === 'width' || name === 'height') {
      this.cb.onClient({ resolution: 'custom' });
      this.cb.onRender({ [name]: int() });
    } else if (name === 'previewScale') {
      this.cb.onClient({ previewScale: parseFloat(v) });
    } else if (name === 'previewFormat') {
      this.cb.onClient({ previewFormat: v });
    } else if (name === 'previewQuality') {
      this.cb.onClient({ previewQuality: int() });
    } else if (name === 'refineDelayMs') {
      this.cb.onClient({ refineDelayMs: int() });
    } else if (name === 'renderer') {
      this.cb.onClient({ renderer: v });
    }
  }
}
