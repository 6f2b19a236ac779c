// ui/messages.js: the service's 422s in the panel's words, at the field their loc names.

import './declared.mjs';
import { test } from 'node:test';
import * as msg from '../../../client_web/js/ui/messages.js';
import { assert, same } from './same.mjs';

test('422 → its field, in the panel\'s words', () => {
  const e = { status: 422, detail: [{ loc: ['body', 'width'], msg: 'width: width × height × max_recursion_depth × samples_per_pixel = 1 exceeds the limit 2 (POCKETRAY_MAX_WORK); lower width, height, max_recursion_depth or samples_per_pixel' }] };
  const x = msg.explain(e);
  assert.ok(x.field === 'width' && x.text.startsWith('Width: width × height × recursion depth × samples per pixel') &&
    !/samples_per_pixel|max_recursion_depth|POCKETRAY_/.test(x.text), JSON.stringify(x));
});

test('loc → field', () => {
  same([msg.fieldOf(['scene', 'n']), msg.fieldOf(['body', 'museum', 'n']), msg.fieldOf(['query', 'samples_per_pixel']), msg.fieldOf(['body'])],
    ['n', 'n', 'samples_per_pixel', null]);
});

test('a cost refusal → the largest size it accepts, the aspect kept', () => {
  // "width: at most 500" at a height of 2000: 500 × 2000 pixels fit, so 707 × 1414 with the aspect kept
  const e = { status: 422, detail: [{ loc: ['query', 'width'], msg: 'width: the frame would take about 20,000 ms of GL time, over the cap of 10,000 ms; width: at most 500 at these settings' }] };
  same(msg.fitRefused(e, { width: 1000, height: 2000, samples_per_pixel: 4 }),
    { settings: { width: 707, height: 1414 }, text: 'Too costly at 1000 × 2000: 707 × 1414 instead.' });
});

test('a work-cap refusal of samples → the largest count (paths: any; Whitted: a square grid)', () => {
  const e = { status: 422, detail: [{ loc: ['body', 'samples_per_pixel'], msg: 'samples_per_pixel: width × height × samples_per_pixel × expected segments = 1088 × 1088 × 4096 × 6.32 = 30,660,941,349 exceeds the limit 37879808 (POCKETRAY_MAX_WORK)' }] };
  same(msg.fitRefused(e, { width: 1088, height: 1088, samples_per_pixel: 4096, integrator: 'path' }).settings, { samples_per_pixel: 5 });
  same(msg.fitRefused(e, { width: 1088, height: 1088, samples_per_pixel: 4096, integrator: 'whitted' }).settings, { samples_per_pixel: 4 });
});

test('other refusals are not retried', () => {
  same([msg.fitRefused({ status: 422, detail: [{ loc: ['body', 'n'], msg: 'n: at most 100' }] }, { width: 8, height: 8 }),
    msg.fitRefused({ status: 404, detail: 'gone' }, { width: 8 })], [null, null]);
});
