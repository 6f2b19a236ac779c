// settings.js: preview and fitted sizes, URL parameters.

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
