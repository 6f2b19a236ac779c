// Wiring: the View of the thesis's MVC. Gestures go to the service (the
// Controller updates the Model's camera) and the frame it renders comes back.
//
// Test hook: window.pocketray exposes what tests observe (frameCount,
// lastFrameVersion, lastFrame, sessionId, errors, notices, status, idle, …).

import { Api, ApiError, loadStoredSession, storeSession, sameScene } from './api.js';
import { attach } from './gestures.js';
import { FrameScheduler } from './frames.js';
import { Overlay } from './overlay.js';
import { Legend } from './legend.js';
import { Hint } from './hint.js';
import { Banner, Notices } from './notices.js';
import { explain, explainUpload } from './messages.js';
import { DeviceView } from './device.js';
import { SettingsPanel } from './panel.js';
import {
  DEFAULT_SCENE, FALLBACK_METHODS, MODEL_SIZE, RENDER_KEYS, fitResolution, loadClientSettings, meshKind, parseResolution,
  previewSize, readUrlParams, saveClientSettings,
} from './settings.js';

const $ = (sel) => document.querySelector(sel);
const canvas = $('#view');
const ctx = canvas.getContext('2d');
const stage = $('#stage');

// A one-finger orbit drag turns the camera this many degrees per height of the frame on screen.
const ORBIT_DEGREES_PER_VIEW = 180;

const url = readUrlParams(location.search);
const state = {
  sessionId: null,
  session: null,                // the adopted SessionOut (to go back to when a new scene is refused)
  scene: { ...DEFAULT_SCENE },
  render: null,                 // the session's full settings (from the server)
  client: { dragMode: 'pan', ...loadClientSettings(), ...url.client },
  methods: [...FALLBACK_METHODS],
  profiles: null,
  // An animated scene's clock (seconds of scene time): frames are posed at `time`;
  // while playing, time = time0 + wall-clock seconds since clock0.
  anim: { animated: false, playing: false, time: 0, time0: 0, clock0: 0 },
};
// A new scene whose first frame has not been shown yet: {prev: SessionOut, id}. If the service
// refuses to render it (422, e.g. too heavy), the client goes back to the previous session.
let pendingScene = null;

// ---- test hook --------------------------------------------------------------------
const hook = {
  frameCount: 0,
  lastFrameVersion: null,
  lastFrame: null,
  sessionId: null,
  errors: [],
  notices: [],
  log: [],                      // the last frames shown: level, size, content type, version
  status: 'starting',
  state,
  get idle() { return scheduler.idle && device.idle && hook.status === 'ready'; },
  get requests() { return scheduler.requests; },
  get dropped() { return scheduler.dropped; },
};
window.pocketray = hook;

// ---- notices and the error banner ----------------------------------------------------
const notices = new Notices($('#notice'), (n) => hook.notices.push(n));
const notice = (text, kind, ms) => notices.show(text, kind, ms);

// A refusal goes next to the field that caused it when the sheet shows it, else to a notice.
function recordError(e, what) {
  const ex = explain(e);
  const entry = { what, status: ex.status, message: ex.text, field: ex.field };
  hook.errors.push(entry);
  entry.inline = panel.refused(ex);
  if (!entry.inline) notice(ex.text, 'error', 8000);
}

const banner = new Banner($('#banner'), { onRetry: () => api.retryNow() });
function onStatus(s) {
  if (s.state === 'online') {
    if (banner.shown && hook.status === 'offline') notice('Connected to the render service again.');
    banner.hide();
    hook.status = state.render ? 'ready' : 'starting';
    return;
  }
  hook.status = s.state;  // 'offline' | 'busy'
  banner.show(s);
}

const api = new Api({ onStatus });
window.addEventListener('online', () => api.retryNow());

// ---- the animation clock ---------------------------------------------------------------
// The scene time of the next frame (ms resolution), kept in state.anim.time.
function animTime() {
  const a = state.anim;
  if (a.playing) a.time = Math.round((a.time0 + (performance.now() - a.clock0) / 1000) * 1000) / 1000;
  return a.time;
}

const playButton = $('#play-button');
function setPlaying(playing) {
  const a = state.anim;
  if (playing && !a.animated) return;
  if (playing && !a.playing) {
    a.time0 = a.time;
    a.clock0 = performance.now();
  } else if (!playing && a.playing) {
    animTime();
  }
  a.playing = playing;
  // The icon (style.css, by aria-pressed) and the label say what a press does next.
  playButton.setAttribute('aria-pressed', String(playing));
  const label = playing ? 'Pause the animation' : 'Play the animation';
  playButton.setAttribute('aria-label', label);
  playButton.title = `${label} (space)`;
  playButton.querySelector('[data-label]').textContent = playing ? 'Pause' : 'Play';
  if (playing && state.render) scheduler.animate();
}
playButton.addEventListener('click', () => setPlaying(!state.anim.playing));
window.addEventListener('keydown', (e) => {
  if (e.key !== ' ' || !state.anim.animated || e.target.closest?.('input, select, textarea, button, [data-no-gesture-keys]')) return;
  e.preventDefault();
  setPlaying(!state.anim.playing);
});

// ---- frames -------------------------------------------------------------------------
function frameParams(level) {
  const r = state.render, c = state.client;
  const timed = state.anim.animated ? { time: animTime() } : {};
  if (level === 'full') {
    const p = { width: r.width, height: r.height, format: c.fullFormat, ...timed };
    if (c.fullFormat === 'jpeg') p.quality = c.fullQuality;
    return p;
  }
  const { width, height } = previewSize(r.width, r.height, c.previewScale);
  const p = { width, height, format: c.previewFormat, ...timed };
  if (c.previewFormat === 'jpeg') p.quality = c.previewQuality;
  // The service's measured "interactive" profile (GET /api/info): cheaper rays while the finger moves.
  const fast = state.profiles && state.profiles.interactive;
  if (fast) {
    for (const k of ['max_recursion_depth', 'samples_per_pixel', 'min_weight']) {
      if (fast[k] === undefined) continue;
      p[k] = k === 'max_recursion_depth' ? Math.min(fast[k], r.max_recursion_depth || fast[k]) : fast[k];
    }
  }
  return p;
}

// What a frame asked for now will show: the overlay and the legend describe the frame on
// screen with it, not the settings of a request still on its way.
function requestMeta(level) {
  const r = state.render, fast = level === 'full' ? null : state.profiles && state.profiles.interactive;
  return {
    sessionId: state.sessionId, n: state.scene.n_spheres ?? state.scene.n, mode: r.mode, method: r.method,
    samples: (fast && fast.samples_per_pixel) ?? r.samples_per_pixel ?? 1, minWeight: (fast && fast.min_weight) ?? r.min_weight,
    scenario: state.scene.scenario, motion: state.scene.motion, triangles: state.scene.n_triangles || 0,
    meshes: state.scene.n_meshes || 0,
  };
}

// Where the frame is drawn inside the stage (object-fit: contain), CSS pixels.
function displayedSize() {
  const cw = stage.clientWidth || window.innerWidth, ch = stage.clientHeight || window.innerHeight;
  const a = state.render ? state.render.width / state.render.height : cw / ch;
  return cw / ch > a ? { width: ch * a, height: ch } : { width: cw, height: cw / a };
}

let activity = 0, activityTimer = null;
async function timed(fn, meta) {
  const t0 = performance.now();
  if (activity++ === 0) activityTimer = setTimeout(() => $('#activity').classList.add('on'), 250);
  try {
    const frame = await fn();
    if (frame && frame.blob) {
      frame.t0 = t0;
      frame.meta = meta;
    }
    return frame;
  } finally {
    if (--activity === 0) {
      clearTimeout(activityTimer);
      $('#activity').classList.remove('on');
    }
  }
}

const deviceMode = () => state.client.renderer === 'device';

const transport = {
  gesture(op, level) {
    const body = op.type === 'pan' ? { ...op, viewport_height: displayedSize().height } : op;
    if (deviceMode()) {  // the device draws; the server's Model follows (JSON answer, no frame)
      const seq = device.localSeq;
      return timed(() => api.gesture(state.sessionId, body, null)).then((r) => {
        if (level && !scheduler.pending) device.serverCamera(r, seq);
        return null;
      });
    }
    const meta = level ? requestMeta(level) : null;
    return timed(() => api.gesture(state.sessionId, body, level ? frameParams(level) : null), meta);
  },
  async frame(level, onPreview = null) {
    if (deviceMode()) {
      if (state.anim.animated) animTime();   // the device's data is posed at state.anim.time
      try {
        return await device.frame(level, onPreview && level === 'full' ? onPreview : null);
      } catch (e) {
        if (e instanceof ApiError && e.status === 404) throw e;  // the session expired: handled as ever
        fallBackToServer(e instanceof ApiError ? explain(e).text : (e.message || String(e)), false);  // frame below
      }
    }
    const meta = requestMeta(level);
    // Full frames come progressively: the pixel centres first, then the supersampled image.
    const t0 = performance.now();
    const preview = onPreview && level === 'full' ? (f) => onPreview({ ...f, t0, meta }) : null;
    return timed(() => api.frame(state.sessionId, frameParams(level), preview), meta);
  },
  refineNeeded() {
    if (deviceMode()) return false;
    const c = state.client;
    return c.previewScale < 1 || c.previewFormat !== c.fullFormat;
  },
};

const legend = new Legend($('#legend'));

async function display(frame, level) {
  const bitmap = frame.image || await createImageBitmap(frame.blob);  // image: the device's canvas
  if (canvas.width !== bitmap.width || canvas.height !== bitmap.height) {
    canvas.width = bitmap.width;
    canvas.height = bitmap.height;
  }
  ctx.drawImage(bitmap, 0, 0);
  if (!frame.image) bitmap.close?.();
  const meta = frame.meta || {};
  if (pendingScene && meta.sessionId === pendingScene.id) pendingScene = null;   // the new scene is on screen
  const clientMs = performance.now() - frame.t0;
  const renderer = frame.renderer || 'server';
  const renderedBy = renderer === 'device' ? `device (${frame.rendererInfo})` : `server (${hook.serverRenderer || 'OpenGL'})`;
  const n = frame.stats?.n_spheres ?? meta.n;
  const method = frame.method || meta.method;
  hook.frameCount++;
  hook.lastFrameVersion = frame.version;
  hook.lastFrame = {
    level, width: canvas.width, height: canvas.height, version: frame.version,
    contentType: frame.contentType, method, timing: frame.timing, stats: frame.stats, clientMs,
    renderer, renderedBy, n, mode: meta.mode, samples: meta.samples, camera: frame.camera ?? null,
    part: frame.part || 'final',
  };
  hook.log.push({
    level, width: canvas.width, height: canvas.height, contentType: frame.contentType, version: frame.version, renderer,
    camera: frame.camera ?? null, part: frame.part || 'final', clientMs,
  });
  if (hook.log.length > 100) hook.log.shift();
  const shownTime = frame.stats && Number.isFinite(frame.stats.time) ? frame.stats.time : null;
  hook.lastFrame.time = shownTime;
  const mode = meta.mode || state.render.mode;
  // (the device's frames are of the data it fetched for the scene as it is now)
  const triangles = frame.stats?.n_triangles ?? meta.triangles ?? (renderer === 'device' ? state.scene.n_triangles : 0) ?? 0;
  hook.lastFrame.triangles = triangles;
  const withTriangles = triangles ? `, ${triangles} triangles in ${meta.meshes || 1} mesh${meta.meshes > 1 ? 'es' : ''}` : '';
  const kind = meshKind(meta.scenario);
  canvas.setAttribute('aria-label', meta.scenario === 'museum'
    ? `Ray-traced animated museum: ${n} spheres (${meta.motion}), ${mode} mode`
    : kind ? `Ray-traced mesh scene: ${kind}, ${n} spheres${withTriangles}, ${mode} mode`
      : `Ray-traced scene: scenario ${meta.scenario ?? state.scene.scenario}, ${n} spheres${withTriangles}, ${mode} mode`);
  legend.show(mode === 'recursion' || mode === 'heat' ? mode : null);
  overlay.frame({
    level, width: canvas.width, height: canvas.height, clientMs, timing: frame.timing, stats: frame.stats,
    method, n, triangles, version: frame.version, renderedBy, renderer, samples: meta.samples, minWeight: meta.minWeight,
    time: state.anim.animated ? shownTime : null, playing: state.anim.playing,
  });
  if (state.anim.playing) scheduler.animate();   // the next frame as soon as this one is shown
}

const scheduler = new FrameScheduler({
  transport,
  display,
  refineDelayMs: state.client.refineDelayMs,
  onError(e, what) {
    if (state.anim.playing && what !== 'gesture') setPlaying(false);   // a failed frame stops the animation
    if (e instanceof ApiError && e.status === 404 && state.sessionId) {  // the session expired
      replaceExpiredSession();
      return;
    }
    if (pendingScene && e instanceof ApiError && e.status === 422 && what === 'frame') {
      // The service will not render the new scene (too heavy, …): say why, next to n, and stay
      // with the scene on screen — its session still exists.
      const { prev } = pendingScene;
      pendingScene = null;
      recordError(e, what);
      if (prev) adopt(prev);
      return;
    }
    recordError(e, what);
  },
});

// ---- the session --------------------------------------------------------------------
function adopt(s) {
  state.sessionId = s.id;
  state.session = s;
  hook.sessionId = s.id;
  const info = s.scene_info || {};
  const museum = info.museum || null;
  const mesh = info.mesh_scene || null;
  state.scene = {
    scenario: museum ? 'museum' : mesh ? `mesh:${mesh.kind}` : info.scenario ?? state.scene.scenario,
    n: museum ? museum.n : info.n ?? info.n_spheres ?? state.scene.n,
    seed: museum ? museum.seed : info.seed ?? state.scene.seed, radius: info.radius ?? state.scene.radius,
    motion: museum ? museum.kind : state.scene.motion, n_spheres: info.n_spheres, animated: !!info.animated,
    n_triangles: info.n_triangles || 0, n_meshes: info.n_meshes || 0,
  };
  state.render = pickRender(s.settings);
  const anim = state.anim;
  if (anim.animated !== !!info.animated || !info.animated) setPlaying(false);
  anim.animated = !!info.animated;
  anim.time = Number.isFinite(s.settings?.time) ? s.settings.time : 0;
  playButton.hidden = !anim.animated;
  document.querySelector('[data-animated]').hidden = !anim.animated;
  storeSession({ id: s.id, scene: sceneBodyKeys(state.scene) });
  scheduler.resetVersions();
  panel.show(state);
}

function pickRender(settings) {
  const r = {};
  for (const k of [...RENDER_KEYS, 'format', 'quality']) if (settings[k] !== undefined) r[k] = settings[k];
  return r;
}

// What identifies a scene the client can ask for again (kept with the session in localStorage).
function sceneBodyKeys(scene) {
  const k = { scenario: scene.scenario, n: scene.n, seed: scene.seed, radius: scene.radius };
  if (scene.scenario === 'museum') k.motion = scene.motion;
  return k;
}

// POST /api/sessions body: a thesis scenario, the animated museum or a mesh scene.
function sceneBody(scene) {
  const kind = meshKind(scene.scenario);
  if (kind) return { mesh_scene: { kind } };
  if (scene.scenario === 'museum') {
    return { museum: { n: scene.n, kind: scene.motion || 'deformable', seed: scene.seed || 0 } };
  }
  return { scenario: scene.scenario, n: scene.n, seed: scene.seed, radius: scene.radius };
}

// Full resolution the client wants now ('fit' follows the screen).
function wantedSize() {
  const c = state.client;
  if (c.resolution === 'fit') {
    return fitResolution(stage.clientWidth || window.innerWidth, stage.clientHeight || window.innerHeight,
      window.devicePixelRatio || 1, c.maxFitSide);
  }
  return parseResolution(c.resolution);  // null for 'custom': keep the session's
}

// Render settings to apply on top of the session's: URL parameters and the resolution.
function wantedRender(current) {
  const want = { ...url.render };
  const size = wantedSize();
  if (size) Object.assign(want, size);
  const diff = {};
  for (const [k, v] of Object.entries(want)) if (!current || current[k] !== v) diff[k] = v;
  return diff;
}

let replacing = false;
function replaceExpiredSession() {
  if (replacing) return;
  replacing = true;
  scheduler.dropPending();
  scheduler.enqueue(async () => {
    const s = await api.createSession(sceneBody(state.scene), state.render);
    adopt(s);
    notice('The session had expired; a new one was started with the same scene (the camera is reset).', 'warn');
  }).then(() => scheduler.invalidate(), () => {}).finally(() => { replacing = false; });
}

async function start() {
  const stored = loadStoredSession();
  let s = null, expired = false;
  if (stored && stored.id) {
    try {
      s = await api.getSession(stored.id);
      if (Object.keys(url.scene).length && !sameScene(url.scene, s.scene_info)) s = null;  // a link to another scene
    } catch (e) {
      if (!(e instanceof ApiError && e.status === 404)) throw e;
      expired = true;
    }
  }
  if (!s) {
    const scene = { ...DEFAULT_SCENE, ...(stored && stored.scene), ...url.scene };
    try {
      s = await api.createSession(sceneBody(scene), wantedRender(null));
    } catch (e) {
      if (!(e instanceof ApiError && e.status === 422)) throw e;
      recordError(e, 'start');  // e.g. a link with parameters the service refuses
      notice('Starting the default scene instead.', 'warn');
      s = await api.createSession(sceneBody(DEFAULT_SCENE), wantedSize() || {});
    }
    if (expired) notice('Your previous session had expired; a new one was started with the same scene.', 'warn');
    adopt(s);
  } else {
    adopt(s);
    const diff = wantedRender(state.render);
    if (Object.keys(diff).length) adopt({ ...s, settings: await patch(diff) });
  }
  hook.status = 'ready';
}

async function patch(partial) {
  const r = await api.patchSettings(state.sessionId, partial);
  return r.settings ?? r;  // SettingsOut: the full settings plus version, flat
}

// ---- settings ------------------------------------------------------------------------
function applyRender(partial) {
  scheduler.enqueue(async () => {
    const settings = await patch(partial);
    state.render = pickRender(settings);
    state.session = { ...state.session, settings };
    panel.show(state);
  }).then(() => scheduler.invalidate(), () => panel.show(state));
}

const panel = new SettingsPanel($('#settings'), $('#settings-toggle'), {
  onScene(scene) {
    scheduler.dropPending();
    scheduler.enqueue(async () => {
      const prev = state.session;
      const s = await api.createSession(sceneBody(scene), state.render);
      adopt(s);
      pendingScene = { prev, id: s.id };
    }).then(() => scheduler.invalidate(), () => panel.show(state));
  },
  onRender: applyRender,
  // A model file chosen in the sheet: added to this session's scene (POST …/meshes, the raw
  // bytes), then the new frame. A refusal (413, 422) goes next to the picker; the scene stays.
  onModel(file, format) {
    scheduler.dropPending();
    return scheduler.enqueue(async () => {
      const sid = state.sessionId;
      let added;
      try {
        added = await api.addMesh(sid, file, { format, size: MODEL_SIZE });
      } catch (e) {
        if (!(e instanceof ApiError) || ![413, 422].includes(e.status)) throw e;
        const ex = explainUpload(e);
        const entry = { what: 'model', status: ex.status, message: ex.text, field: 'model' };
        hook.errors.push(entry);
        entry.inline = panel.open && panel.mark('model', ex.text);
        if (!entry.inline) notice(ex.text, 'error', 8000);
        return false;
      }
      if (state.sessionId !== sid) return false;
      const s = { ...state.session, version: added.version, scene_info: added.scene_info };
      state.sceneRev = (state.sceneRev || 0) + 1;   // device mode fetches the grown scene's data
      adopt(s);
      notice(`Added ${file.name}: ${added.scene_info.n_triangles} triangles in the scene now.`);
      return true;
    }).then((ok) => { if (ok) scheduler.invalidate(); }, () => {});
  },
  onClient(partial) {
    state.client = { ...state.client, ...partial };
    saveClientSettings(state.client);
    scheduler.refineDelayMs = state.client.refineDelayMs;
    if ('renderer' in partial) setRenderer(partial.renderer);
    if ('resolution' in partial) {
      const size = wantedSize();
      if (size && (size.width !== state.render.width || size.height !== state.render.height)) applyRender(size);
    }
    panel.show(state);
  },
});

const overlay = new Overlay($('#overlay'), $('#overlay-toggle'));
if (url.client.overlay !== undefined) overlay.setHidden(!url.client.overlay);
const hint = new Hint($('#hint'));
hook.hint = hint;

// 'fit' follows the screen: rotate the phone, resize the window.
let resizeTimer = null;
window.addEventListener('resize', () => {
  clearTimeout(resizeTimer);
  resizeTimer = setTimeout(() => {
    if (!state.render || state.client.resolution !== 'fit') return;
    const size = wantedSize();
    if (size.width !== state.render.width || size.height !== state.render.height) applyRender(size);
  }, 300);
});

// ---- device mode: the same tracer in this browser's WebGL2 ------------------------------
const device = new DeviceView({
  api,
  getState: () => state,
  viewportHeight: () => displayedSize().height,
  display,
  onFallback: fallBackToServer,
});
hook.device = {
  renderOnce: (params) => device.renderOnce(params),
  bench: (params) => device.bench(params),
  probe: () => device.probe(),
  get camera() { return device.camera; },
  get fallback() { return hook.deviceFallback ?? null; },
  get counts() { return { ...device.counts }; },
  get job() { return device.job && { level: device.job.level, rowsDone: device.job.rowsDone, rowsTotal: device.job.rowsTotal }; },
};

// Where the device cannot run the tracer: server mode, with a visible notice.
function fallBackToServer(reason, redraw = true) {
  device.stop();
  hook.deviceFallback = reason;
  state.client = { ...state.client, renderer: 'server' };
  notice(`Rendering on the server: this device cannot (${reason}).`, 'warn', 10000);
  $('#f-renderer').value = 'server';   // also while focused (panel.show leaves focused controls alone)
  panel.show(state);
  if (redraw && state.render) scheduler.invalidate();
}

function setRenderer(which) {
  if (which === 'device') {
    const p = device.probe();
    if (!p.ok) return fallBackToServer(p.reason);
  } else {
    device.stop();
  }
  if (state.render) scheduler.invalidate();
}

fetch('/api/ready', { cache: 'no-store' }).then((r) => r.json())
  .then((j) => { hook.serverRenderer = j.gl_renderer || null; }, () => {});

// ---- gestures ----------------------------------------------------------------------
// In device mode the local camera moves at once (display rate); the server's Model always follows.
function userGesture(g) {
  hint.dismiss();   // they found out
  if (!state.render) return;
  if (deviceMode()) device.gesture(g);
  scheduler.gesture(g);
}
// A drag in orbit mode: "grab the scene" — dragging right turns the scene right (the camera
// left about its target), dragging down turns it down (the camera up).
function orbitDrag(dx, dy) {
  const k = ORBIT_DEGREES_PER_VIEW / displayedSize().height;
  userGesture({ type: 'orbit', yaw: -dx * k, pitch: -dy * k });
}
const gestures = attach(canvas, {
  onStart: () => hint.dismiss(),
  onPan: (dx, dy) => userGesture({ type: 'pan', dx, dy }),
  onOrbitDrag: orbitDrag,
  // Two fingers turning clockwise turn the scene as if the near floor followed the lower finger.
  onTwist: (deg) => userGesture({ type: 'orbit', yaw: deg, pitch: 0 }),
  onPinch: (scale) => userGesture({ type: 'pinch', scale }),
  onReset: () => userGesture({ type: 'reset' }),
  onWheel: (scale) => userGesture({ type: 'pinch', scale }),
  onKey: (g) => userGesture(g),
});
$('#reset-button').addEventListener('click', () => userGesture({ type: 'reset' }));

const orbitButton = $('#orbit-toggle');
function setDragMode(mode) {
  state.client = { ...state.client, dragMode: mode };
  gestures.recognizer.dragMode = mode;
  orbitButton.setAttribute('aria-pressed', String(mode === 'orbit'));
  document.body.classList.toggle('orbit-mode', mode === 'orbit');
}
orbitButton.addEventListener('click', () => {
  setDragMode(state.client.dragMode === 'orbit' ? 'pan' : 'orbit');
  saveClientSettings(state.client);
});
setDragMode(state.client.dragMode === 'orbit' ? 'orbit' : 'pan');

// ---- go ------------------------------------------------------------------------------
// What this service offers: its method and mode lists, and limits for the form.
api.info().then((info) => {
  hook.info = info;
  legend.setInfo(info);
  if (!info) return;
  if (Array.isArray(info.methods) && info.methods.length) state.methods = info.methods;
  if (info.profiles && typeof info.profiles === 'object') state.profiles = info.profiles;
  // A frame may take up to the service's own limit (then it answers 422 itself): wait that long.
  if (info.render_timeout_s > 0) api.timeoutMs = Math.max(api.timeoutMs, (info.render_timeout_s + 15) * 1000);
  panel.setInfo(info);
});

scheduler.enqueue(start).then(
  () => scheduler.invalidate(),
  (e) => {
    hook.status = 'failed';
    recordError(e, 'start');
  },
);
