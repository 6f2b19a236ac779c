// The settings form's limits and which settings apply, from GET /api/info — so that the
// form refuses, before anything is sent, what the service would refuse, and says why in
// the panel's words with the accepted range (the service's own 422s are translated by
// messages.js). Pure: no DOM (tests/browser/units/test_limits.mjs).
//
// ctx = {info, scene: {scenario, n, …}, render: {width, height, samples_per_pixel,
//        max_recursion_depth, method, …}, animated, renderer} — the values as they would be
// with the change applied.

import { FIELD_LABELS, renderSettings, settingSpec } from '../settings.js';

// Used when the service does not describe its methods (an older service).
const FALLBACK_METHOD = Object.freeze({
  settings: ['max_prims', 'max_tree_depth'], modes: null, device: true, tests_every_sphere: false, update_schemes: ['rebuild'],
});
const FALLBACK_METHODS = Object.freeze({
  bih: FALLBACK_METHOD,
  bruteforce: { ...FALLBACK_METHOD, settings: [], tests_every_sphere: true },
});
const DEFAULT_LIMITS = Object.freeze({ max_image_side: 4096, max_spheres: 1 << 21, max_work: Infinity, max_bruteforce_work: Infinity });
const MUSEUM_ROOM = 576;            // renderer.scenes.animation.MUSEUM_ROOM_SPHERES, when /api/info does not say
const MUSEUM_N_MAX = (1 << 21) - 1024;  // server.api.schemas.MuseumRecipe.n's bound
const WHITTED_DEPTH = 8;            // renderer.limits.MAX_RECURSION_DEPTH, when /api/info does not say
// The path integrator's segments per sample (renderer/frame/cost.py), when /api/info does not say.
const DEFAULT_PATH = Object.freeze({ segments_limit: 6.58, segments_rate: 0.644 });

const fmt = (x) => (Number.isFinite(x) ? Math.floor(x).toLocaleString('en') : String(x));
const label = (name) => FIELD_LABELS[name] || name;

export function methodInfo(info, method) {
  const m = info && info.method_settings && info.method_settings[method];
  return m || FALLBACK_METHODS[method] || FALLBACK_METHOD;
}

function limitsOf(info) {
  return { ...DEFAULT_LIMITS, ...((info && info.limits) || {}) };
}

export function pathInfo(info) {
  return { ...DEFAULT_PATH, ...((info && info.path) || {}) };
}

const isPath = (render) => render.integrator === 'path';

// What setting `name` accepts, and means, for a frame of `render`'s integrator and mode: the service's
// declaration (GET /api/info's settings[].integrators, renderer/config/settings.py's IntegratorValues) —
// Whitted's samples are sub-pixel grids, the path integrator's any count of paths. Null when the
// service declares none.
export function integratorValues(name, ctx) {
  const specs = Array.isArray(ctx.info?.settings) ? ctx.info.settings : renderSettings;
  const by = settingSpec(name, specs)?.integrators;
  if (!by) return null;
  const own = by[ctx.render.integrator ?? 'whitted'];
  return own && (!own.modes || own.modes.includes(ctx.render.mode ?? 'color')) ? own : by.whitted || null;
}

// Sub-pixels per side of `spp` samples: k of a k × k grid where the integrator's samples are one, else 1.
export function subpixels(spp, ctx) {
  return integratorValues('samples_per_pixel', ctx)?.subpixel_grid ? Math.max(1, Math.round(Math.sqrt(spp))) : 1;
}

// Segments (rays, shadow rays included) one path sample is expected to trace at max_recursion_depth
// `depth`: renderer/frame/cost.py's path_segments, with /api/info's numbers.
export function pathSegments(depth, info) {
  const p = pathInfo(info), d = Math.max(1, Math.floor(depth));
  return Math.min(2 * d - 1, p.segments_limit - (p.segments_limit - 1) * p.segments_rate ** (d - 1));
}

// What the service's max_work caps (renderer/frame/cost.py's request_work): Whitted's width × height × depth ×
// samples (a ray tree's levels); a path frame's expected segments, width × height × samples × segments(depth).
export function requestWork(render, info, { spp = render.samples_per_pixel || 1, depth = render.max_recursion_depth || 1 } = {}) {
  const px = render.width * render.height;
  return isPath(render) ? px * spp * pathSegments(depth, info) : px * depth * spp;
}

// The sample counts the sheet offers for the integrator at hand (as declared; 1 until the service says).
export function sampleChoices(ctx) {
  return integratorValues('samples_per_pixel', ctx)?.offered || [1];
}

// The deepest max_recursion_depth the integrator allows (before the work cap).
export function maxDepth(ctx) {
  return integratorValues('max_recursion_depth', ctx)?.maximum ?? ((ctx.info && ctx.info.max_recursion_depth) || WHITTED_DEPTH);
}

// The most samples per pixel the integrator allows (before the work cap).
const maxSamples = (ctx) => {
  const v = integratorValues('samples_per_pixel', ctx);
  return v ? (v.maximum ?? Math.max(...(v.choices || [1]))) : Infinity;
};

// The deepest max_recursion_depth of the path integrator (what a Whitted refusal offers instead).
const pathDepth = (ctx) => integratorValues('max_recursion_depth', { ...ctx, render: { ...ctx.render, integrator: 'path', mode: 'color' } })?.maximum;

// Spheres the scene has (the museum's n counts moving ones, on top of its room).
export function sceneSpheres(ctx) {
  const museum = ctx.scene.scenario === 'museum';
  return (Number(ctx.scene.n) || 0) + (museum ? (ctx.info && ctx.info.museum_room_spheres) ?? MUSEUM_ROOM : 0);
}

// Whether a setting means anything for the scene, method and renderer at hand (else the panel hides it).
export function applies(name, ctx) {
  const museum = ctx.scene.scenario === 'museum';
  const mesh = /^mesh:/.test(String(ctx.scene.scenario ?? ''));   // a mesh scene: made by its kind alone
  const m = methodInfo(ctx.info, ctx.render.method);
  switch (name) {
    case 'motion': return museum;
    case 'radius': return !museum && !mesh;
    case 'n': case 'seed': return !mesh;
    case 'update': return !!ctx.animated && m.settings.includes('update');
    case 'max_prims': case 'max_tree_depth': case 'tile_size': return m.settings.includes(name);
    // How the path integrator's radiance is shown and denoised (Whitted's image is display values
    // already); both integrators' colour is refined while the camera rests (Whitted's by jittered slices).
    case 'tone_map': case 'exposure': case 'denoise':
      return ctx.render.integrator === 'path';
    case 'refine_samples': case 'refine_time_ms': case 'refine_noise':
      return (ctx.render.mode ?? 'color') === 'color';
    case 'previewFormat': case 'previewQuality':
      // The device draws its previews itself: no image format to choose.
      return ctx.renderer !== 'device' && (name === 'previewFormat' || ctx.client?.previewFormat === 'jpeg');
    default: return true;
  }
}

// The modes the method can draw (null: all of them).
export function modesOf(ctx) {
  return methodInfo(ctx.info, ctx.render.method).modes;
}

// Samples per pixel a frame of width × height at this depth can have (the path integrator's samples
// are paths, not sub-pixels: only the work cap bounds them).
export function samplesAllowed(ctx, values = sampleChoices(ctx)) {
  const L = limitsOf(ctx.info), r = ctx.render, path = isPath(r);
  return values.filter((s) => (path ? s <= maxSamples(ctx)
    : subpixels(s, ctx) * Math.max(r.width, r.height) <= L.max_image_side) &&
    requestWork(r, ctx.info, { spp: s }) <= L.max_work);
}

// {min, max, why} of a numeric setting, given the others in ctx.
export function range(name, ctx) {
  const L = limitsOf(ctx.info), r = ctx.render;
  const spp = r.samples_per_pixel || 1, k = subpixels(spp, ctx), d = r.max_recursion_depth || 1;
  const bf = methodInfo(ctx.info, r.method).tests_every_sphere;
  const spheres = sceneSpheres(ctx);
  switch (name) {
    case 'n': {
      const museum = ctx.scene.scenario === 'museum';
      const room = museum ? sceneSpheres({ ...ctx, scene: { ...ctx.scene, n: 0 } }) : 0;
      let max = museum ? Math.min(L.max_spheres - room, MUSEUM_N_MAX) : L.max_spheres;
      let why = museum ? `the room has ${fmt(room)} more and a scene at most ${fmt(L.max_spheres)}` : '';
      if (bf) {
        const m = Math.floor(L.max_bruteforce_work / (r.width * r.height * d)) - room;
        if (m < max) {
          max = m;
          why = `${label('method')} ${r.method} tests every sphere: at ${r.width} × ${r.height} and recursion depth ${d}`;
        }
      }
      return { min: museum ? 0 : 1, max, why };
    }
    case 'seed': return { min: 0, max: 2 ** 32 - 1 };
    case 'radius': return { min: 1e-6, max: 20 };
    case 'width': case 'height': {
      const other = name === 'width' ? r.height : r.width;
      const bySide = Math.floor(L.max_image_side / k);
      const byWork = Math.floor(L.max_work / (other * requestWork({ ...r, width: 1, height: 1 }, ctx.info)));
      const byBf = bf ? Math.floor(L.max_bruteforce_work / (other * d * spheres)) : Infinity;
      const max = Math.min(bySide, byWork, byBf);
      const why = max === bySide ? (k > 1 ? `at ${spp} samples per pixel (${k} × the side is traced, at most ${fmt(L.max_image_side)})` : '')
        : max === byWork ? `at ${label(name === 'width' ? 'height' : 'width').toLowerCase()} ${other}, recursion depth ${d} and ${spp} samples per pixel${isPath(r) ? ' (paths)' : ''}`
          : `${r.method} tests every sphere: at ${fmt(spheres)} spheres, ${label(name === 'width' ? 'height' : 'width').toLowerCase()} ${other} and recursion depth ${d}`;
      return { min: 8, max, why };
    }
    case 'max_recursion_depth': {
      // The deepest the work cap admits: a path's segments grow with depth but saturate, so count up.
      const top = maxDepth(ctx);
      let byWork = 0;
      while (byWork < top && requestWork(r, ctx.info, { depth: byWork + 1 }) <= L.max_work) byWork++;
      byWork = byWork === top ? Infinity : byWork;
      const byBf = bf ? Math.floor(L.max_bruteforce_work / (r.width * r.height * spheres)) : Infinity;
      const max = Math.min(top, byWork, byBf);
      const why = max === top ? (isPath(r) ? '' : `with the Whitted tracer (up to ${pathDepth(ctx)} with the path integrator)`)
        : max === byWork ? `at ${r.width} × ${r.height} and ${spp} samples per pixel`
        : `${r.method} tests every sphere: at ${fmt(spheres)} spheres and ${r.width} × ${r.height}`;
      return { min: 1, max, why };
    }
    case 'max_prims': return { min: 1, max: 1 << 24 };
    case 'max_tree_depth': return { min: 1, max: 64 };
    case 'tile_size': return { min: 2, max: 64 };
    case 'previewQuality': return { min: 1, max: 100 };
    case 'refineDelayMs': return { min: 0, max: 5000 };
    default: return null;
  }
}

const INTEGER = new Set(['n', 'seed', 'width', 'height', 'max_recursion_depth', 'max_prims', 'max_tree_depth', 'tile_size',
  'previewQuality', 'refineDelayMs']);

// What is wrong with setting `name` as ctx has it (null: nothing). `value` is the form's value.
export function check(name, value, ctx) {
  const rg = range(name, ctx);
  if (rg) {
    const x = Number(value);
    const ok = value !== '' && Number.isFinite(x) && (!INTEGER.has(name) || Number.isInteger(x)) &&
      x >= rg.min && x <= rg.max && (name !== 'radius' || x > 0);
    if (ok) return null;
    if (rg.max < rg.min) return `${label(name)}: no value fits ${rg.why}; change the others first`;
    const lo = name === 'radius' ? 'more than 0' : fmt(rg.min);
    const kind = INTEGER.has(name) ? 'a whole number ' : 'a number ';
    return `${label(name)}: ${kind}${lo} … ${fmt(rg.max)}${rg.why ? ` ${rg.why}` : ''}`;
  }
  if (name === 'samples_per_pixel') {
    const r = ctx.render, x = Number(value);
    if (isPath(r)) {
      // Any count of paths (a link may ask for one the sheet does not list), within the work cap.
      const L = limitsOf(ctx.info), top = maxSamples(ctx);
      if (Number.isInteger(x) && x >= 1 && x <= top && requestWork(r, ctx.info, { spp: x }) <= L.max_work) return null;
      const most = Math.min(top, Math.floor(L.max_work / requestWork(r, ctx.info, { spp: 1 })));
      return `${label(name)}: a whole number 1 … ${fmt(most)} for a ${r.width} × ${r.height} frame at recursion depth ` +
        `${r.max_recursion_depth} with the path integrator (at most ${fmt(L.max_work)} expected path segments a frame)`;
    }
    const allowed = samplesAllowed(ctx);
    if (allowed.includes(x)) return null;
    return `${label(name)}: ${allowed.join(', ') || 'none'} for a ${r.width} × ${r.height} frame at recursion depth ` +
      `${r.max_recursion_depth} (the traced frame may be at most ${fmt(limitsOf(ctx.info).max_image_side)} a side)`;
  }
  if (name === 'method') {
    const r = ctx.render, L = limitsOf(ctx.info), spheres = sceneSpheres(ctx);
    const work = r.width * r.height * r.max_recursion_depth * spheres;
    if (methodInfo(ctx.info, value).tests_every_sphere && work > L.max_bruteforce_work) {
      return `${label('method')}: ${value} tests every sphere, and ${r.width} × ${r.height} × recursion depth ` +
        `${r.max_recursion_depth} × ${fmt(spheres)} spheres is over the ${fmt(L.max_bruteforce_work)} it may trace; ` +
        'choose a method with a tree (bih) or lower the resolution, the depth or n';
    }
    return null;
  }
  if (name === 'mode') {
    const modes = modesOf(ctx);
    return !modes || modes.includes(value) ? null
      : `${label('mode')}: ${ctx.render.method} draws ${modes.join(', ')}`;
  }
  return null;
}
