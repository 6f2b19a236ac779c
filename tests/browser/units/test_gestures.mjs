// gestures.js: one pointer pans, two pinch or twist, taps, double tap, wheel, keys.

import { test } from 'node:test';
import * as g from '../../../client_web/js/gestures.js';
import { assert, near, same } from './same.mjs';

function recorder() {
  const ev = [];
  const r = new g.GestureRecognizer({
    onPan: (dx, dy) => ev.push(['pan', dx, dy]), onPinch: (k) => ev.push(['pinch', k]),
    onReset: () => ev.push(['reset']), onStart: () => ev.push(['start']), onEnd: () => ev.push(['end']),
  });
  return { r, ev };
}

test('pan: slop travel included, then deltas', () => {
  const { r, ev } = recorder();
  r.down(1, 100, 100, 0); r.move(1, 102, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 95, 30); r.up(1, 120, 95, 40);
  same(ev, [['start'], ['pan', 10, 0], ['pan', 10, -5], ['end']]);
});

test('pinch: ratios of finger distance, no pan after a pinch', () => {
  const { r, ev } = recorder();
  r.down(1, 100, 100, 0); r.move(1, 102, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 95, 30); r.up(1, 120, 95, 40);
  ev.length = 0;
  r.down(1, 100, 100, 100); r.down(2, 200, 100, 100); r.move(2, 300, 100, 110); r.move(1, 50, 100, 120);
  r.up(2, 300, 100, 130); r.move(1, 10, 100, 140); r.up(1, 10, 100, 150);
  same(ev, [['start'], ['pinch', 2], ['pinch', 1.25], ['end']]);
});

test('double tap resets', () => {
  const { r, ev } = recorder();
  r.down(1, 50, 50, 1000); r.up(1, 51, 50, 1050); r.down(1, 52, 51, 1200); r.up(1, 52, 51, 1250);
  same(ev.filter((e) => e[0] === 'reset'), [['reset']]);
});

test('two slow taps do not', () => {
  const { r, ev } = recorder();
  r.down(1, 50, 50, 1000); r.up(1, 51, 50, 1050); r.down(1, 52, 51, 1200); r.up(1, 52, 51, 1250);
  ev.length = 0;
  r.down(1, 50, 50, 3000); r.up(1, 50, 50, 3050); r.down(1, 50, 50, 3600); r.up(1, 50, 50, 3650);
  same(ev.filter((e) => e[0] === 'reset'), []);
});

test('wheel up is forward', () => {
  assert.ok(g.wheelScale(-100) > 1 && g.wheelScale(100) < 1 && near(g.wheelScale(-100) * g.wheelScale(100), 1));
});

test('trackpad pinch (ctrl) is more sensitive', () => {
  assert.ok(g.wheelScale(-10, 0, true) > g.wheelScale(-10, 0, false));
});

test('line mode counts lines', () => {
  assert.ok(near(g.wheelScale(-3, 1), g.wheelScale(-48, 0)));
});

test('keys', () => {
  same(['ArrowRight', 'ArrowUp', '+', '-', '0', 'x'].map((k) => g.keyGesture(k, 10)),
    [{ type: 'pan', dx: -10, dy: 0 }, { type: 'pan', dx: 0, dy: 10 }, { type: 'pinch', scale: 1.25 },
      { type: 'pinch', scale: 0.8 }, { type: 'reset' }, null]);
});

// Two fingers 100 px apart turning about their midpoint: 2°, then to 10°, then to 25° (clockwise on screen).
function twist() {
  const ev = [];
  const r = new g.GestureRecognizer({
    onPan: (dx, dy) => ev.push(['pan', dx, dy]), onOrbitDrag: (dx, dy) => ev.push(['orbit', dx, dy]),
    onPinch: (k) => ev.push(['pinch', k]), onTwist: (d) => ev.push(['twist', Math.round(d * 1e6) / 1e6]),
  });
  const at = (deg) => {
    const a = deg * Math.PI / 180;
    return [[200 - 50 * Math.cos(a), 300 - 50 * Math.sin(a)], [200 + 50 * Math.cos(a), 300 + 50 * Math.sin(a)]];
  };
  r.down(1, ...at(0)[0], 0); r.down(2, ...at(0)[1], 0);
  for (const deg of [2, 10, 25]) { const [p1, p2] = at(deg); r.move(1, ...p1, 1); r.move(2, ...p2, 1); }
  r.up(1, undefined, undefined, 2); r.up(2, undefined, undefined, 2);
  return { r, ev };
}

test('twist: nothing inside the slop, then the whole turn', () => {
  const twists = twist().ev.filter((e) => e[0] === 'twist');
  assert.ok(twists.length >= 2 && near(twists.reduce((acc, e) => acc + e[1], 0), 25, 1e-6) && twists[0][1] >= 4,
    JSON.stringify(twists));
});

test('twist: the pinches of a turn at one distance cancel out', () => {
  const { ev } = twist();
  assert.ok(near(ev.filter((e) => e[0] === 'pinch').reduce((acc, e) => acc * e[1], 1), 1, 1e-9));
});

test('turn folds angles', () => {
  same([g.turn(10, 350), g.turn(350, 10), g.turn(180, -180)], [20, -20, 0]);
});

test('orbit mode: one finger orbits', () => {
  const { r, ev } = twist();
  ev.length = 0;
  r.dragMode = 'orbit';
  r.down(1, 100, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 104, 30); r.up(1, 120, 104, 40);
  same(ev, [['orbit', 10, 0], ['orbit', 10, 4]]);
});

test('a right-button / shift drag orbits in pan mode', () => {
  const { r, ev } = twist();
  r.dragMode = 'orbit';
  r.down(1, 100, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 104, 30); r.up(1, 120, 104, 40);
  ev.length = 0;
  r.dragMode = 'pan';
  r.down(1, 100, 100, 10, { orbit: true }); r.move(1, 110, 100, 20); r.up(1, 110, 100, 30);
  same(ev, [['orbit', 10, 0]]);
});

test('shift + arrows orbit, other keys as ever', () => {
  same(['ArrowRight', 'ArrowUp', '+'].map((k) => g.keyGesture(k, 10, true)),
    [{ type: 'orbit', yaw: 5, pitch: 0 }, { type: 'orbit', yaw: 0, pitch: -5 }, { type: 'pinch', scale: 1.25 }]);
});
