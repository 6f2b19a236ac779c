// ui/messages.js: the service's 422s in the panel's words, at the field their loc names.

import './declared.mjs';
import { test } from 'node:test';
import * as msg from '../../../client_web/js/ui/messages.js';
import { assert, same } from './same.mjs';

test('422 → its field, in the panel\'s words', () => {
  const e = { status: 422, detail: [{ loc: ['body', 'width'], msg: 'width: width × height × max_recursion_depth × samples_per_pixel = 1 exceeds the limit 2 (POCKETRAY_MAX_WORK); lower width, height, max_recursion_depth or samples_per_pixel' }] };
  const x = msg.explain(e);
  assert.ok(x.field === 'width' && x.text.startsWith('Width: width × height × recursion depth × samples per pixel') &&
    !/samples_per_pixel|max_recursion_depth|POCKETRAY_/.test(x.text), JSON.stringify(x));
});

test('loc → field', () => {
  same([msg.fieldOf(['scene', 'n']), msg.fieldOf(['body', 'museum', 'n']), msg.fieldOf(['query', 'samples_per_pixel']), msg.fieldOf(['body'])],
    ['n', 'n', 'samples_per_pixel', null]);
});
