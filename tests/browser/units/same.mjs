// The assertion the client's unit tests share: equal as JSON (key order included, as the
// browser's JSON.stringify writes them), failing with both values written out.

import assert from 'node:assert/strict';

export function same(got, want, message = 'not the same') {
  const g = JSON.stringify(got), w = JSON.stringify(want);
  if (g !== w) assert.fail(`${message}\n  got:  ${g}\n  want: ${w}`);
}

export const near = (x, y, e = 1e-9) => Math.abs(x - y) <= e;

export { assert };
