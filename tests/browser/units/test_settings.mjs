// settings.js: preview and fitted sizes, URL parameters.

import './declared.mjs';
import { test } from 'node:test';
import * as s from '../../../client_web/js/settings.js';
import { assert, same } from './same.mjs';

test("a method's label is the service's, its name before the service answered", () => {
  const info = { method_settings: { bih: { label: 'BIH (thesis)' }, bvh: {} } };
  same([s.methodLabel(info, 'bih'), s.methodLabel(info, 'bvh'), s.methodLabel(info, 'kdtree'), s.methodLabel(null, 'bih')],
    ['BIH (thesis)', 'bvh', 'kdtree', 'bih']);
});

test("a mode's label is the service's, its name before the service answered", () => {
  const info = { mode_labels: { color: 'Colour', heat: 'Traversal heat' } };
  same([s.modeLabel(info, 'heat'), s.modeLabel(info, 'depth'), s.modeLabel(null, 'color')], ['Traversal heat', 'depth', 'color']);
});

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

// ---- the picker: GET /api/info's scenes, their recommended settings, the denoiser at rest ----
const INFO_SCENES = [
  { value: '1', label: 'Grid', settings: {} },
  { value: 'mesh:cornell', label: 'Cornell box', settings: { integrator: 'path', max_recursion_depth: 8 } },
  { value: 'mesh:gallery', label: 'A scene only the service knows', settings: { integrator: 'path' } },
];

test('the picker is the service\'s list when it gives one, its own list otherwise', () => {
  const own = s.pickerScenes.map((x) => x.value);
  same([s.learnScenes(undefined), s.learnScenes([]), s.pickerScenes.map((x) => x.value)], [false, false, own]);
  same(s.learnScenes(INFO_SCENES), true);
  same(s.pickerScenes.map((x) => [x.value, x.label]), [[1, 'Grid'], ['mesh:cornell', 'Cornell box'], ['mesh:gallery', 'A scene only the service knows']]);
  same([s.readUrlParams('?scenario=mesh:gallery').scene, s.readUrlParams('?scenario=museum').ignored.map((x) => x.name)],
    [{ scenario: 'mesh:gallery' }, ['scenario']]);
});

test('a new session without a named scene gets the service\'s default scene', () => {
  const held = s.pickerScenes.map((x) => ({ ...x }));
  same(s.learnScenes(INFO_SCENES), true);
  same(s.defaultScenario(), s.DEFAULT_SCENE.scenario);   // a list without a default: the client's own
  same(s.learnScenes([...INFO_SCENES, { value: 'mesh:spheres', label: 'Spheres', settings: {}, default: true }]), true);
  same(s.defaultScenario(), 'mesh:spheres');
  same(s.learnScenes(held), true);
});

test('a picked scene brings its recommended settings; what the last one recommended goes back to its default', () => {
  const whitted = { integrator: 'whitted', max_recursion_depth: 3, denoise: 'off', width: 64, height: 64 };
  const cornell = s.sceneSettings(whitted, s.sceneEntry(1), s.sceneEntry('mesh:cornell'));
  same(cornell, { integrator: 'path', max_recursion_depth: 8, denoise: 'oidn', width: 64, height: 64 });
  const back = s.sceneSettings(cornell, s.sceneEntry('mesh:cornell'), s.sceneEntry(1));
  const dflt = (k) => s.settingSpec(k).default;
  same([back.integrator, back.max_recursion_depth, back.width], [dflt('integrator'), dflt('max_recursion_depth'), 64]);
  // the link's own settings win over the scene's
  same(s.sceneSettings(whitted, null, s.sceneEntry('mesh:cornell'), { max_recursion_depth: 4, denoise: 'off' }),
    { integrator: 'path', max_recursion_depth: 4, denoise: 'off', width: 64, height: 64 });
});

test('the path integrator rests denoised unless the denoiser was chosen', () => {
  same([s.withRestDenoiser({ integrator: 'path', denoise: 'off' }).denoise, s.withRestDenoiser({ integrator: 'path' }).denoise,
    s.withRestDenoiser({ integrator: 'path', denoise: 'atrous' }).denoise, s.withRestDenoiser({ integrator: 'whitted', denoise: 'off' }).denoise,
    s.withRestDenoiser({ integrator: 'path', denoise: 'off' }, { denoise: 'off' }).denoise,
    s.withRestDenoiser({ integrator: 'path', denoise: 'off' }, {}, []).denoise],
  ['oidn', 'oidn', 'atrous', 'off', 'off', 'off']);
});
