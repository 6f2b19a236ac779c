// The session: the scene, camera and render settings the service keeps for this page. Started
// (or resumed from localStorage) and adopted into state; render settings PATCHed; a new scene
// is a new session, and when the service refuses to render it the client goes back to the
// scene on screen; an expired session is started again with the same scene; model files are
// added to the scene.

import { ApiError, loadStoredSession, sameScene, storeSession } from './api.js';
import {
  DEFAULT_SCENE, MODEL_SIZE, defaultScenario, fitResolution, meshKind, parseResolution, saveClientSettings, sceneEntry, sceneSettings,
  settingNames, skyScenario, withRestDenoiser,
} from './settings.js';
import { fitRefused } from './ui/messages.js';

// Whether a 422 refuses the body's `aspect` (a service that frames no scene for it, or a value out of its range).
const refusesAspect = (e) => Array.isArray(e.detail) && e.detail.some((d) => Array.isArray(d.loc) && d.loc.includes('aspect'));
// How many times in a row a refused frame is retried at the settings its refusal names.
const FIT_RETRIES = 3;

// The render settings the client keeps of a session's settings (and carries to a new session):
// those GET /api/info declares so; from a service that declares none, all of them.
export function pickRender(settings) {
  const r = {}, keys = settingNames('client');
  for (const k of keys.length ? keys : Object.keys(settings)) if (k !== 'version' && settings[k] !== undefined) r[k] = settings[k];
  return r;
}

// A session's scene_info → state.scene (what it does not say is kept from `scene`, the one before).
export function sceneOf(info, scene) {
  const museum = info.museum || null;
  const mesh = info.mesh_scene || null;
  return {
    scenario: museum ? 'museum' : mesh ? `mesh:${mesh.kind}` : info.sky && info.scenario ? `sky:${info.scenario}`
      : info.scenario ?? scene.scenario,
    n: museum ? museum.n : info.n ?? info.n_spheres ?? scene.n,
    seed: museum ? museum.seed : info.seed ?? scene.seed, radius: info.radius ?? scene.radius,
    motion: museum ? museum.kind : scene.motion, n_spheres: info.n_spheres, animated: !!info.animated,
    n_triangles: info.n_triangles || 0, n_meshes: info.n_meshes || 0, n_shapes: info.n_shapes || 0,
  };
}

// What identifies a scene the client can ask for again (kept with the session in localStorage).
export function sceneBodyKeys(scene) {
  const k = { scenario: scene.scenario, n: scene.n, seed: scene.seed, radius: scene.radius };
  if (scene.scenario === 'museum') k.motion = scene.motion;
  return k;
}

// POST /api/sessions body: a thesis scenario, the animated museum or a mesh scene.
export function sceneBody(scene) {
  const kind = meshKind(scene.scenario);
  if (kind) return { mesh_scene: { kind } };
  if (scene.scenario === 'museum') {
    return { museum: { n: scene.n, kind: scene.motion || 'deformable', seed: scene.seed || 0 } };
  }
  const sky = skyScenario(scene.scenario);
  if (sky) return { scenario: sky, n: scene.n, seed: scene.seed, radius: scene.radius, sky: true };
  return { scenario: scene.scenario, n: scene.n, seed: scene.seed, radius: scene.radius };
}

// The settings of `want` that differ from `current` (all of them without a current).
export function changed(want, current) {
  const diff = {};
  for (const [k, v] of Object.entries(want)) if (!current || current[k] !== v) diff[k] = v;
  return diff;
}

// state, url (readUrlParams), api, scheduler (frames.js), panel (ui/panel.js), player
// (ui/player.js), refusals (ui/errors.js), notice(text, kind), hook; stage: the element the
// frame is shown in ('fit' resolutions follow its size).
export class Session {
  constructor({ state, url, api, scheduler, panel, player, refusals, notice, hook, stage }) {
    Object.assign(this, { state, url, api, scheduler, panel, player, refusals, notice, hook, stage });
    // A new scene whose first frame has not been shown yet: {prev: SessionOut, id}. If the service
    // refuses to render it (422, e.g. too heavy), the client goes back to the previous session.
    this.pendingScene = null;
    this.replacing = false;
    this.ready = Promise.resolve();   // GET /api/info taken in (start() says when)
  }

  adopt(s) {
    const { state } = this;
    state.sessionId = s.id;
    state.session = s;
    this.hook.sessionId = s.id;
    const info = s.scene_info || {};
    state.scene = sceneOf(info, state.scene);
    state.render = pickRender(s.settings);
    this.player.adoptScene(!!info.animated, Number.isFinite(s.settings?.time) ? s.settings.time : 0);
    storeSession({ id: s.id, scene: sceneBodyKeys(state.scene) });
    this.scheduler.resetVersions();
    this.panel.show(state);
  }

  // Full resolution the client wants now ('fit' follows the screen; null for 'custom': keep the session's).
  wantedSize() {
    const c = this.state.client;
    if (c.resolution === 'fit') {
      const stage = this.stage;
      return fitResolution(stage.clientWidth || window.innerWidth, stage.clientHeight || window.innerHeight,
        window.devicePixelRatio || 1, c.maxFitSide);
    }
    return parseResolution(c.resolution);
  }

  // The width / height of the frame on screen, for the service to frame a demo scene (null when unknown).
  aspect() {
    const size = this.wantedSize();
    const a = size ? size.width / size.height : (this.stage.clientWidth || 0) / (this.stage.clientHeight || 1);
    return a > 0 && Number.isFinite(a) ? Math.round(a * 1e4) / 1e4 : null;
  }

  // Render settings to apply on top of the session's: URL parameters and the resolution; a new
  // session's path integrator with its denoiser on (withRestDenoiser), unless the link chose it.
  wantedRender(current, created = false) {
    let want = { ...this.url.render };
    const size = this.wantedSize();
    if (size) Object.assign(want, size);
    if (created) {
      const merged = { ...current, ...want }, denoised = withRestDenoiser(merged, this.url.render);
      if (denoised.denoise !== merged.denoise) want = { ...want, denoise: denoised.denoise };
    }
    return changed(want, current);
  }

  // POST /api/sessions of `scene` with `settings` and the frame's aspect (the service frames a demo
  // scene for it). A service that refuses the aspect is asked again without it (and not sent it
  // again); settings refused for their cost are asked again at the largest the refusal names, said
  // in a notice.
  async create(scene, settings = {}) {
    const body = sceneBody(scene), aspect = this.aspect();
    // A service that lists its demo scenes (GET /api/info's scenes) frames them for an aspect too
    // (the same contract); one that does not would refuse the field.
    await this.ready.catch(() => {});
    if (aspect && !this.noAspect && Array.isArray(this.hook.info?.scenes)) body.aspect = aspect;
    let want = settings;
    for (let fits = 0; ; ) {
      try {
        return await this.api.createSession(body, want);
      } catch (e) {
        if (!(e instanceof ApiError && e.status === 422)) throw e;
        if ('aspect' in body && refusesAspect(e)) {
          delete body.aspect;
          this.noAspect = true;
          continue;
        }
        const fit = fits++ < FIT_RETRIES ? fitRefused(e, { ...this.state.render, ...want }) : null;
        if (!fit) throw e;
        want = { ...want, ...fit.settings };
        this.notice(fit.text, 'warn');
      }
    }
  }

  // Start (or resume) the session, then its first frame; `ready`: the service's declarations of its
  // settings (what a link may set and what a session carries). The hook's status says 'failed' if it cannot.
  begin(ready = Promise.resolve()) {
    this.scheduler.enqueue(() => this.start(ready)).then(
      () => this.scheduler.invalidate(true),   // a quick preview first: nothing is on screen yet
      (e) => {
        this.hook.status = 'failed';
        this.refusals.record(e, 'start');
      },
    );
  }

  // The session is asked for (resumed, or made with the scene and the size) while `ready` is on its
  // way — one round trip less before the first image —; the link's render settings, which need the
  // service's declarations, follow as one PATCH. A setting the service refuses there is said (the
  // session keeps its own).
  async start(ready = Promise.resolve()) {
    this.ready = ready;
    const opened = this.open();
    opened.catch(() => {});   // awaited below, after `ready`
    await ready;
    const s = await opened;
    this.adopt(s);
    const diff = this.wantedRender(this.state.render, this.created);
    if (Object.keys(diff).length) {
      try {
        this.adopt({ ...s, settings: await this.patch(diff) });
      } catch (e) {
        if (!(e instanceof ApiError && e.status === 422)) throw e;
        this.refusals.record(e, 'start');
      }
    }
    this.hook.status = 'ready';
  }

  // The stored session when it still exists and shows the link's scene, else a new one (the default
  // scene when the service refuses the link's).
  async open() {
    const { api, url } = this;
    const stored = loadStoredSession();
    this.created = false;
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
    this.created = !s;
    if (s) return s;
    // The default scene is the service's (GET /api/info's scenes): it is known once `ready` is.
    const named = (stored && stored.scene) || Object.keys(url.scene).length;
    if (!named) await this.ready.catch(() => {});
    const fallback = { ...DEFAULT_SCENE, scenario: defaultScenario() };
    const scene = { ...fallback, ...(stored && stored.scene), ...url.scene };
    try {
      s = await this.create(scene, this.wantedSize() || {});
    } catch (e) {
      if (!(e instanceof ApiError && e.status === 422)) throw e;
      this.refusals.record(e, 'start');  // e.g. a link with a scene the service refuses
      this.notice('Starting the default scene instead.', 'warn');
      await this.ready.catch(() => {});
      s = await this.create({ ...DEFAULT_SCENE, scenario: defaultScenario() }, this.wantedSize() || {});
    }
    if (expired) this.notice('Your previous session had expired; a new one was started with the same scene.', 'warn');
    return s;
  }

  async patch(partial) {
    const r = await this.api.patchSettings(this.state.sessionId, partial);
    return r.settings ?? r;  // SettingsOut: the full settings plus version, flat
  }

  applyRender(partial) {
    const { state, scheduler, panel } = this;
    scheduler.enqueue(async () => {
      const settings = await this.patch(partial);
      state.render = pickRender(settings);
      state.session = { ...state.session, settings };
      panel.show(state);
    }).then(() => scheduler.invalidate(), () => panel.show(state));
  }

  // The settings sheet chose another scene.
  newScene(scene) {
    const { state, scheduler } = this;
    scheduler.dropPending();
    scheduler.enqueue(async () => {
      const prev = state.session;
      // The picked scene's recommended settings over the session's (the link's own still win).
      const settings = sceneSettings(state.render, sceneEntry(state.scene.scenario), sceneEntry(scene.scenario), this.url.render);
      const s = await this.create(scene, settings);
      this.adopt(s);
      this.pendingScene = { prev, id: s.id };
    }).then(() => scheduler.invalidate(true), () => this.panel.show(state));
  }

  // A frame of `meta` (transport.js's requestMeta) is on screen at `level`. Only a full frame settles
  // a new scene: its quick preview may pass where the full frame is refused (too heavy).
  shown(meta, level = 'full') {
    if (level === 'full') this.fits = 0;
    if (this.pendingScene && meta.sessionId === this.pendingScene.id && level === 'full') this.pendingScene = null;
  }

  // The scheduler's onError: a request of `what` ('frame', 'gesture', a task) failed with e.
  failed(e, what) {
    if (this.state.anim.playing && what !== 'gesture') this.player.set(false);   // a failed frame stops the animation
    if (e instanceof ApiError && e.status === 404 && this.state.sessionId) {  // the session expired
      this.replaceExpired();
      return;
    }
    // A frame refused for its cost: asked again at the largest size or samples the refusal names.
    const fit = what === 'frame' && (this.fits || 0) < FIT_RETRIES && fitRefused(e, this.state.render);
    if (fit) {
      this.fits = (this.fits || 0) + 1;
      this.notice(fit.text, 'warn');
      this.applyRender(fit.settings);
      return;
    }
    if (this.pendingScene && e instanceof ApiError && e.status === 422 && what === 'frame') {
      // The service will not render the new scene (too heavy, …): say why, next to n, and stay
      // with the scene on screen — its session still exists.
      const { prev } = this.pendingScene;
      this.pendingScene = null;
      this.refusals.record(e, what);
      if (prev) this.adopt(prev);
      return;
    }
    this.refusals.record(e, what);
  }

  replaceExpired() {
    if (this.replacing) return;
    this.replacing = true;
    const { scheduler } = this;
    scheduler.dropPending();
    scheduler.enqueue(async () => {
      const s = await this.create(this.state.scene, this.state.render);
      this.adopt(s);
      this.notice('The session had expired; a new one was started with the same scene (the camera is reset).', 'warn');
    }).then(() => scheduler.invalidate(true), () => {}).finally(() => { this.replacing = false; });
  }

  // A model file chosen in the sheet: added to this session's scene (POST …/meshes, the raw
  // bytes), then the new frame. A refusal (413, 422) goes next to the picker; the scene stays.
  addModel(file, format) {
    const { state, scheduler } = this;
    scheduler.dropPending();
    return scheduler.enqueue(async () => {
      const sid = state.sessionId;
      let added;
      try {
        added = await this.api.addMesh(sid, file, { format, size: MODEL_SIZE });
      } catch (e) {
        if (!(e instanceof ApiError) || ![413, 422].includes(e.status)) throw e;
        this.refusals.upload(e);
        return false;
      }
      if (state.sessionId !== sid) return false;
      const s = { ...state.session, version: added.version, scene_info: added.scene_info };
      state.sceneRev = (state.sceneRev || 0) + 1;   // device mode fetches the grown scene's data
      this.adopt(s);
      this.notice(`Added ${file.name}: ${added.scene_info.n_triangles} triangles in the scene now.`);
      return true;
    }).then((ok) => { if (ok) scheduler.invalidate(); }, () => {});
  }

  // What this service offers (GET /api/info): its method and mode lists, its profiles, limits for the form.
  offered(info) {
    const { state, api } = this;
    this.hook.info = info;
    if (!info) return;
    if (Array.isArray(info.methods) && info.methods.length) state.methods = info.methods;
    if (info.profiles && typeof info.profiles === 'object') state.profiles = info.profiles;
    // A frame may take up to the service's own limit (then it answers 422 itself): wait that long.
    if (info.render_timeout_s > 0) api.timeoutMs = Math.max(api.timeoutMs, (info.render_timeout_s + 15) * 1000);
    this.panel.setInfo(info);
  }

  // The sheet changed this browser's own settings (kept in localStorage); setRenderer(which):
  // device/mode.js's RendererChoice.set.
  setClient(partial, setRenderer) {
    const { state } = this;
    state.client = { ...state.client, ...partial };
    saveClientSettings(state.client);
    this.scheduler.refineDelayMs = state.client.refineDelayMs;
    if ('renderer' in partial) setRenderer(partial.renderer);
    if ('resolution' in partial) {
      const size = this.wantedSize();
      if (size && (size.width !== state.render.width || size.height !== state.render.height)) this.applyRender(size);
    }
    this.panel.show(state);
  }

  // 'fit' follows the screen: rotate the phone, resize the window.
  followScreen() {
    let timer = null;
    window.addEventListener('resize', () => {
      clearTimeout(timer);
      timer = setTimeout(() => {
        const { state } = this;
        if (!state.render || state.client.resolution !== 'fit') return;
        const size = this.wantedSize();
        if (size.width !== state.render.width || size.height !== state.render.height) this.applyRender(size);
      }, 300);
    });
  }
}
