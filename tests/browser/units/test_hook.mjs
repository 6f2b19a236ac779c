// hook.js: the test hook records each frame shown and keeps the last 100.

import { test } from 'node:test';
import { createHook, recordFrame } from '../../../client_web/js/hook.js';
import { same } from './same.mjs';

test('a frame shown: counted, described, logged; the log keeps the last 100', () => {
  const hook = createHook({});
  for (let v = 1; v <= 101; v++) {
    recordFrame(hook, { level: 'preview', width: 8, height: 8, version: v, contentType: 'image/jpeg', method: 'bih',
      renderer: 'server', camera: null, part: 'final', clientMs: 5 });
  }
  same([hook.frameCount, hook.lastFrameVersion, hook.lastFrame.method, hook.log.length, hook.log[0].version], [101, 101, 'bih', 100, 2]);
  same(hook.log[99], { level: 'preview', width: 8, height: 8, contentType: 'image/jpeg', version: 101, renderer: 'server',
    camera: null, part: 'final', clientMs: 5 });
  same(hook.status, 'starting');
});
