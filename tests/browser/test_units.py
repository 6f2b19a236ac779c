"""The client's pure modules (gestures.js, frames.js, api.js, settings.js), run in Chromium.

No server round trips: the modules are imported as they are served, and fed with
fake pointers, a fake transport and fake timers.
"""

from __future__ import annotations

UNIT_TESTS = r"""
async () => {
  const g = await import('/js/gestures.js');
  const f = await import('/js/frames.js');
  const a = await import('/js/api.js');
  const s = await import('/js/settings.js');
  const out = {};
  const eq = (name, got, want) => { out[name] = JSON.stringify(got) === JSON.stringify(want) ? true : {got, want}; };
  const near = (x, y, e = 1e-9) => Math.abs(x - y) <= e;

  // --- gestures: one pointer pans, two pinch, taps, double tap ---
  {
    const ev = [];
    const r = new g.GestureRecognizer({
      onPan: (dx, dy) => ev.push(['pan', dx, dy]), onPinch: (k) => ev.push(['pinch', k]),
      onReset: () => ev.push(['reset']), onStart: () => ev.push(['start']), onEnd: () => ev.push(['end']),
    });
    r.down(1, 100, 100, 0); r.move(1, 102, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 95, 30); r.up(1, 120, 95, 40);
    eq('pan: slop travel included, then deltas', ev, [['start'], ['pan', 10, 0], ['pan', 10, -5], ['end']]);
    ev.length = 0;
    r.down(1, 100, 100, 100); r.down(2, 200, 100, 100); r.move(2, 300, 100, 110); r.move(1, 50, 100, 120);
    r.up(2, 300, 100, 130); r.move(1, 10, 100, 140); r.up(1, 10, 100, 150);
    eq('pinch: ratios of finger distance, no pan after a pinch', ev, [['start'], ['pinch', 2], ['pinch', 1.25], ['end']]);
    ev.length = 0;
    r.down(1, 50, 50, 1000); r.up(1, 51, 50, 1050); r.down(1, 52, 51, 1200); r.up(1, 52, 51, 1250);
    eq('double tap resets', ev.filter((e) => e[0] === 'reset'), [['reset']]);
    ev.length = 0;
    r.down(1, 50, 50, 3000); r.up(1, 50, 50, 3050); r.down(1, 50, 50, 3600); r.up(1, 50, 50, 3650);
    eq('two slow taps do not', ev.filter((e) => e[0] === 'reset'), []);
    out['wheel up is forward'] = g.wheelScale(-100) > 1 && g.wheelScale(100) < 1 && near(g.wheelScale(-100) * g.wheelScale(100), 1);
    out['trackpad pinch (ctrl) is more sensitive'] = g.wheelScale(-10, 0, true) > g.wheelScale(-10, 0, false);
    out['line mode counts lines'] = near(g.wheelScale(-3, 1), g.wheelScale(-48, 0));
    eq('keys', ['ArrowRight', 'ArrowUp', '+', '-', '0', 'x'].map((k) => g.keyGesture(k, 10)),
      [{type: 'pan', dx: -10, dy: 0}, {type: 'pan', dx: 0, dy: 10}, {type: 'pinch', scale: 1.25},
       {type: 'pinch', scale: 0.8}, {type: 'reset'}, null]);
  }

  // --- frames: merge ---
  {
    const acc = f.emptyGesture();
    [{type: 'pan', dx: 3, dy: 1}, {type: 'pinch', scale: 2}, {type: 'pan', dx: -1, dy: 2}, {type: 'pinch', scale: 1.5}]
      .forEach((x) => f.mergeGesture(acc, x));
    eq('merge: pans add, pinches multiply', f.gestureOps(acc), [{type: 'pinch', scale: 3}, {type: 'pan', dx: 2, dy: 3}]);
    f.mergeGesture(acc, {type: 'reset'}); f.mergeGesture(acc, {type: 'pan', dx: 5, dy: 0});
    eq('merge: a reset drops what came before it', f.gestureOps(acc), [{type: 'reset'}, {type: 'pan', dx: 5, dy: 0}]);
  }

  // --- frames: scheduler with a fake transport and fake timers ---
  {
    let now = 0, timers = [], tid = 0;
    const fakeTimers = {
      set: (fn, ms) => { timers.push({id: ++tid, at: now + ms, fn}); return tid; },
      clear: (id) => { timers = timers.filter((t) => t.id !== id); },
      now: () => now,
    };
    const runTimers = () => { const due = timers.filter((t) => t.at <= now); timers = timers.filter((t) => t.at > now); due.forEach((t) => t.fn()); };
    const calls = [], shown = [];
    let version = 0, release = null;
    const transport = {
      gesture: (op, level) => new Promise((res) => { calls.push(['gesture', op, level]); version++; const v = version; release = () => res({version: v, level}); }),
      frame: (level) => new Promise((res) => { calls.push(['frame', level]); const v = version; release = () => res({version: v, level}); }),
    };
    const sch = new f.FrameScheduler({transport, display: (fr, level) => shown.push([fr.version, level]), timers: fakeTimers, refineDelayMs: 200});
    const tick = () => new Promise((r) => setTimeout(r, 0));
    sch.gesture({type: 'pan', dx: 1, dy: 0});
    sch.gesture({type: 'pan', dx: 2, dy: 0});   // in flight: merged
    sch.gesture({type: 'pan', dx: 3, dy: 1});
    eq('one request in flight', calls.length, 1);
    release(); await tick(); await tick();
    eq('merged pans go as one, with a preview frame', calls[1], ['gesture', {type: 'pan', dx: 5, dy: 1}, 'preview']);
    eq('no refine while a gesture is in flight', timers.length, 0);
    release(); await tick(); await tick();
    eq('previews shown in order', shown, [[1, 'preview'], [2, 'preview']]);
    eq('refine is scheduled', timers.length, 1);
    now += 100; runTimers(); eq('not before its delay', calls.length, 2);
    now += 100; runTimers(); await tick();
    eq('full frame after the delay', calls[2], ['frame', 'full']);
    release(); await tick(); await tick();
    eq('full frame shown', shown[2], [2, 'full']);
    eq('idle', sch.idle, true);
    // A late frame (lower version than the one shown) is dropped.
    const late = await sch._offer({version: 1}, ++sch.seq, 'full');
    eq('late frame dropped', [late, shown.length, sch.dropped], [false, 3, 1]);
    // Tasks run before gestures and in between, never two requests at once.
    const order = [];
    sch.gesture({type: 'pinch', scale: 2});
    const t = sch.enqueue(async () => { order.push('task'); });
    sch.gesture({type: 'pinch', scale: 2});
    release(); await tick(); await t; await tick();
    eq('task between gestures', [order, calls[calls.length - 1]], [['task'], ['gesture', {type: 'pinch', scale: 2}, 'preview']]);
    // Animation: animate() asks for preview frames one at a time; no refine while it plays; the
    // full frame comes refineDelayMs after the last animation frame.
    release(); await tick(); await tick();
    timers = [];
    const before = calls.length;
    sch.animate();
    sch.animate();                                    // already due: still one request
    eq('animation frame at the preview level', [calls.length - before, calls[calls.length - 1]], [1, ['frame', 'preview']]);
    sch.animate();                                    // the next one is due while this is in flight
    release(); await tick(); await tick();
    eq('next animation frame follows, no refine meanwhile', [calls.length - before, calls[calls.length - 1], timers.length],
       [2, ['frame', 'preview'], 0]);
    release(); await tick(); await tick();
    eq('paused: the refine is scheduled', timers.length, 1);
    now += 200; runTimers(); await tick();
    eq('full frame after the last animation frame', calls[calls.length - 1], ['frame', 'full']);
    release(); await tick(); await tick();
    eq('idle after the animation', sch.idle, true);
  }

  // --- api helpers ---
  eq('server timing', a.parseServerTiming('build;dur=1.5, upload;dur=0.25, trace;desc="gpu";dur=7, total;dur=9'),
     {build: 1.5, upload: 0.25, trace: 7, total: 9});
  eq('retry-after seconds', a.parseRetryAfter('2'), 2000);
  eq('retry-after date', a.parseRetryAfter(new Date(10000).toUTCString(), 7000), 3000);
  eq('retry-after capped', a.parseRetryAfter('3600'), a.RETRY_AFTER_MAX_MS);
  eq('back-off grows and is capped', [1, 2, 3, 10].map((n) => a.backoffDelay(n, () => 0.5)), [500, 1000, 2000, 10000]);
  out['same scene'] = a.sameScene({n: 64}, {scenario: 1, n: 64, seed: 1, radius: 1}) && !a.sameScene({n: 65}, {n: 64});
  // A fetch that fails twice, then answers 503 with Retry-After 0, then 200.
  {
    const answers = ['fail', 'fail', 503, 200]; const statuses = [];
    const api = new a.Api({
      fetchImpl: async () => { const x = answers.shift(); if (x === 'fail') throw new TypeError('net');
        return new Response('{"ok":1}', {status: x, headers: x === 503 ? {'Retry-After': '0'} : {}}); },
      onStatus: (st) => statuses.push(st.state),
    });
    api._sleep = async () => {};
    const j = await api.json('GET', '/x');
    eq('retries until it gets through', [j, statuses], [{ok: 1}, ['offline', 'offline', 'busy', 'online']]);
    const api2 = new a.Api({fetchImpl: async () => new Response('{"detail":"bad n"}', {status: 422})});
    try { await api2.json('GET', '/x'); out['422 throws'] = false; } catch (e) { eq('422 throws', [e.status, e.detail], [422, 'bad n']); }
  }

  // --- settings helpers ---
  eq('preview size', s.previewSize(320, 544, 0.5), {width: 160, height: 272});
  eq('fit keeps the screen aspect, long side capped', s.fitResolution(390, 844, 3, 1088), {width: 503, height: 1088});
  const u = s.readUrlParams('?scenario=2&n=128&width=320&height=544&preview_scale=0.25&mode=heat');
  eq('url params', u, {scene: {scenario: 2, n: 128}, render: {width: 320, height: 544, mode: 'heat'},
                       client: {resolution: '320x544', previewScale: 0.25}});
  const m = s.readUrlParams('?scenario=museum&n=256&motion=rigid&update=refit');
  eq('museum url params', [m.scene, m.render], [{n: 256, scenario: 'museum', motion: 'rigid'}, {update: 'refit'}]);
  const museumInfo = {n_spheres: 832, museum: {n: 256, kind: 'rigid', seed: 0, absent: 0.2}, animated: true};
  out['same museum'] = a.sameScene({scenario: 'museum', n: 256, motion: 'rigid'}, museumInfo) &&
    !a.sameScene({scenario: 'museum', n: 256, motion: 'deformable'}, museumInfo) &&
    !a.sameScene({scenario: 1, n: 256}, museumInfo) && !a.sameScene({scenario: 'museum', n: 256}, {scenario: 1, n: 256});
  return out;
}
"""


def test_pure_modules(open_client):
    c = open_client("mobile", query=None)
    c.page.goto(c.server.base + "/?n=8&width=64&height=64")   # a page on the origin to import from
    results = c.page.evaluate(UNIT_TESTS)
    failed = {k: v for k, v in results.items() if v is not True}
    assert failed == {}, failed
    assert len(results) >= 25
