// settings.js: preview and fitted sizes, URL parameters.

import './declared.mjs';
import { test } from 'node:test';
import * as s from '../../../client_web/js/settings.js';
import { same } from './same.mjs';

test('preview size', () => same(s.previewSize(320, 544, 0.5), { width: 160, height: 272 }));

test('fit keeps the screen aspect, long side capped', () => {
  same(s.fitResolution(390, 844, 3, 1088), { width: 503, height: 1088 });
});

test('url params', () => {
  const u = s.readUrlParams('?scenario=2&n=128&width=320&height=544&preview_scale=0.25&mode=heat');
  same(u, { scene: { scenario: 2, n: 128 }, render: { width: 320, height: 544, mode: 'heat' },
    client: { resolution: '320x544', previewScale: 0.25 } });
});

test('museum url params', () => {
  const m = s.readUrlParams('?scenario=museum&n=256&motion=rigid&update=refit');
  same([m.scene, m.render], [{ n: 256, scenario: 'museum', motion: 'rigid' }, { update: 'refit' }]);
});

test('a link sets only declared sheet settings, a choice only among its choices', () => {
  same(s.readUrlParams('?update=sometimes&min_weight=0.5&time=3&specialize=false&tile_size=8&bogus=1').render, { tile_size: 8 });
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
