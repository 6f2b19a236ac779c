// ui/controls.js: an orbit drag "grabs the scene", the frame's height turning 180°.

import { test } from 'node:test';
import { ORBIT_DEGREES_PER_VIEW, orbitDrag } from '../../../client_web/js/ui/controls.js';
import { same } from './same.mjs';

test('dragging right turns the scene right, down turns it down; a frame height is 180°', () => {
  same(ORBIT_DEGREES_PER_VIEW, 180);
  same(orbitDrag(100, 50, 200), { type: 'orbit', yaw: -90, pitch: -45 });
});
