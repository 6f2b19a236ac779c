// Settings: the lists and labels the client offers (kept here, in one place), URL
// parameters and the client-side levels (preview / full). The panel is panel.js; the
// form's limits are limits.js.
//
// The render settings themselves are the service's: GET /api/info's `settings` declares each
// one (renderer/config/settings.py: type, bounds or choices, default, label, whether the sheet offers
// it and whether the client carries it to a new session); the client names none of them here.
//
// Scene parameters (scenario, n, seed, radius) are fixed when a session is made,
// so changing them makes a new session; render settings are PATCHed onto the
// session; the preview/refine levels live in the client (localStorage).

// Used when the server does not offer its list (GET /api/info: methods).
export const FALLBACK_METHODS = Object.freeze(['bih', 'bruteforce']);
// A method's label: its declaration's (GET /api/info's method_settings), its name before the service answered.
export const methodLabel = (info, name) => (info && info.method_settings && info.method_settings[name] && info.method_settings[name].label) || name;
// The modes offered before the service answered (GET /api/info: modes, mode_labels).
export const FALLBACK_MODES = Object.freeze(['color']);
// A mode's label: the service's (renderer/modes.py MODE_LABELS), its name before the service answered.
export const modeLabel = (info, mode) => (info && info.mode_labels && info.mode_labels[mode]) || mode;
export const SCENARIOS = Object.freeze([
  { value: 1, label: '1 — grid' },
  { value: 2, label: '2 — eight corner clusters' },
  { value: 3, label: '3 — half grid, half clusters' },
  // A thesis scenario under the procedural daylight sky (POST /api/sessions {scenario, sky: true}).
  { value: 'sky:2', label: '2 under the sky (path)' },
  { value: 'museum', label: 'Museum — animated (Reiter)' },
  // Scenes of triangle meshes (POST /api/sessions {mesh_scene: {kind}}, renderer/scenes/scenarios.py).
  { value: 'mesh:teapot', label: 'Teapot — triangles (Newell)' },
  { value: 'mesh:mixed', label: 'Icosphere, torus and spheres' },
  { value: 'mesh:room', label: 'Mesh room' },
  { value: 'mesh:cornell', label: 'Cornell box (path)' },
  // Analytic shapes, no triangle (the same recipe: POST /api/sessions {mesh_scene: {kind: 'table'}}).
  { value: 'mesh:table', label: 'Table and lamp (shapes)' },
  // glTF materials on the project's own textures (POST /api/sessions {mesh_scene: {kind: 'materials'}}).
  { value: 'mesh:materials', label: 'Materials (path)' },
]);
// A mesh scene's kind ('mesh:teapot' → 'teapot'), or null for the sphere scenes: any kind the
// service's registry names (GET /api/info's scenes), not only those of the list above.
export const meshKind = (scenario) => (/^mesh:([a-z][a-z0-9_]*)$/.exec(String(scenario ?? '')) || [])[1] || null;

// The picker's scenes, in its order: GET /api/info's `scenes` (renderer/scenes/scenarios.py's registry:
// {value, label, settings}, `settings` the scene's recommended render settings) once it answered,
// SCENARIOS (no recommended settings) from a service that does not list them.
export const pickerScenes = SCENARIOS.map((x) => ({ ...x, settings: {} }));
// The scene a new session gets when neither a link nor this browser names one: the registry's
// `default` entry once the service listed its scenes, else DEFAULT_SCENE's.
let defaultValue = null;
export const defaultScenario = () => defaultValue ?? DEFAULT_SCENE.scenario;

// A scene value as the client keeps it: the thesis scenarios as numbers, the rest as text.
export const sceneValue = (v) => (/^\d+$/.test(String(v)) ? Number(v) : String(v));

// Take the service's list (info.scenes); a value that is no list, or an empty one, keeps the list held.
export function learnScenes(list) {
  if (!Array.isArray(list)) return false;
  const entries = list.filter((x) => x && (typeof x.value === 'string' || typeof x.value === 'number'))
    .map((x) => ({
      value: sceneValue(x.value), label: typeof x.label === 'string' && x.label ? x.label : String(x.value),
      settings: x.settings && typeof x.settings === 'object' ? { ...x.settings } : {},
    }));
  if (!entries.length) return false;
  const chosen = list.find((x) => x && x.default === true);
  defaultValue = chosen ? sceneValue(chosen.value) : null;
  pickerScenes.splice(0, pickerScenes.length, ...entries);
  return true;
}

export const sceneEntry = (value, scenes = pickerScenes) => scenes.find((x) => String(x.value) === String(value)) || null;

// The render settings a session of the scene `to` is made with when the picker changes the scene from
// `from` (entries of pickerScenes, or null): the session's own, with `to`'s recommended settings over
// them; what `from` recommended and `to` does not goes back to its declared default (the Cornell box's
// path integrator does not follow into a thesis scene); the link's own settings (`named`) win over
// both. With the path integrator at rest the denoiser is on (Intel Open Image Denoise), unless the
// scene, the link or the session chose another.
export function sceneSettings(render, from, to, named = {}, specs = renderSettings) {
  const out = { ...render };
  const rec = (to && to.settings) || {};
  for (const k of Object.keys((from && from.settings) || {})) {
    if (k in rec) continue;
    const spec = specs.find((x) => x.name === k);
    if (spec && spec.default !== undefined) out[k] = spec.default;
  }
  Object.assign(out, rec, named);
  return withRestDenoiser(out, { ...rec, ...named }, specs);
}

// `settings` with the denoiser on for the path integrator, unless `chosen` names `denoise` or the
// service offers no Open Image Denoise; the denoiser is for the resting image (previews stay fast,
// they are small).
export function withRestDenoiser(settings, chosen = {}, specs = renderSettings) {
  const spec = specs.find((x) => x.name === 'denoise');
  if (!spec || !Array.isArray(spec.choices) || !spec.choices.includes('oidn') || 'denoise' in chosen) return settings;
  if (settings.integrator !== 'path' || (settings.denoise !== undefined && settings.denoise !== 'off')) return settings;
  return { ...settings, denoise: 'oidn' };
}
// A sky scenario's number ('sky:2' → 2), or null for every other scene.
export const skyScenario = (scenario) => Number((/^sky:([123])$/.exec(String(scenario ?? '')) || [])[1]) || null;
// Model files the settings sheet uploads (POST /api/sessions/{id}/meshes?format=…), by suffix;
// zip: a model's folder (the model file with its .bin, .mtl and images).
export const MODEL_FORMATS = Object.freeze(['obj', 'ply', 'stl', 'glb', 'gltf', 'zip']);
// An uploaded model is fitted into this many world units, standing on the floor (the endpoint's size).
export const MODEL_SIZE = 20;
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
  { value: 'auto', label: 'Auto (≥ 15 fps)' },   // client.previewAuto: preview_size.js
  { value: 1, label: 'Full (no preview)' },
  { value: 0.5, label: '½' },
  { value: 1 / 3, label: '⅓' },
  { value: 0.25, label: '¼' },
]);

export const DEFAULT_SCENE = Object.freeze({ scenario: 1, n: 512, seed: 1, radius: 1, motion: 'deformable' });
// The museum's n counts moving spheres, on top of its room's 576: a thesis n of thousands would
// make a crowd (and a first frame of many seconds), so each kind keeps its own n.
export const DEFAULT_MUSEUM_N = 64;

// The panel's words for each setting: every message the client shows names settings by these. The
// render settings' words are the service's labels (GET /api/info, learnSettings).
export const FIELD_LABELS = {
  scenario: 'Scenario', motion: 'Motion', n: 'Spheres (n)', seed: 'Seed', radius: 'Radius',
  renderer: 'Rendered by', resolution: 'Full resolution', previewScale: 'While moving (preview)',
  previewFormat: 'Preview format', previewQuality: 'Preview JPEG quality', refineDelayMs: 'Refine after (ms)',
  model: 'Model',
};

// The render settings GET /api/info declares ([] until it answered, or from a service that does not).
export const renderSettings = [];

// Take the service's declarations (info.settings). The labels of those the sheet offers name them in
// every message (a 422 about another one is not about a field of the sheet: "Not accepted: …").
export function learnSettings(specs) {
  if (!Array.isArray(specs)) return;
  renderSettings.splice(0, renderSettings.length, ...specs.filter((x) => x && typeof x.name === 'string'));
  for (const x of renderSettings) if (x.sheet && x.label) FIELD_LABELS[x.name] = x.label;
}

// The names of the declared render settings that have `flag` (sheet: the settings sheet offers it;
// client: the client carries it to a new session), in the service's order.
export const settingNames = (flag, specs = renderSettings) => specs.filter((x) => x[flag]).map((x) => x.name);
export const settingSpec = (name, specs = renderSettings) => specs.find((x) => x.name === name) || null;

// A setting's value from the form's text (or a URL's), by its declared type; undefined when it is none.
export function settingValue(spec, text) {
  if (text === null || text === undefined || text === '') return undefined;
  switch (spec.type) {
    case 'integer': { const v = parseInt(text, 10); return Number.isFinite(v) ? v : undefined; }
    case 'number': { const v = parseFloat(text); return Number.isFinite(v) ? v : undefined; }
    case 'boolean': return text === true || text === 'true' ? true : text === false || text === 'false' ? false : undefined;
    default: return String(text);
  }
}
export const DEFAULT_CLIENT = Object.freeze({
  resolution: 'fit',       // 'fit' | 'WxH' | 'custom'
  previewAuto: true,       // server mode: the preview's scale from its measured rate (preview_size.js)
  previewScale: 0.5,       // else (and in device mode) preview resolution = full × this, while a gesture goes on
  previewFormat: 'jpeg',
  previewQuality: 70,
  fullFormat: 'png',
  fullQuality: 90,
  refineDelayMs: 200,      // full frame this long after the last gesture
  maxFitSide: 1088,        // 'fit': the long side at most this many pixels
  renderer: 'server',      // 'server' | 'device' (the same tracer in WebGL2)
});

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

// A setting's value from a link's text, checked against its declaration: {value} or {why} (the
// accepted values, in the panel's words).
export function checkSetting(spec, text) {
  const bounds = () => {
    const lo = spec.minimum ?? null, hi = spec.maximum ?? null;
    return lo !== null && hi !== null ? `${lo} … ${hi}` : lo !== null ? `≥ ${lo}` : hi !== null ? `≤ ${hi}` : 'any';
  };
  const kind = { integer: 'a whole number', number: 'a number', boolean: 'true or false' }[spec.type];
  let value;
  if (spec.type === 'integer') value = /^[+-]?\d+$/.test(text) ? parseInt(text, 10) : undefined;
  else if (spec.type === 'number') value = /^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i.test(text) ? parseFloat(text) : undefined;
  else value = settingValue(spec, text);
  if (value === undefined) return { why: `${kind || 'text'}${spec.type === 'boolean' ? '' : ` ${bounds()}`}` };
  if (spec.type === 'string' && spec.choices && !spec.choices.includes(value)) return { why: `one of ${spec.choices.join(', ')}` };
  if ((spec.minimum != null && value < spec.minimum) || (spec.maximum != null && value > spec.maximum)) {
    return { why: `${kind} ${bounds()}` };
  }
  return { value };
}

// The link's parameters that are not render settings: the scene's and this browser's.
const SCENE_PARAMS = ['scenario', 'n', 'seed', 'radius', 'motion'];
const CLIENT_PARAMS = ['preview_scale', 'preview_format', 'preview_quality', 'refine_ms', 'overlay', 'renderer'];

// URL parameters → {scene, render, client, ignored}: e.g. ?scenario=mesh:cornell&integrator=path&exposure=1
// &width=320&height=544&preview_scale=auto. Every render setting the service declares (`specs`: GET
// /api/info's settings) can be set, checked against its declaration (type, bounds, choices); the demo
// scenes by `scenario` (1, 2, 3, museum, mesh:teapot, …). width and height also make the resolution.
// `ignored`: [{name, value, why}] — the parameters not taken (a value out of range, a name that is
// nothing), for the page to say so; render settings are only judged once `specs` are known.
export function readUrlParams(search, specs = renderSettings) {
  const q = new URLSearchParams(search);
  const scene = {}, render = {}, client = {}, ignored = [];
  const skip = (name, why) => ignored.push({ name, value: q.get(name), why });
  const int = (k) => (/^[+-]?\d+$/.test(q.get(k)) ? parseInt(q.get(k), 10) : NaN);
  const f = (k) => (q.get(k) !== '' ? Number(q.get(k)) : NaN);
  if (q.has('scenario')) {
    const v = q.get('scenario'), known = sceneEntry(v);
    if (known) scene.scenario = known.value;
    else if (meshKind(v) && specs === renderSettings && !specs.length) scene.scenario = v;   // the service's list is on its way
    else skip('scenario', `one of ${pickerScenes.map((x) => x.value).join(', ')}`);
  }
  for (const k of ['n', 'seed']) {
    if (!q.has(k)) continue;
    if (int(k) >= (k === 'n' ? 1 : 0)) scene[k] = int(k);
    else skip(k, k === 'n' ? 'a whole number ≥ 1' : 'a whole number ≥ 0');
  }
  if (q.has('radius')) { if (f('radius') > 0) scene.radius = f('radius'); else skip('radius', 'a number > 0'); }
  if (q.has('motion')) {
    if (MUSEUM_KINDS.some((m) => m.value === q.get('motion'))) scene.motion = q.get('motion');
    else skip('motion', `one of ${MUSEUM_KINDS.map((m) => m.value).join(', ')}`);
  }
  for (const name of new Set(q.keys())) {
    if (SCENE_PARAMS.includes(name) || CLIENT_PARAMS.includes(name)) continue;
    const spec = specs.find((x) => x.name === name);
    if (!spec) {
      if (specs.length) skip(name, 'not a setting of this service');
      continue;
    }
    const r = checkSetting(spec, q.get(name));
    if (r.why) skip(name, r.why);
    else render[name] = r.value;
  }
  const side = (k) => parseInt(q.get(k), 10);
  if (side('width') && side('height')) client.resolution = `${side('width')}x${side('height')}`;
  if (q.has('preview_scale')) {
    if (q.get('preview_scale') === 'auto') client.previewAuto = true;
    else if (f('preview_scale') > 0 && f('preview_scale') <= 1) Object.assign(client, { previewScale: f('preview_scale'), previewAuto: false });
    else skip('preview_scale', 'auto, or a number > 0 and ≤ 1');
  }
  if (q.has('preview_format')) {
    if (['jpeg', 'png'].includes(q.get('preview_format'))) client.previewFormat = q.get('preview_format');
    else skip('preview_format', 'jpeg or png');
  }
  if (q.has('preview_quality')) {
    if (f('preview_quality') >= 1 && f('preview_quality') <= 100) client.previewQuality = Math.round(f('preview_quality'));
    else skip('preview_quality', 'a number 1 … 100');
  }
  if (q.has('refine_ms')) { if (f('refine_ms') >= 0) client.refineDelayMs = f('refine_ms'); else skip('refine_ms', 'a number ≥ 0'); }
  if (q.has('overlay')) client.overlay = q.get('overlay') !== '0';
  if (q.has('renderer')) {
    if (['server', 'device'].includes(q.get('renderer'))) client.renderer = q.get('renderer');
    else skip('renderer', 'server or device');
  }
  return { scene, render, client, ignored };
}

// The notice for a link's ignored parameters (readUrlParams), or null when there are none.
export function ignoredNotice(ignored) {
  if (!ignored || !ignored.length) return null;
  const label = (name) => (FIELD_LABELS[name] ? `${FIELD_LABELS[name]}: ` : '');
  return `Ignored in the link: ${ignored.map((x) => `${x.name}=${x.value} — ${label(x.name)}${x.why}`).join('; ')}.`;
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
