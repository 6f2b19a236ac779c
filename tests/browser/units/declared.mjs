// The render settings the service declares (GET /api/info's `settings`, from renderer/config/settings.py),
// taken by settings.js as the page takes them once /api/info has answered. test_units.py writes them
// to the file POCKETRAY_SETTINGS_JSON names; run by hand, they are asked of the checkout's Python.

import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { learnSettings } from '../../../client_web/js/settings.js';

function declared() {
  const file = process.env.POCKETRAY_SETTINGS_JSON;
  if (file) return JSON.parse(readFileSync(file, 'utf8'));
  const code = 'import json; from renderer.config.settings import SETTINGS; print(json.dumps([s.metadata() for s in SETTINGS]))';
  return JSON.parse(execFileSync('.venv/bin/python', ['-c', code], { encoding: 'utf8' }));
}

export const SETTINGS = declared();
learnSettings(SETTINGS);
