// display.js: what the overlay, the legend, the test hook and the canvas's label say of a frame.

import { test } from 'node:test';
import { containedSize, describeFrame, sceneLabel } from '../../../client_web/js/display.js';
import { same } from './same.mjs';

const state = (o = {}) => ({
  render: { mode: 'color' }, scene: { scenario: 1, n: 512, n_triangles: 0 }, anim: { animated: false, playing: false }, ...o,
});

test('a frame fits its stage (object-fit: contain)', () => {
  same([containedSize(400, 800, 0.5), containedSize(800, 400, 1), containedSize(300, 900, 1)],
    [{ width: 400, height: 800 }, { width: 400, height: 400 }, { width: 300, height: 300 }]);
});

test('the label names the scene of the frame on screen', () => {
  same([
    sceneLabel({ scenario: 2 }, { n: 64, triangles: 0, mode: 'heat' }),
    sceneLabel({ scenario: 'museum', motion: 'rigid' }, { n: 832, triangles: 0, mode: 'color' }),
    sceneLabel({ scenario: 'mesh:teapot', meshes: 1 }, { n: 3, triangles: 6320, mode: 'color' }),
    sceneLabel({ scenario: 'mesh:mixed', meshes: 3 }, { n: 4, triangles: 9, mode: 'depth' }),
    sceneLabel({}, { n: 8, triangles: 0, mode: 'color', scenario: 3 }),
    sceneLabel({ scenario: 'sky:2' }, { n: 64, triangles: 0, mode: 'color' }),
    sceneLabel({ scenario: 'mesh:table', shapes: 14 }, { n: 0, triangles: 0, mode: 'color' })],
  ['Ray-traced scene: scenario 2, 64 spheres, heat mode',
    'Ray-traced animated museum: 832 spheres (rigid), color mode',
    'Ray-traced mesh scene: teapot, 3 spheres, 6320 triangles in 1 mesh, color mode',
    'Ray-traced mesh scene: mixed, 4 spheres, 9 triangles in 3 meshes, depth mode',
    'Ray-traced scene: scenario 3, 8 spheres, color mode',
    'Ray-traced scene: scenario 2 under the sky, 64 spheres, color mode',
    'Ray-traced mesh scene: table, 0 spheres, 14 analytic shapes, color mode']);
});

test('a server frame: its stats first, then what it was asked with', () => {
  const frame = { version: 7, contentType: 'image/png', timing: { total: 9 }, stats: { n_spheres: 500, time: 1.5 }, t0: 100,
    meta: { sessionId: 's', n: 512, mode: 'recursion', method: 'bih', samples: 4, minWeight: 0.03, scenario: 1, triangles: 0, meshes: 0 } };
  const d = describeFrame(frame, 'full', { width: 64, height: 32 }, state(), null, 150);
  same(d.lastFrame, { level: 'full', width: 64, height: 32, version: 7, contentType: 'image/png', method: 'bih', timing: { total: 9 },
    stats: { n_spheres: 500, time: 1.5 }, clientMs: 50, renderer: 'server', renderedBy: 'server (OpenGL)', n: 500, mode: 'recursion',
    samples: 4, camera: null, part: 'final', time: 1.5, triangles: 0 });
  same([d.legend, d.label, d.overlay.time, d.overlay.minWeight], ['recursion', 'Ray-traced scene: scenario 1, 500 spheres, recursion mode', null, 0.03]);
});

test('a device frame: who drew it, the scene time only for an animated scene, no legend for colour', () => {
  const frame = { version: 3, renderer: 'device', rendererInfo: 'WebGL2', method: 'bvh', camera: { fov_y: 60 }, part: 'centres',
    stats: { time: 2 }, t0: 0, meta: { n: 64, scenario: 'museum', motion: 'rigid' } };
  const d = describeFrame(frame, 'preview', { width: 8, height: 8 }, state({ anim: { animated: true, playing: true },
    scene: { scenario: 'museum', n_triangles: 12 } }), 'llvmpipe', 20);
  same([d.lastFrame.renderedBy, d.lastFrame.method, d.lastFrame.part, d.lastFrame.triangles, d.lastFrame.mode, d.legend],
    ['device (WebGL2)', 'bvh', 'centres', 12, undefined, null]);
  same([d.overlay.time, d.overlay.playing, d.overlay.clientMs], [2, true, 20]);
  same(describeFrame({ ...frame, renderer: undefined }, 'full', { width: 8, height: 8 }, state(), 'llvmpipe', 20).lastFrame.renderedBy,
    'server (llvmpipe)');
});
