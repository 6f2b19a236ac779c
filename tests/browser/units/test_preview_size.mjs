// preview_size.js: the preview's scale from the measured times — down at once by the steps the
// time asks for, up one step after a few fast previews, bounded, with hysteresis.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { LADDER_STEP, PreviewSizer } from '../../../client_web/js/preview_size.js';

// A service whose preview costs `fixed` ms plus `perFull` ms at full scale, × scale².
const cost = (scale, { fixed = 20, perFull = 600 } = {}) => fixed + perFull * scale * scale;

test('starts at the given scale, on the ladder', () => {
  assert.equal(new PreviewSizer({ start: 0.25 }).scale, 0.25);
  assert.ok(Math.abs(new PreviewSizer({ start: 0.5 }).scale - 0.5) < 1e-12);
});

test('a slow preview brings the scale down at once, by as many steps as its time says', () => {
  const s = new PreviewSizer({ start: 1, targetMs: 80 });
  assert.equal(s.observe(620, 1), true);
  // 620 ms → 80 ms: pixels × 0.129, scale × 0.36: four steps of 2^(−1/4) are not enough, six are.
  assert.ok(Math.abs(s.scale - LADDER_STEP ** 6) < 1e-12, s.scale);
  // The service's fixed cost (20 ms) did not shrink with the pixels: the next preview takes it one step further.
  assert.equal(s.observe(cost(s.scale), s.scale), true);
  assert.ok(cost(s.scale) <= 80, cost(s.scale));
});

test('fast previews raise the scale one step at a time, and it settles under the target', () => {
  const s = new PreviewSizer({ start: 0.125, targetMs: 80, settle: 3 });
  const scales = [];
  for (let i = 0; i < 60; i++) {
    s.observe(cost(s.scale), s.scale);
    scales.push(s.scale);
  }
  for (let i = 1; i < scales.length; i++) assert.ok(scales[i] <= scales[i - 1] / LADDER_STEP + 1e-12, 'one step up at most');
  const tail = scales.slice(-20);
  assert.ok(tail.every((x) => x === tail[0]), `settled: ${tail}`);   // hysteresis: no toggling
  assert.ok(cost(tail[0]) <= 80, `under the target: ${cost(tail[0])} ms`);
  // …and as large as the hysteresis lets it be: one step up would be over 0.7 × the target.
  assert.ok(cost(tail[0] / LADDER_STEP) > 0.7 * 80 * 0.9);
});

test('a time just under the target never moves the scale', () => {
  const s = new PreviewSizer({ start: 0.5, targetMs: 80 });
  for (let i = 0; i < 20; i++) assert.equal(s.observe(75, s.scale), false);
  assert.ok(Math.abs(s.scale - 0.5) < 1e-12);
});

test('bounded: never below min nor above max', () => {
  const slow = new PreviewSizer({ start: 0.5, min: 0.125 });
  for (let i = 0; i < 10; i++) slow.observe(5000, slow.scale);
  assert.equal(slow.scale, 0.125);
  const fast = new PreviewSizer({ start: 0.5, max: 0.75 });
  for (let i = 0; i < 40; i++) fast.observe(1, fast.scale);
  assert.ok(fast.scale <= 0.75 && fast.scale > 0.75 * LADDER_STEP, fast.scale);
});

test('a time measured at another scale than the present one is not counted', () => {
  const s = new PreviewSizer({ start: 0.25 });
  assert.equal(s.observe(5000, 0.5), false);
  assert.equal(s.scale, 0.25);
  assert.equal(s.observe(Number.NaN, 0.25), false);
});

test('one slow outlier among fast previews is smoothed, not obeyed in full', () => {
  const s = new PreviewSizer({ start: 0.5, targetMs: 80, smoothing: 0.5 });
  s.observe(60, s.scale);
  s.observe(60, s.scale);
  s.observe(200, s.scale);   // mean 130 ms: down, but by the mean's steps, not the outlier's
  assert.ok(Math.abs(s.scale - 0.5 * LADDER_STEP ** 2) < 1e-12, s.scale);
});

test('the default aims at 15 previews a second or more, with a margin', () => {
  assert.ok(new PreviewSizer().targetMs < 1000 / 15, new PreviewSizer().targetMs);
});
