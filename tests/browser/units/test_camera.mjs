// device/camera.js (server/sessions/controller.py's camera moves, ported): orbit keeps target and distance, never flips.

import { test } from 'node:test';
import * as cam from '../../../client_web/js/device/camera.js';
import { assert, near } from './same.mjs';

const c0 = { position: [0, 0, 100], target: [0, 0, 0], up: [0, 1, 0], fov_y: 60 };

test('orbit: yaw 90° moves the camera to its right', () => {
  const c1 = cam.orbitCamera(c0, 90, 0);
  assert.ok(near(c1.position[0], 100, 1e-9) && near(c1.position[2], 0, 1e-9), JSON.stringify(c1));
});

test('orbit: pitch clamped short of the pole', () => {
  const c2 = cam.orbitCamera(c0, 0, 500);
  assert.ok(near(cam.polarAngle(c2), 180 - cam.MIN_POLAR_DEG, 1e-9) &&
    near(cam.targetDistance(c2), 100, 1e-9) && c2.target.every((x) => x === 0), JSON.stringify(c2));
});

test('applyGesture: orbit', () => {
  assert.ok(near(cam.applyGesture(c0, { type: 'orbit', yaw: 90, pitch: 0 }, { viewportHeight: 100 }).position[0], 100, 1e-9));
});
