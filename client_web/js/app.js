// The composition root: makes the client's parts and wires them. The View of the thesis's MVC:
// gestures go to the service (the Controller updates the Model's camera) and the frame it
// renders comes back (transport.js → frames.js → display.js), or this browser traces it
// (device/). Test hook: window.pocketray (hook.js).

import { Api } from './api.js';
import { Display, displayedSize } from './display.js';
import { FrameScheduler } from './frames.js';
import { createHook, observe } from './hook.js';
import { Session } from './session.js';
import { PreviewSizer } from './preview_size.js';
import { ignoredNotice, readUrlParams } from './settings.js';
import { createState } from './state.js';
import { Transport } from './transport.js';
import { DeviceView } from './device/device.js';
import { RendererChoice } from './device/mode.js';
import { connectionStatus } from './ui/connection.js';
import { attachControls } from './ui/controls.js';
import { Refusals } from './ui/errors.js';
import { Hint } from './ui/hint.js';
import { Legend } from './ui/legend.js';
import { Banner, Notices } from './ui/notices.js';
import { Overlay } from './ui/overlay.js';
import { SettingsPanel } from './ui/panel.js';
import { Player } from './ui/player.js';
import { RefineBadge } from './ui/refine.js';

const $ = (sel) => document.querySelector(sel);
const canvas = $('#view'), stage = $('#stage');
const { url, state } = createState(location.search);
const hook = (window.pocketray = createHook(state));
const viewportHeight = () => displayedSize(stage, state.render).height;

const notices = new Notices($('#notice'), (n) => hook.notices.push(n));
const notice = (text, kind, ms) => notices.show(text, kind, ms);
const banner = new Banner($('#banner'), { onRetry: () => api.retryNow() });
const api = new Api({ onStatus: connectionStatus({ banner, notice, hook, state }) });
window.addEventListener('online', () => api.retryNow());
const player = new Player({
  button: $('#play-button'), animatedRows: $('[data-animated]'), state, onPlay: () => state.render && scheduler.animate(),
});

const overlay = new Overlay($('#overlay'), $('#overlay-toggle')), legend = new Legend($('#legend'));
if (url.client.overlay !== undefined) overlay.setHidden(!url.client.overlay);
const display = new Display({
  canvas, state, hook, overlay, legend,
  onShown(meta, level) {
    session.shown(meta, level);
    if (state.anim.playing) scheduler.animate();   // the next frame as soon as this one is shown
  },
});
const show = (frame, level) => display.show(frame, level);
const device = new DeviceView({ api, getState: () => state, viewportHeight, display: show,
  onFallback: (reason) => renderers.fallBack(reason) });
// The service's previews keep ≥ 15 frames/s: their size follows their measured time (from ¼, the
// size of the first image after load).
const sizer = new PreviewSizer({ start: 0.25 });
const transport = new Transport({ state, api, device, activity: $('#activity'), viewportHeight, sizer,
  pending: () => scheduler.pending, onFallback: (reason, redraw) => renderers.fallBack(reason, redraw) });
// The refinement stream's counter ("64 / 256 samples" and a bar); the hook keeps its parts.
const refineBadge = new RefineBadge(stage);
hook.refinement = { parts: [], stopped: 0 };
const scheduler = new FrameScheduler({
  transport, display: show, refineDelayMs: state.client.refineDelayMs,
  onError: (e, what) => session.failed(e, what),
  onRefinement(p) {
    refineBadge.show(p);
    if (p) hook.refinement.parts.push({ samples: p.samples, target: p.target_samples, done: p.done, reason: p.reason });
    else hook.refinement.stopped++;
  },
});
observe(hook, { scheduler, device });
Object.defineProperty(hook, 'previewScale', { get: () => transport.previewScale, enumerable: true });

const panel = new SettingsPanel($('#settings'), $('#settings-toggle'), {
  onScene: (scene) => session.newScene(scene),
  onRender: (partial) => session.applyRender(partial),
  onModel: (file, format) => session.addModel(file, format),
  onClient: (partial) => session.setClient(partial, (which) => renderers.set(which)),
});
const refusals = new Refusals({ hook, panel, notice });
const session = new Session({ state, url, api, scheduler, panel, player, refusals, notice, hook, stage });
const renderers = new RendererChoice({ state, hook, device, scheduler, panel, select: $('#f-renderer'), notice });
const hint = new Hint($('#hint'));
hook.hint = hint;
attachControls({
  canvas, orbitButton: $('#orbit-toggle'), resetButton: $('#reset-button'), state, hint, device, scheduler, viewportHeight,
});
session.followScreen();

fetch('/api/ready', { cache: 'no-store' }).then((r) => r.json())
  .then((j) => { hook.serverRenderer = j.gl_renderer || null; }, () => {});
const infoReady = api.info().then((info) => { legend.setInfo(info); session.offered(info); });
// A link's render settings are those the service declares: read them again once it has said which,
// and say which parameters were not taken.
session.begin(infoReady.then(() => {
  const again = readUrlParams(location.search);
  Object.assign(url.render, again.render);
  hook.ignoredParams = again.ignored;
  const text = ignoredNotice(again.ignored);
  if (text) notice(text, 'warn', 12000);
}));
