// settings.js: preview and fitted sizes, URL parameters.

import './declared.mjs';
import { test } from 'node:test';
import * as s from '../../../client_web/js/settings.js';
import { assert, same } from './same.mjs';

test('preview size', () => same(s.previewSize(320, 544, 0.5), { width: 160, height: 272 }));

test('fit keeps the screen aspect, long side capped', () => {
  same(s.fitResolution(390, 844, 3, 1088), { width: 503, height: 1088 });
});

test('url params', () => {
  const u = s.readUrlParams('?scenario=2&n=128&width=320&height=544&preview_scale=0.25&mode=heat');
  same(u, { scene: { scenario: 2, n: 128 }, render: { width: 320, height: 544, mode: 'heat' },
    client: { resolution: '320x544', previewScale: 0.25, previewAuto: false }, ignored: [] });
  same(s.readUrlParams('?preview_scale=auto').client, { previewAuto: true });
});

test('the demo scenes by their scenario', () => {
  for (const v of ['mesh:cornell', 'mesh:teapot', 'mesh:mixed', 'mesh:room', 'mesh:table', 'museum', '3']) {
    same(s.readUrlParams(`?scenario=${v}`).scene.scenario, v === '3' ? 3 : v);
  }
  same(s.readUrlParams('?scenario=mesh:nothing').ignored.map((x) => x.name), ['scenario']);
});

test('museum url params', () => {
  const m = s.readUrlParams('?scenario=museum&n=256&motion=rigid&update=refit');
  same([m.scene, m.render], [{ scenario: 'museum', n: 256, motion: 'rigid' }, { update: 'refit' }]);
});

test('a link sets every declared render setting, not only the sheet\'s', () => {
  const u = s.readUrlParams('?integrator=path&tone_map=aces&exposure=-1.5&min_weight=0.5&time=3&specialize=false' +
    '&tile_size=8&samples_per_pixel=64&quality=60');
  same(u.render, { integrator: 'path', tone_map: 'aces', exposure: -1.5, min_weight: 0.5, time: 3, specialize: false,
    tile_size: 8, samples_per_pixel: 64, quality: 60 });
  same(u.ignored, []);
  // …every one of them: each declared setting's default, written in a link, comes back as it was.
  for (const spec of s.renderSettings) {
    const got = s.readUrlParams(`?${spec.name}=${encodeURIComponent(String(spec.default))}`);
    same([got.render[spec.name], got.ignored], [spec.default, []], spec.name);
  }
});

test('invalid values and unknown names are ignored, each with why', () => {
  const u = s.readUrlParams('?update=sometimes&samples_per_pixel=0&max_recursion_depth=2.5&exposure=bright' +
    '&specialize=maybe&bogus=1&tile_size=8&n=-3&preview_scale=2&renderer=gpu');
  same(u.render, { tile_size: 8 });
  same(u.ignored.map((x) => x.name).sort(), ['bogus', 'exposure', 'max_recursion_depth', 'n', 'preview_scale', 'renderer',
    'samples_per_pixel', 'specialize', 'update'].sort());
  const why = Object.fromEntries(u.ignored.map((x) => [x.name, x.why]));
  same([why.update, why.samples_per_pixel, why.bogus], ['one of rebuild, refit, selective', 'a whole number 1 … 4096',
    'not a setting of this service']);
  const text = s.ignoredNotice(u.ignored);
  assert.ok(text.startsWith('Ignored in the link: ') && text.includes('samples_per_pixel=0 — Quality (samples per pixel): a whole number 1 … 4096'), text);
  same(s.ignoredNotice([]), null);
});

test('before the service has declared its settings, render parameters are neither taken nor judged', () => {
  same(s.readUrlParams('?integrator=path&bogus=1', []), { scene: {}, render: {}, client: {}, ignored: [] });
});

test('settings by their declared flags', () => {
  same([s.settingNames('sheet').includes('samples_per_pixel'), s.settingNames('sheet').includes('time'),
    s.settingNames('client').includes('quality'), s.settingNames('client').includes('time')], [true, false, true, false]);
});

test('values by their declared type', () => {
  same([s.settingValue({ type: 'integer' }, '4'), s.settingValue({ type: 'number' }, '0.5'),
    s.settingValue({ type: 'boolean' }, 'false'), s.settingValue({ type: 'string' }, 'bvh'), s.settingValue({ type: 'integer' }, 'x')],
  [4, 0.5, false, 'bvh', undefined]);
});

test('labels are the declared ones', () => {
  same([s.FIELD_LABELS.samples_per_pixel, s.FIELD_LABELS.max_recursion_depth], ['Quality (samples per pixel)', 'Recursion depth']);
});
