// The service's refusals in the panel's words: which field of the form a 422 is about
// (its `loc`) and its message with the API's names (samples_per_pixel, …) replaced by the
// labels the panel shows, and server-side variable names left out — a phone user cannot
// set POCKETRAY_MAX_WORK. Pure (tests/browser/units/test_messages.mjs).

import { FIELD_LABELS } from '../settings.js';

// API name → the panel's words (longest names first, so that max_tree_depth is not cut by a shorter one).
const WORDS = [
  ['max_recursion_depth', 'recursion depth'], ['samples_per_pixel', 'samples per pixel'],
  ['max_tree_depth', 'max tree depth'], ['max_prims', 'max primitives per leaf'], ['tile_size', 'tile size'],
  ['min_weight', 'the ray cut-off ε'], ['update_threshold', 'the selective rebuild threshold'],
];

export function inPanelWords(text) {
  let out = String(text);
  out = out.replace(/\s*\(POCKETRAY_[A-Z_]+\)/g, '');            // "(POCKETRAY_MAX_WORK)"
  out = out.replace(/POCKETRAY_[A-Z_]+/g, 'the service\u2019s limit');
  for (const [api, words] of WORDS) out = out.replaceAll(api, words);
  out = out.replace(/method=(\w+)/g, 'method $1');
  return out;
}

// The form field a 422's loc names: its last part that is a setting of the panel.
export function fieldOf(loc) {
  if (!Array.isArray(loc)) return null;
  for (let i = loc.length - 1; i >= 0; i--) if (typeof loc[i] === 'string' && FIELD_LABELS[loc[i]]) return loc[i];
  return null;
}

// Why a chosen model file is not sent (null: send it): its suffix, its size against the
// service's body limit (POCKETRAY_MAX_BODY_BYTES, GET /api/info's limits.max_body_bytes).
export function modelFileProblem(name, size, format, formats, limit) {
  if (!formats.includes(format)) {
    return `${FIELD_LABELS.model}: ${name} is not a model file the service reads (${formats.map((f) => `.${f}`).join(', ')})`;
  }
  if (!size) return `${FIELD_LABELS.model}: ${name} is empty`;
  if (limit > 0 && size > limit) return `${FIELD_LABELS.model}: ${tooBig(size, limit)}`;
  return null;
}

const mb = (b) => (b >= 1e6 ? `${(b / 1e6).toFixed(1)} MB` : `${Math.ceil(b / 1e3)} kB`);
const tooBig = (size, limit) => `the file is too big (${mb(size)}; the service takes at most ${mb(limit)})`;

// A refused model upload in the panel's words, next to the file picker: 413 (too big), 422
// (not a model, too many triangles, …: the service's message without its field prefix).
export function explainUpload(e) {
  if (e && e.status === 413) {
    const d = typeof e.detail === 'string' ? e.detail : '';
    const m = /of (\d+) bytes exceeds the limit of (\d+) bytes/.exec(d);
    return { field: 'model', status: 413,
      text: `${FIELD_LABELS.model}: ${m ? tooBig(Number(m[1]), Number(m[2])) : 'the file is too big for the service'}` };
  }
  if (e && e.status === 422) {
    const d = e.detail;
    let msg = Array.isArray(d) && d.length ? String(d[0].msg ?? JSON.stringify(d[0])) : typeof d === 'string' ? d : JSON.stringify(d);
    msg = msg.replace(/^[\w.[\]]+: /, '');
    return { field: 'model', status: 422, text: `${FIELD_LABELS.model}: ${inPanelWords(msg)}` };
  }
  return { ...explain(e), field: 'model' };
}

// {field, text, status} for an error from api.js (an ApiError has status and detail).
export function explain(e) {
  if (!e || e.status === undefined) return { field: null, text: `Something went wrong: ${e && (e.message || e)}`, status: null };
  const d = e.detail;
  if (Array.isArray(d) && d.length) {   // FastAPI / the service's validation errors
    const first = d[0];
    const field = fieldOf(first.loc);
    let msg = String(first.msg ?? JSON.stringify(first));
    msg = msg.replace(/^[\w.[\]]+: /, '');   // the server's "settings.width: " prefix: the label says it
    const text = field ? `${FIELD_LABELS[field]}: ${inPanelWords(msg)}` : `Not accepted: ${inPanelWords(msg)}`;
    return { field, text, status: e.status };
  }
  const msg = typeof d === 'string' ? d : JSON.stringify(d);
  return { field: null, text: e.status === 422 ? `Not accepted: ${inPanelWords(msg)}` : `The service answered ${e.status}: ${inPanelWords(msg)}`, status: e.status };
}

// A 422 that refuses a frame for its cost — the service's cost cap ("width: at most 512"), or its
// work cap ("… = 30,660,941,349 exceeds the limit 37879808") — as the largest settings it accepts
// instead: {settings, text} (the partial to retry with, and the notice saying so), or null when the
// refusal is of another kind. A smaller frame keeps the aspect of `render` (both sides shrink).
export function fitRefused(e, render) {
  if (!e || e.status !== 422 || !Array.isArray(e.detail) || !render) return null;
  for (const d of e.detail) {
    const field = fieldOf(d.loc), msg = String(d.msg ?? '');
    if (!['width', 'height', 'samples_per_pixel'].includes(field)) continue;
    let ratio = null;
    const most = new RegExp(`${field}: at most ([\\d,]+)`).exec(msg);
    const cap = /= ([\d,]+) exceeds the limit ([\d,]+)/.exec(msg);
    const num = (t) => Number(t.replaceAll(',', ''));
    if (most && render[field] > 0) ratio = num(most[1]) / render[field];
    else if (cap) ratio = num(cap[2]) / num(cap[1]);
    if (!(ratio > 0 && ratio < 1)) continue;
    if (field === 'samples_per_pixel') {
      const spp = render.samples_per_pixel || 1;
      let best = most ? num(most[1]) : Math.floor(spp * ratio);
      if (render.integrator !== 'path') best = Math.floor(Math.sqrt(best)) ** 2;   // Whitted's √s × √s grid
      if (best < 1 || best >= spp) continue;
      return { settings: { samples_per_pixel: best }, text: `Too costly at ${spp} samples per pixel: ${best} instead.` };
    }
    // The service's "width: at most N" holds the height as it is (and "height" the width): the frame
    // may keep that many pixels, so with the aspect kept each side shrinks by the ratio's root.
    const k = Math.sqrt(ratio);
    const width = Math.floor(render.width * k), height = Math.floor(render.height * k);
    if (width < 8 || height < 8) continue;
    return {
      settings: { width, height },
      text: `Too costly at ${render.width} × ${render.height}: ${width} × ${height} instead.`,
    };
  }
  return null;
}
