// transport.js: the query of a frame (levels, the interactive profile, the scene time) and what it was asked with.

import { test } from 'node:test';
import { Transport, frameParams, requestMeta } from '../../../client_web/js/transport.js';
import { PreviewSizer } from '../../../client_web/js/preview_size.js';
import { same } from './same.mjs';

const state = (o = {}) => ({
  sessionId: 's1', render: { width: 320, height: 544, mode: 'heat', method: 'bih', samples_per_pixel: 4, max_recursion_depth: 8, min_weight: 0.03 },
  client: { previewScale: 0.5, previewFormat: 'jpeg', previewQuality: 70, fullFormat: 'png', fullQuality: 90 },
  scene: { scenario: 2, n: 128, n_spheres: 128 }, profiles: null,
  anim: { animated: false, playing: false, time: 0, time0: 0, clock0: 0 }, ...o,
});

test('full frames at the session size and full format; previews scaled, with their quality', () => {
  same(frameParams(state(), 'full'), { width: 320, height: 544, format: 'png' });
  same(frameParams(state(), 'preview'), { width: 160, height: 272, format: 'jpeg', quality: 70 });
});

test('previews at the service\'s interactive profile, the depth no deeper than the session\'s', () => {
  const s = state({ profiles: { interactive: { max_recursion_depth: 10, samples_per_pixel: 1, min_weight: 0.1 } } });
  same(frameParams(s, 'preview'), { width: 160, height: 272, format: 'jpeg', quality: 70, max_recursion_depth: 8, samples_per_pixel: 1, min_weight: 0.1 });
  same(requestMeta(s, 'preview'), { sessionId: 's1', n: 128, mode: 'heat', method: 'bih', samples: 1, integrator: 'whitted', minWeight: 0.1, scenario: 2,
    motion: undefined, triangles: 0, meshes: 0, shapes: 0 });
  same([requestMeta(s, 'full').samples, requestMeta(s, 'full').minWeight], [4, 0.03]);
});

test('an animated scene\'s frames carry the scene time', () => {
  const s = state({ anim: { animated: true, playing: true, time: 0, time0: 1, clock0: 0 } });
  same(frameParams(s, 'full', 500), { width: 320, height: 544, format: 'png', time: 1.5 });
});

test('previews at the sizer\'s scale with auto (server mode), else at the chosen one', () => {
  const sizer = new PreviewSizer({ start: 0.25 });
  const auto = new Transport({ state: state({ client: { ...state().client, previewAuto: true } }), sizer });
  same([auto.previewScale, auto.quickFirst(), auto.refineNeeded()], [0.25, true, true]);
  same(frameParams(auto.state, 'preview', 0, auto.previewScale), { width: 80, height: 136, format: 'jpeg', quality: 70 });
  auto.previewTaken(500, { scale: 0.25 });   // slow: smaller next time
  same(auto.previewScale < 0.25, true);
  const fixed = new Transport({ state: state(), sizer: new PreviewSizer({ start: 0.25 }) });
  same(fixed.previewScale, 0.5);
  fixed.previewTaken(500, { scale: 0.5 });
  same(fixed.previewScale, 0.5);
  const device = new Transport({ state: state({ client: { ...state().client, previewAuto: true, renderer: 'device' } }), sizer });
  same([device.quickFirst(), device.refineNeeded()], [false, false]);
});

// A fake api that records each frame's query and signal.
const recording = () => {
  const asked = [];
  return { asked, frame: (id, params, onPreview, signal) => { asked.push({ params, signal }); return Promise.resolve({ blob: {}, version: 1 }); } };
};
const activity = { classList: { add: () => {}, remove: () => {} } };

test('a path-traced view at rest: its full frame is one accumulated sample; no ε in what it says', async () => {
  const api = recording();
  const path = state({ render: { ...state().render, mode: 'color', integrator: 'path', samples_per_pixel: 64 } });
  const t = new Transport({ state: path, api, activity });
  const frame = await t.frame('full');
  same([api.asked[0].params, frame.meta.samples, frame.meta.minWeight],
    [{ width: 320, height: 544, format: 'png', samples_per_pixel: 1, accumulate: 1 }, 1, null]);
  const whitted = new Transport({ state: state({ render: { ...state().render, mode: 'color' } }), api, activity });
  await whitted.frame('full');
  same(api.asked[1].params, { width: 320, height: 544, format: 'png' });
});

test('the service\'s frames can be abandoned (their signal reaches the request); the device\'s cannot', async () => {
  const api = recording(), ctl = new AbortController();
  const t = new Transport({ state: state(), api, activity });
  await t.frame('full', null, ctl.signal);
  same([api.asked[0].signal === ctl.signal, t.abortable()], [true, true]);
  same(new Transport({ state: state({ client: { ...state().client, renderer: 'device' } }), api, activity }).abortable(), false);
});
