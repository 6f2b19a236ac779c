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

// The path integrator: its sample counts are paths, its depth goes to 16, and a frame's work is
// counted as the service counts it (renderer/frame/cost.py's path_segments / request_work, from /api/info).
const pathInfo = { ...info, max_recursion_depth: 8,
  path: { samples_per_pixel: [1, 4, 16, 64, 256, 1024], max_samples: 4096, max_depth: 16, segments_limit: 6.58, segments_rate: 0.644 } };
const pctx = (render = {}) => ({ ...ctx({ integrator: 'path', width: 126, height: 272, samples_per_pixel: 64, ...render }), info: pathInfo });

test("a path sample's segments are the service's (renderer/frame/cost.py's path_segments at depths 1, 2, 4, 8, 16)", () => {
  const want = [1.0, 2.98648, 5.0896378892800005, 6.3236488497546715, 6.572415582889342];
  [1, 2, 4, 8, 16].forEach((d, i) => assert.ok(Math.abs(lim.pathSegments(d, pathInfo) - want[i]) < 1e-12, `${d}`));
});

test('the sheet offers the path counts with the path integrator, the sub-pixel grids without', () => {
  same([lim.sampleChoices(pctx()), lim.sampleChoices({ ...ctx(), info: { ...pathInfo, samples_per_pixel: [1, 4, 9, 16] } })],
    [[1, 4, 16, 64, 256, 1024], [1, 4, 9, 16]]);
});

test('path counts the work cap admits: 126 × 272 at depth 8 up to 64, 503 × 1088 up to 4', () => {
  same([lim.samplesAllowed(pctx()), lim.samplesAllowed(pctx({ width: 503, height: 1088 }))], [[1, 4, 16, 64], [1, 4]]);
});

test('path depth: up to 16, unless the work cap stops it (503 × 1088 × 16 paths: 3); Whitted stops at 8', () => {
  same([lim.range('max_recursion_depth', pctx()).max,
    lim.range('max_recursion_depth', pctx({ width: 503, height: 1088, samples_per_pixel: 16 })).max,
    lim.range('max_recursion_depth', { ...ctx({ width: 126, height: 272 }), info: pathInfo }).max], [16, 3, 8]);
  assert.match(lim.check('max_recursion_depth', 12, { ...ctx({ width: 126, height: 272, max_recursion_depth: 12 }), info: pathInfo }),
    /Recursion depth: a whole number 1 … 8 with the Whitted tracer \(up to 16 with the path integrator\)/);
  same(lim.check('max_recursion_depth', 16, pctx({ max_recursion_depth: 16 })), null);
});

test('any path count within the cap passes (a link may ask for 100); past it, the range is named', () => {
  same([lim.check('samples_per_pixel', 100, pctx({ samples_per_pixel: 100 })), lim.check('samples_per_pixel', 64, pctx())], [null, null]);
  assert.match(lim.check('samples_per_pixel', 256, pctx({ samples_per_pixel: 256 })),
    /\(samples per pixel\): a whole number 1 … 174 for a 126 × 272 frame at recursion depth 8 with the path integrator/);
});

test('the path integrator traces no sub-pixels: its width is bounded by the work, not by 4096 / √samples', () => {
  same(lim.range('width', pctx({ height: 16, samples_per_pixel: 16 })).max, 4096);
  same(lim.range('width', pctx({ height: 1088, samples_per_pixel: 16 })).max, Math.floor(37879808 / (1088 * 16 * lim.pathSegments(8, pathInfo))));
});

// The samples and depths come from the service's declaration (settings[].integrators), not from lists
// of the client's: a service that declared other values is offered those.
test('the sheet offers what the service declares for each integrator', () => {
  const declared = [
    { name: 'samples_per_pixel', integrators: {
      whitted: { choices: [1, 9], offered: [1, 9], minimum: null, maximum: null, subpixel_grid: true, modes: null },
      path: { choices: null, offered: [2, 8], minimum: 1, maximum: 8, subpixel_grid: false, modes: null } } },
    { name: 'max_recursion_depth', integrators: {
      whitted: { minimum: 1, maximum: 3, choices: null, offered: null, subpixel_grid: false, modes: null },
      path: { minimum: 1, maximum: 5, choices: null, offered: null, subpixel_grid: false, modes: ['color'] } } },
  ];
  const own = (render) => ({ ...ctx({ width: 100, height: 100, max_recursion_depth: 1, ...render }), info: { ...info, settings: declared } });
  same([lim.sampleChoices(own()), lim.sampleChoices(own({ integrator: 'path' }))], [[1, 9], [2, 8]]);
  same([lim.subpixels(9, own()), lim.subpixels(8, own({ integrator: 'path' }))], [3, 1]);
  same(lim.range('width', own({ samples_per_pixel: 9 })).max, Math.floor(4096 / 3));
  same([lim.maxDepth(own()), lim.maxDepth(own({ integrator: 'path' })), lim.maxDepth(own({ integrator: 'path', mode: 'recursion' }))],
    [3, 5, 3]);
  assert.match(lim.check('samples_per_pixel', 9, own({ integrator: 'path', samples_per_pixel: 9 })), /a whole number 1 … 8 /);
  // the checkout's own declaration: Whitted's grids and the path integrator's offered counts
  same([lim.sampleChoices(ctx()), lim.sampleChoices(pctx())], [[1, 4, 9, 16], [1, 4, 16, 64, 256, 1024]]);
});
