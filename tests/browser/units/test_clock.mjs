// clock.js: the scene clock of an animated scene.

import { test } from 'node:test';
import { sceneTime, setClock } from '../../../client_web/js/clock.js';
import { same } from './same.mjs';

const anim = (o = {}) => ({ animated: true, playing: false, time: 0, time0: 0, clock0: 0, ...o });

test('a still scene does not play', () => {
  const a = anim({ animated: false });
  same([setClock(a, true, 1000), a.playing], [false, false]);
});

test('playing, the time runs with the wall clock from where it stood (ms resolution)', () => {
  const a = anim({ time: 2 });
  same(setClock(a, true, 1000), true);
  same([sceneTime(a, 1500), sceneTime(a, 2000.4), a.time0, a.clock0], [2.5, 3, 2, 1000]);
});

test('paused, the time stops where the pause found it', () => {
  const a = anim();
  setClock(a, true, 0);
  setClock(a, false, 1250);
  same([a.playing, a.time, sceneTime(a, 9999)], [false, 1.25, 1.25]);
});

test('play while playing keeps the clock', () => {
  const a = anim();
  setClock(a, true, 0);
  setClock(a, true, 500);
  same([a.clock0, sceneTime(a, 1000)], [0, 1]);
});
