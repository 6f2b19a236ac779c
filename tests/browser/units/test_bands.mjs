// device/bands.js: bands near the time budget; which frames a gesture cancels.

import { test } from 'node:test';
import * as b from '../../../client_web/js/device/bands.js';
import { assert, same } from './same.mjs';

test('bands: first band small, then sized to the budget', () => {
  const pl = new b.BandPlanner({ budgetMs: 20, firstRows: 4 });
  const first = pl.rows(100, 500);
  pl.record(first * 100, 8);                   // 4 rows × 100 px in 8 ms: 0.02 ms/px
  same([first, pl.rows(100, 500), pl.rows(100, 3), pl.rows(100, 0)], [4, 10, 3, 0]);
});

test('bands: slower pixels, fewer rows', () => {
  const pl = new b.BandPlanner({ budgetMs: 20, firstRows: 4 });
  pl.record(pl.rows(100, 500) * 100, 8);
  pl.record(1000, 100);                        // 10× slower now: the estimate follows (smoothed)
  assert.ok(pl.rows(100, 500) < 10 && pl.rows(100, 500) >= 1, String(pl.rows(100, 500)));
});

test('gestures cancel full frames and previews short of half-way', () => {
  same([b.cancelsFrame({ level: 'full', rowsDone: 90, rowsTotal: 100 }), b.cancelsFrame({ level: 'preview', rowsDone: 10, rowsTotal: 100 }),
    b.cancelsFrame({ level: 'preview', rowsDone: 60, rowsTotal: 100 }), b.cancelsFrame(null)], [true, true, false, false]);
});
