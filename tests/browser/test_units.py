"""The client's pure modules (gestures.js, frames.js, api.js, settings.js, camera.js, bands.js,
limits.js, messages.js), run in Chromium.

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
  const cam = await import('/js/camera.js');
  const b = await import('/js/bands.js');
  const lim = await import('/js/limits.js');
  const msg = await import('/js/messages.js');
  const out = {};
  const eq = (name, got, want) => { out[name] = JSON.stringify(got) === JSON.stringify(want) ? true : {got, want}; };
  // The render settings are the service's declarations (GET /api/info), as the app learns them.
  s.learnSettings((await (await fetch('/api/info')).json()).settings);
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
  eq('a link sets only declared sheet settings, a choice only among its choices',
     s.readUrlParams('?update=sometimes&min_weight=0.5&time=3&specialize=false&tile_size=8&bogus=1').render, {tile_size: 8});
  eq('settings by their declared flags', [s.settingNames('sheet').includes('samples_per_pixel'), s.settingNames('sheet').includes('time'),
     s.settingNames('client').includes('quality'), s.settingNames('client').includes('time')], [true, false, true, false]);
  eq('values by their declared type', [s.settingValue({type: 'integer'}, '4'), s.settingValue({type: 'number'}, '0.5'),
     s.settingValue({type: 'boolean'}, 'false'), s.settingValue({type: 'string'}, 'bvh'), s.settingValue({type: 'integer'}, 'x')],
     [4, 0.5, false, 'bvh', undefined]);
  eq('labels are the declared ones', [s.FIELD_LABELS.samples_per_pixel, s.FIELD_LABELS.max_recursion_depth],
     ['Quality (samples per pixel)', 'Recursion depth']);
  const museumInfo = {n_spheres: 832, museum: {n: 256, kind: 'rigid', seed: 0, absent: 0.2}, animated: true};
  out['same museum'] = a.sameScene({scenario: 'museum', n: 256, motion: 'rigid'}, museumInfo) &&
    !a.sameScene({scenario: 'museum', n: 256, motion: 'deformable'}, museumInfo) &&
    !a.sameScene({scenario: 1, n: 256}, museumInfo) && !a.sameScene({scenario: 'museum', n: 256}, {scenario: 1, n: 256});

  // --- gestures: twist orbits (after its slop), orbit drags, shift + arrows ---
  {
    const ev = [];
    const r = new g.GestureRecognizer({
      onPan: (dx, dy) => ev.push(['pan', dx, dy]), onOrbitDrag: (dx, dy) => ev.push(['orbit', dx, dy]),
      onPinch: (k) => ev.push(['pinch', k]), onTwist: (d) => ev.push(['twist', Math.round(d * 1e6) / 1e6]),
    });
    // Two fingers 100 px apart turning about their midpoint: 2°, then to 10°, then to 25° (clockwise on screen).
    const at = (deg) => { const a = deg * Math.PI / 180; return [[200 - 50 * Math.cos(a), 300 - 50 * Math.sin(a)], [200 + 50 * Math.cos(a), 300 + 50 * Math.sin(a)]]; };
    r.down(1, ...at(0)[0], 0); r.down(2, ...at(0)[1], 0);
    for (const deg of [2, 10, 25]) { const [p1, p2] = at(deg); r.move(1, ...p1, 1); r.move(2, ...p2, 1); }
    r.up(1, undefined, undefined, 2); r.up(2, undefined, undefined, 2);
    const twists = ev.filter((e) => e[0] === 'twist');
    out['twist: nothing inside the slop, then the whole turn'] = twists.length >= 2 &&
      near(twists.reduce((acc, e) => acc + e[1], 0), 25, 1e-6) && twists[0][1] >= 4;
    out['twist: the pinches of a turn at one distance cancel out'] =
      near(ev.filter((e) => e[0] === 'pinch').reduce((acc, e) => acc * e[1], 1), 1, 1e-9);
    eq('turn folds angles', [g.turn(10, 350), g.turn(350, 10), g.turn(180, -180)], [20, -20, 0]);
    ev.length = 0;
    r.dragMode = 'orbit';
    r.down(1, 100, 100, 10); r.move(1, 110, 100, 20); r.move(1, 120, 104, 30); r.up(1, 120, 104, 40);
    eq('orbit mode: one finger orbits', ev, [['orbit', 10, 0], ['orbit', 10, 4]]);
    ev.length = 0;
    r.dragMode = 'pan';
    r.down(1, 100, 100, 10, {orbit: true}); r.move(1, 110, 100, 20); r.up(1, 110, 100, 30);
    eq('a right-button / shift drag orbits in pan mode', ev, [['orbit', 10, 0]]);
    eq('shift + arrows orbit, other keys as ever', ['ArrowRight', 'ArrowUp', '+'].map((k) => g.keyGesture(k, 10, true)),
      [{type: 'orbit', yaw: 5, pitch: 0}, {type: 'orbit', yaw: 0, pitch: -5}, {type: 'pinch', scale: 1.25}]);
  }

  // --- frames: orbits merge ---
  {
    const acc = f.emptyGesture();
    [{type: 'orbit', yaw: 200, pitch: 10}, {type: 'pan', dx: 1, dy: 0}, {type: 'orbit', yaw: 100, pitch: 250}]
      .forEach((x) => f.mergeGesture(acc, x));
    eq('merge: orbits add (yaw modulo a turn, pitch within ±180°)', f.gestureOps(acc),
       [{type: 'orbit', yaw: -60, pitch: 180}, {type: 'pan', dx: 1, dy: 0}]);
  }

  // --- camera.js: orbit keeps target and distance, never flips ---
  {
    const c0 = {position: [0, 0, 100], target: [0, 0, 0], up: [0, 1, 0], fov_y: 60};
    const c1 = cam.orbitCamera(c0, 90, 0);
    out['orbit: yaw 90° moves the camera to its right'] = near(c1.position[0], 100, 1e-9) && near(c1.position[2], 0, 1e-9);
    const c2 = cam.orbitCamera(c0, 0, 500);
    out['orbit: pitch clamped short of the pole'] = near(cam.polarAngle(c2), 180 - cam.MIN_POLAR_DEG, 1e-9) &&
      near(cam.targetDistance(c2), 100, 1e-9) && c2.target.every((x) => x === 0);
    out['applyGesture: orbit'] = near(cam.applyGesture(c0, {type: 'orbit', yaw: 90, pitch: 0}, {viewportHeight: 100}).position[0], 100, 1e-9);
  }

  // --- bands.js: bands near the budget; which frames a gesture cancels ---
  {
    const pl = new b.BandPlanner({budgetMs: 20, firstRows: 4});
    const first = pl.rows(100, 500);
    pl.record(first * 100, 8);                   // 4 rows × 100 px in 8 ms: 0.02 ms/px
    eq('bands: first band small, then sized to the budget', [first, pl.rows(100, 500), pl.rows(100, 3), pl.rows(100, 0)], [4, 10, 3, 0]);
    pl.record(1000, 100);                        // 10× slower now: the estimate follows (smoothed)
    out['bands: slower pixels, fewer rows'] = pl.rows(100, 500) < 10 && pl.rows(100, 500) >= 1;
    eq('gestures cancel full frames and previews short of half-way',
       [b.cancelsFrame({level: 'full', rowsDone: 90, rowsTotal: 100}), b.cancelsFrame({level: 'preview', rowsDone: 10, rowsTotal: 100}),
        b.cancelsFrame({level: 'preview', rowsDone: 60, rowsTotal: 100}), b.cancelsFrame(null)], [true, true, false, false]);
  }

  // --- limits.js: the form refuses what the service would, naming the range ---
  {
    const info = {limits: {max_image_side: 4096, max_spheres: 2097152, max_work: 1088 * 1088 * 8 * 4, max_bruteforce_work: 640 * 1088 * 512},
                  method_settings: {bih: {settings: ['max_prims', 'max_tree_depth'], modes: ['color', 'heat'], tests_every_sphere: false},
                                    kdtree: {settings: ['max_tree_depth'], modes: null, tests_every_sphere: false},
                                    bvh: {settings: ['max_prims', 'max_tree_depth', 'update'], modes: null, tests_every_sphere: false},
                                    hre: {settings: ['tile_size'], modes: null, tests_every_sphere: true},
                                    bruteforce: {settings: [], modes: null, tests_every_sphere: true}},
                  museum_room_spheres: 576};
    const ctx = (render = {}, scene = {}, extra = {}) => ({info, scene: {scenario: 1, n: 512, ...scene},
      render: {width: 503, height: 1088, samples_per_pixel: 4, max_recursion_depth: 8, method: 'bih', mode: 'color', ...render}, ...extra});
    eq('width at 4 spp: ≤ 4096 / 2', lim.range('width', ctx({height: 100})).max, 2048);
    out['width 4096 at 4 spp is refused, naming the range and the samples'] =
      /Width: a whole number 8 … 2,048 at 4 samples per pixel/.test(lim.check('width', 4096, ctx({width: 4096, height: 100})));
    out['depth 99 refused with its range'] = /Recursion depth: a whole number 1 … /.test(lim.check('max_recursion_depth', 99, ctx({max_recursion_depth: 99})));
    out['n = 0 refused'] = /Spheres \(n\): a whole number 1 … 2,097,152/.test(lim.check('n', 0, ctx({}, {n: 0})));
    out['museum n: the room counts'] = lim.range('n', ctx({}, {scenario: 'museum', n: 10})).max === 2097152 - 1024 && lim.range('n', ctx({}, {scenario: 'museum'})).min === 0;
    eq('samples allowed at 503 × 1088, depth 8', lim.samplesAllowed(ctx()), [1, 4]);
    out['brute force over its cap is refused at the method'] = /tests every sphere/.test(lim.check('method', 'bruteforce', ctx({method: 'bruteforce'})));
    eq('what applies', [
      lim.applies('update', ctx()), lim.applies('update', ctx({method: 'bvh'}, {}, {animated: true})),
      lim.applies('max_prims', ctx({method: 'kdtree'})), lim.applies('max_tree_depth', ctx({method: 'kdtree'})),
      lim.applies('tile_size', ctx()), lim.applies('tile_size', ctx({method: 'hre'})),
      lim.applies('radius', ctx({}, {scenario: 'museum'})), lim.applies('previewFormat', ctx({}, {}, {renderer: 'device'}))],
      [false, true, false, true, false, true, false, false]);
    eq('valid values pass', [lim.check('width', 320, ctx({width: 320})), lim.check('n', 64, ctx({}, {n: 64})),
      lim.check('samples_per_pixel', 4, ctx())], [null, null, null]);
  }

  // --- messages.js: the service's 422s in the panel's words ---
  {
    const e = {status: 422, detail: [{loc: ['body', 'width'], msg: 'width: width × height × max_recursion_depth × samples_per_pixel = 1 exceeds the limit 2 (POCKETRAY_MAX_WORK); lower width, height, max_recursion_depth or samples_per_pixel'}]};
    const x = msg.explain(e);
    out['422 → its field, in the panel\'s words'] = x.field === 'width' && x.text.startsWith('Width: width × height × recursion depth × samples per pixel')
      && !/samples_per_pixel|max_recursion_depth|POCKETRAY_/.test(x.text);
    eq('loc → field', [msg.fieldOf(['scene', 'n']), msg.fieldOf(['body', 'museum', 'n']), msg.fieldOf(['query', 'samples_per_pixel']), msg.fieldOf(['body'])],
       ['n', 'n', 'samples_per_pixel', null]);
  }
  return out;
}
"""


def test_pure_modules(open_client):
    c = open_client("mobile", query=None)
    c.page.goto(c.server.base + "/?n=8&width=64&height=64")   # a page on the origin to import from
    results = c.page.evaluate(UNIT_TESTS)
    failed = {k: v for k, v in results.items() if v is not True}
    assert failed == {}, failed
    assert len(results) >= 50
