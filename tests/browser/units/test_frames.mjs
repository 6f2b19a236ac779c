// frames.js: gestures merged while one is in flight; the FrameScheduler with a fake transport
// and fake timers (one request at a time, preview → refine, late frames dropped, animation).
// The scheduler's tests are one story, in order: each test starts where the one before ended.

import { test } from 'node:test';
import * as f from '../../../client_web/js/frames.js';
import { same } from './same.mjs';

test('merge: pans add, pinches multiply', () => {
  const acc = f.emptyGesture();
  [{ type: 'pan', dx: 3, dy: 1 }, { type: 'pinch', scale: 2 }, { type: 'pan', dx: -1, dy: 2 }, { type: 'pinch', scale: 1.5 }]
    .forEach((x) => f.mergeGesture(acc, x));
  same(f.gestureOps(acc), [{ type: 'pinch', scale: 3 }, { type: 'pan', dx: 2, dy: 3 }]);
});

test('merge: a reset drops what came before it', () => {
  const acc = f.emptyGesture();
  [{ type: 'pan', dx: 3, dy: 1 }, { type: 'pinch', scale: 2 }, { type: 'pan', dx: -1, dy: 2 }, { type: 'pinch', scale: 1.5 },
    { type: 'reset' }, { type: 'pan', dx: 5, dy: 0 }]
    .forEach((x) => f.mergeGesture(acc, x));
  same(f.gestureOps(acc), [{ type: 'reset' }, { type: 'pan', dx: 5, dy: 0 }]);
});

test('merge: orbits add (yaw modulo a turn, pitch within ±180°)', () => {
  const acc = f.emptyGesture();
  [{ type: 'orbit', yaw: 200, pitch: 10 }, { type: 'pan', dx: 1, dy: 0 }, { type: 'orbit', yaw: 100, pitch: 250 }]
    .forEach((x) => f.mergeGesture(acc, x));
  same(f.gestureOps(acc), [{ type: 'orbit', yaw: -60, pitch: 180 }, { type: 'pan', dx: 1, dy: 0 }]);
});

// ---- the scheduler's story ----
let now = 0, timers = [], tid = 0;
const fakeTimers = {
  set: (fn, ms) => { timers.push({ id: ++tid, at: now + ms, fn }); return tid; },
  clear: (id) => { timers = timers.filter((t) => t.id !== id); },
  now: () => now,
};
const runTimers = () => {
  const due = timers.filter((t) => t.at <= now);
  timers = timers.filter((t) => t.at > now);
  due.forEach((t) => t.fn());
};
const calls = [], shown = [];
let version = 0, release = null;
const transport = {
  gesture: (op, level) => new Promise((res) => {
    calls.push(['gesture', op, level]); version++; const v = version; release = () => res({ version: v, level });
  }),
  frame: (level) => new Promise((res) => { calls.push(['frame', level]); const v = version; release = () => res({ version: v, level }); }),
};
const sch = new f.FrameScheduler({ transport, display: (fr, level) => shown.push([fr.version, level]), timers: fakeTimers, refineDelayMs: 200 });
const tick = () => new Promise((r) => setTimeout(r, 0));
const last = () => calls[calls.length - 1];

test('one request in flight', () => {
  sch.gesture({ type: 'pan', dx: 1, dy: 0 });
  sch.gesture({ type: 'pan', dx: 2, dy: 0 });   // in flight: merged
  sch.gesture({ type: 'pan', dx: 3, dy: 1 });
  same(calls.length, 1);
});

test('merged pans go as one, with a preview frame', async () => {
  release(); await tick(); await tick();
  same(calls[1], ['gesture', { type: 'pan', dx: 5, dy: 1 }, 'preview']);
});

test('no refine while a gesture is in flight', () => same(timers.length, 0));

test('previews shown in order', async () => {
  release(); await tick(); await tick();
  same(shown, [[1, 'preview'], [2, 'preview']]);
});

test('refine is scheduled', () => same(timers.length, 1));

test('not before its delay', () => {
  now += 100; runTimers();
  same(calls.length, 2);
});

test('full frame after the delay', async () => {
  now += 100; runTimers(); await tick();
  same(calls[2], ['frame', 'full']);
});

test('full frame shown', async () => {
  release(); await tick(); await tick();
  same(shown[2], [2, 'full']);
});

test('idle', () => same(sch.idle, true));

// A late frame (lower version than the one shown) is dropped.
test('late frame dropped', async () => {
  const late = await sch._offer({ version: 1 }, ++sch.seq, 'full');
  same([late, shown.length, sch.dropped], [false, 3, 1]);
});

// Tasks run before gestures and in between, never two requests at once.
test('task between gestures', async () => {
  const order = [];
  sch.gesture({ type: 'pinch', scale: 2 });
  const t = sch.enqueue(async () => { order.push('task'); });
  sch.gesture({ type: 'pinch', scale: 2 });
  release(); await tick(); await t; await tick();
  same([order, last()], [['task'], ['gesture', { type: 'pinch', scale: 2 }, 'preview']]);
});

// Animation: animate() asks for preview frames one at a time; no refine while it plays; the
// full frame comes refineDelayMs after the last animation frame.
let before = 0;
test('animation frame at the preview level', async () => {
  release(); await tick(); await tick();
  timers = [];
  before = calls.length;
  sch.animate();
  sch.animate();                                    // already due: still one request
  same([calls.length - before, last()], [1, ['frame', 'preview']]);
});

test('next animation frame follows, no refine meanwhile', async () => {
  sch.animate();                                    // the next one is due while this is in flight
  release(); await tick(); await tick();
  same([calls.length - before, last(), timers.length], [2, ['frame', 'preview'], 0]);
});

test('paused: the refine is scheduled', async () => {
  release(); await tick(); await tick();
  same(timers.length, 1);
});

test('full frame after the last animation frame', async () => {
  now += 200; runTimers(); await tick();
  same(last(), ['frame', 'full']);
});

test('idle after the animation', async () => {
  release(); await tick(); await tick();
  same(sch.idle, true);
});

// ---- a new page or scene: a quick preview first; each gesture's preview timed ----
function quickStory({ quickFirst }) {
  const log = [], taken = [];
  let clock = 0, next = null;
  const tr = {
    quickFirst: () => quickFirst,
    previewTaken: (ms, fr) => taken.push([ms, fr.level]),
    gesture: (op, level) => new Promise((res) => { log.push(['gesture', level]); next = () => { clock += 40; res({ version: 1, level }); }; }),
    frame: (level) => new Promise((res) => { log.push(['frame', level]); next = () => { clock += level === 'full' ? 900 : 30; res({ version: 1, level }); }; }),
  };
  const seen = [];
  const s = new f.FrameScheduler({
    transport: tr, display: (fr, level) => seen.push(level), refineDelayMs: 0,
    timers: { set: () => 1, clear: () => {}, now: () => clock },
  });
  return { s, log, taken, seen, release: async () => { next(); await tick(); await tick(); await tick(); } };
}

test('a new page: a quick preview, then the full frame; the preview\'s time is not a gesture\'s', async () => {
  const q = quickStory({ quickFirst: true });
  q.s.invalidate(true);
  same(q.log, [['frame', 'preview']]);
  await q.release();
  same([q.log, q.seen], [[['frame', 'preview'], ['frame', 'full']], ['preview']]);
  await q.release();
  same([q.seen, q.taken, q.s.idle], [['preview', 'full'], [], true]);
});

test('no quick preview where the transport says it is not smaller, nor for a plain invalidate', async () => {
  const q = quickStory({ quickFirst: false });
  q.s.invalidate(true);
  same(q.log, [['frame', 'full']]);
  const r = quickStory({ quickFirst: true });
  r.s.invalidate();
  same(r.log, [['frame', 'full']]);
});

test('a gesture\'s preview is timed from its request to the screen', async () => {
  const q = quickStory({ quickFirst: true });
  q.s.gesture({ type: 'pan', dx: 1, dy: 0 });
  await q.release();
  same(q.taken, [[40, 'preview']]);
});

// ---- a gesture never waits for a frame ----
// A fake transport whose frames take as long as the test says and honour their abort signal.
function abandonStory({ abortable }) {
  const log = [], seen = [], errors = [];
  let next = null, v = 0;
  const tr = {
    abortable: () => abortable,
    gesture: (op, level) => new Promise((res) => { log.push(['gesture', level]); v++; const ver = v; next = () => res({ version: ver, level }); }),
    frame: (level, onPreview, signal) => new Promise((res, rej) => {
      log.push(['frame', level]);
      const ver = v;
      if (signal) signal.addEventListener('abort', () => { log.push(['aborted', level]); rej(new DOMException('stopped', 'AbortError')); });
      next = () => res({ version: ver, level });
    }),
  };
  const s = new f.FrameScheduler({
    transport: tr, display: (fr, level) => seen.push([fr.version, level]), onError: (e) => errors.push(e.name),
    refineDelayMs: 200, timers: { set: () => 1, clear: () => {}, now: () => 0 },
  });
  return { s, log, seen, errors, release: async () => { next(); await tick(); await tick(); await tick(); } };
}

test('a gesture during a full frame aborts it and goes at once', async () => {
  const q = abandonStory({ abortable: true });
  q.s.invalidate();
  same(q.log, [['frame', 'full']]);
  q.s.gesture({ type: 'pan', dx: 4, dy: 0 });
  same(q.log, [['frame', 'full'], ['aborted', 'full'], ['gesture', 'preview']]);
  await tick(); await tick();
  await q.release();
  same([q.seen, q.errors, q.s.abandoned], [[[1, 'preview']], [], 1]);
});

test('the abandoned frame\'s answer is never shown, and leaves the gesture in flight', async () => {
  const q = abandonStory({ abortable: true });
  let late = null;
  q.s.transport.frame = (level) => new Promise((res) => { q.log.push(['frame', level]); late = () => res({ version: 0, level }); });
  q.s.invalidate();
  q.s.gesture({ type: 'pan', dx: 4, dy: 0 });
  late(); await tick(); await tick();                  // the abandoned frame answers anyway
  q.s.gesture({ type: 'pan', dx: 1, dy: 0 });          // merged: the gesture still holds the flight
  same([q.seen, q.log], [[], [['frame', 'full'], ['gesture', 'preview']]]);
});

test('a gesture during a quick first preview or an animation frame goes at once too', async () => {
  for (const start of [(s) => { s.transport.quickFirst = () => true; s.invalidate(true); }, (s) => s.animate()]) {
    const q = abandonStory({ abortable: true });
    start(q.s);
    q.s.gesture({ type: 'pinch', scale: 2 });
    same(q.log, [['frame', 'preview'], ['aborted', 'preview'], ['gesture', 'preview']]);
  }
});

test('where frames cannot be abandoned (device mode) the gesture waits for the frame', async () => {
  const q = abandonStory({ abortable: false });
  q.s.invalidate();
  q.s.gesture({ type: 'pan', dx: 4, dy: 0 });
  same(q.log, [['frame', 'full']]);
  await q.release();
  same(q.log, [['frame', 'full'], ['gesture', 'preview']]);
});

test('a gesture waits for a gesture or a task (merged), never aborting them', async () => {
  const q = abandonStory({ abortable: true });
  q.s.gesture({ type: 'pan', dx: 1, dy: 0 });
  q.s.gesture({ type: 'pan', dx: 1, dy: 0 });
  same([q.log, q.s.abandoned], [[['gesture', 'preview']], 0]);
});
