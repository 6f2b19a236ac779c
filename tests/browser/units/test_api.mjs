// api.js: Server-Timing, Retry-After, the back-off, the stored scene, retries through a fake fetch.

import { test } from 'node:test';
import * as a from '../../../client_web/js/api.js';
import { assert, same } from './same.mjs';

test('server timing', () => {
  same(a.parseServerTiming('build;dur=1.5, upload;dur=0.25, trace;desc="gpu";dur=7, total;dur=9'),
    { build: 1.5, upload: 0.25, trace: 7, total: 9 });
});

test('retry-after seconds', () => same(a.parseRetryAfter('2'), 2000));
test('retry-after date', () => same(a.parseRetryAfter(new Date(10000).toUTCString(), 7000), 3000));
test('retry-after capped', () => same(a.parseRetryAfter('3600'), a.RETRY_AFTER_MAX_MS));

test('back-off grows and is capped', () => {
  same([1, 2, 3, 10].map((n) => a.backoffDelay(n, () => 0.5)), [500, 1000, 2000, 10000]);
});

test('same scene', () => {
  assert.ok(a.sameScene({ n: 64 }, { scenario: 1, n: 64, seed: 1, radius: 1 }) && !a.sameScene({ n: 65 }, { n: 64 }));
});

test('same museum', () => {
  const museumInfo = { n_spheres: 832, museum: { n: 256, kind: 'rigid', seed: 0, absent: 0.2 }, animated: true };
  assert.ok(a.sameScene({ scenario: 'museum', n: 256, motion: 'rigid' }, museumInfo) &&
    !a.sameScene({ scenario: 'museum', n: 256, motion: 'deformable' }, museumInfo) &&
    !a.sameScene({ scenario: 1, n: 256 }, museumInfo) && !a.sameScene({ scenario: 'museum', n: 256 }, { scenario: 1, n: 256 }));
});

test('same mesh scene', () => {
  const teapot = { n_spheres: 2, mesh_scene: { kind: 'teapot' }, n_triangles: 6320 };
  assert.ok(a.sameScene({ scenario: 'mesh:teapot' }, teapot) && !a.sameScene({ scenario: 'mesh:room' }, teapot) &&
    !a.sameScene({ scenario: 1, n: 2 }, teapot) && !a.sameScene({ scenario: 'mesh:teapot' }, { scenario: 1, n: 2 }));
});

// A fetch that fails twice, then answers 503 with Retry-After 0, then 200.
test('retries until it gets through', async () => {
  const answers = ['fail', 'fail', 503, 200]; const statuses = [];
  const api = new a.Api({
    fetchImpl: async () => {
      const x = answers.shift();
      if (x === 'fail') throw new TypeError('net');
      return new Response('{"ok":1}', { status: x, headers: x === 503 ? { 'Retry-After': '0' } : {} });
    },
    onStatus: (st) => statuses.push(st.state),
  });
  api._sleep = async () => {};
  const j = await api.json('GET', '/x');
  same([j, statuses], [{ ok: 1 }, ['offline', 'offline', 'busy', 'online']]);
});

test('422 throws', async () => {
  const api2 = new a.Api({ fetchImpl: async () => new Response('{"detail":"bad n"}', { status: 422 }) });
  await assert.rejects(api2.json('GET', '/x'), (e) => {
    same([e.status, e.detail], [422, 'bad n']);
    return true;
  });
});
