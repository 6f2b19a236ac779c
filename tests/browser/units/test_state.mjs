// state.js: the state the page starts with, from its URL and the stored client settings.

import { test } from 'node:test';
import { createState } from '../../../client_web/js/state.js';
import { DEFAULT_SCENE, FALLBACK_METHODS } from '../../../client_web/js/settings.js';
import { same } from './same.mjs';

test('the URL overrides the stored client settings; the scene starts as the default', () => {
  const { url, state } = createState('?preview_scale=0.25&n=64', { previewScale: 0.5, refineDelayMs: 300 });
  same(url.scene, { n: 64 });
  same(state.client, { dragMode: 'pan', previewScale: 0.25, refineDelayMs: 300, previewAuto: false });   // a fixed scale from the link
  same([state.scene, state.methods, state.sessionId, state.render], [DEFAULT_SCENE, FALLBACK_METHODS, null, null]);
  same(state.anim, { animated: false, playing: false, time: 0, time0: 0, clock0: 0 });
});
