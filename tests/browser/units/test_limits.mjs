// ui/limits.js: the form refuses what the service would, naming the range; what applies.

import './declared.mjs';
import { test } from 'node:test';
import * as lim from '../../../client_web/js/ui/limits.js';
import { assert, same } from './same.mjs';

const info = {
  limits: { max_image_side: 4096, max_spheres: 2097152, max_work: 1088 * 1088 * 8 * 4, max_bruteforce_work: 640 * 1088 * 512 },
  method_settings: {
    bih: { settings: ['max_prims', 'max_tree_depth'], modes: ['color', 'heat'], tests_every_sphere: false },
    kdtree: { settings: ['max_tree_depth'], modes: null, tests_every_sphere: false },
    bvh: { settings: ['max_prims', 'max_tree_depth', 'update'], modes: null, tests_every_sphere: false },
    hre: { settings: ['tile_size'], modes: null, tests_every_sphere: true },
    bruteforce: { settings: [], modes: null, tests_every_sphere: true },
  },
  museum_room_spheres: 576,
};
const ctx = (render = {}, scene = {}, extra = {}) => ({
  info, scene: { scenario: 1, n: 512, ...scene },
  render: { width: 503, height: 1088, samples_per_pixel: 4, max_recursion_depth: 8, method: 'bih', mode: 'color', ...render }, ...extra,
});

test('width at 4 spp: ≤ 4096 / 2', () => same(lim.range('width', ctx({ height: 100 })).max, 2048));

test('width 4096 at 4 spp is refused, naming the range and the samples', () => {
  assert.match(lim.check('width', 4096, ctx({ width: 4096, height: 100 })), /Width: a whole number 8 … 2,048 at 4 samples per pixel/);
});

test('depth 99 refused with its range', () => {
  assert.match(lim.check('max_recursion_depth', 99, ctx({ max_recursion_depth: 99 })), /Recursion depth: a whole number 1 … /);
});

test('n = 0 refused', () => {
  assert.match(lim.check('n', 0, ctx({}, { n: 0 })), /Spheres \(n\): a whole number 1 … 2,097,152/);
});

test('museum n: the room counts', () => {
  assert.ok(lim.range('n', ctx({}, { scenario: 'museum', n: 10 })).max === 2097152 - 1024 &&
    lim.range('n', ctx({}, { scenario: 'museum' })).min === 0);
});

test('samples allowed at 503 × 1088, depth 8', () => same(lim.samplesAllowed(ctx()), [1, 4]));

test('brute force over its cap is refused at the method', () => {
  assert.match(lim.check('method', 'bruteforce', ctx({ method: 'bruteforce' })), /tests every sphere/);
});

test('what applies', () => {
  same([
    lim.applies('update', ctx()), lim.applies('update', ctx({ method: 'bvh' }, {}, { animated: true })),
    lim.applies('max_prims', ctx({ method: 'kdtree' })), lim.applies('max_tree_depth', ctx({ method: 'kdtree' })),
    lim.applies('tile_size', ctx()), lim.applies('tile_size', ctx({ method: 'hre' })),
    lim.applies('radius', ctx({}, { scenario: 'museum' })), lim.applies('previewFormat', ctx({}, {}, { renderer: 'device' }))],
  [false, true, false, true, false, true, false, false]);
});

test('tone map, exposure and denoiser apply to the path integrator only, refinement to colour', () => {
  const display = ['tone_map', 'exposure', 'denoise'], refine = ['refine_samples', 'refine_time_ms', 'refine_noise'];
  const cases = (name) => [lim.applies(name, ctx()), lim.applies(name, ctx({ integrator: 'whitted' })),
    lim.applies(name, ctx({ integrator: 'path' })), lim.applies(name, ctx({ integrator: 'whitted', mode: 'depth' }))];
  same(display.flatMap(cases), display.flatMap(() => [false, false, true, false]));
  same(refine.flatMap(cases), refine.flatMap(() => [true, true, true, false]));
});

test('valid values pass', () => {
  same([lim.check('width', 320, ctx({ width: 320 })), lim.check('n', 64, ctx({}, { n: 64 })),
    lim.check('samples_per_pixel', 4, ctx())], [null, null, null]);
});
