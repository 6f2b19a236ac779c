// ui/refine.js: the refinement counter's words and bar for a stream's progress.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { refineFraction, refineText } from '../../../client_web/js/ui/refine.js';

const p = (o) => ({ samples: 64, target_samples: 256, target_ms: 10000, elapsed_ms: 1000, done: false, reason: null, ...o });

test('the counter says the samples of the target while the stream goes on', () => {
  assert.equal(refineText(p({})), '64 / 256 samples');
  assert.equal(refineText(null), '');
  assert.equal(refineText(p({ noise: 0.031, target_noise: 0.02 })), '64 / 256 samples · noise 3.1 %');
  assert.equal(refineText(p({ noise: 0.031, target_noise: 0 })), '64 / 256 samples');
});

test('a finished stream says why it stopped', () => {
  assert.equal(refineText(p({ samples: 256, done: true, reason: 'samples' })), '256 samples');
  assert.equal(refineText(p({ samples: 96, done: true, reason: 'time' })), '96 samples (10 s)');
  assert.equal(refineText(p({ done: true, reason: 'held' })), '64 samples (memory full)');
  assert.equal(refineText(p({ done: true, reason: 'noise', noise: 0.0123 })), '64 samples (noise 1.2 %)');
});

test('the bar follows the samples, or the time when that is further', () => {
  assert.equal(refineFraction(p({})), 0.25);
  assert.equal(refineFraction(p({ elapsed_ms: 5000 })), 0.5);
  assert.equal(refineFraction(p({ target_ms: 0, elapsed_ms: 1e9 })), 0.25);
  assert.equal(refineFraction(p({ done: true })), 1);
  assert.equal(refineFraction(null), 0);
});
