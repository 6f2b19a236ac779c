// The render service's HTTP API: fetch with retries, back-off, Retry-After, and
// the session kept in localStorage (a reload or a server restart resumes the scene).
//
// Failures are of two kinds:
//  - transient (network error, timeout, 502/503/504): retried without end, with
//    exponential back-off (503: wait what Retry-After says). onStatus reports
//    {state: 'offline' | 'busy', attempt, delayMs, message} before each wait and
//    {state: 'online'} once a request gets through again.
//  - final (4xx, other 5xx): an ApiError with the status and the server's detail.

import { meshKind } from './settings.js';

export class ApiError extends Error {
  constructor(status, detail, path) {
    super(`${status} ${typeof detail === 'string' ? detail : JSON.stringify(detail)}`);
    this.name = 'ApiError';
    this.status = status;
    this.detail = detail;
    this.path = path;
  }
}

export const BACKOFF = Object.freeze({ baseMs: 500, maxMs: 10000, factor: 2, jitter: 0.2 });
export const RETRY_AFTER_MAX_MS = 30000;
export const REQUEST_TIMEOUT_MS = 60000;

// Delay before retry number `attempt` (1-based).
export function backoffDelay(attempt, rand = Math.random, b = BACKOFF) {
  const d = Math.min(b.maxMs, b.baseMs * b.factor ** (attempt - 1));
  return Math.round(d * (1 - b.jitter + 2 * b.jitter * rand()));
}

// Retry-After: delta seconds or an HTTP date; null when absent or unreadable.
export function parseRetryAfter(value, now = Date.now()) {
  if (value == null || value === '') return null;
  const s = Number(value);
  let ms;
  if (Number.isFinite(s)) ms = s * 1000;
  else {
    const t = Date.parse(value);
    if (Number.isNaN(t)) return null;
    ms = t - now;
  }
  return Math.max(0, Math.min(RETRY_AFTER_MAX_MS, ms));
}

// Server-Timing: "build;dur=1.2, upload;dur=0.3, trace;desc=x;dur=4" → {build: 1.2, …}
export function parseServerTiming(header) {
  const out = {};
  if (!header) return out;
  for (const entry of header.split(',')) {
    const [name, ...params] = entry.trim().split(';');
    if (!name) continue;
    for (const p of params) {
      const [k, v] = p.trim().split('=');
      if (k === 'dur') out[name.trim()] = Number(v);
    }
  }
  return out;
}

function query(params) {
  const q = new URLSearchParams();
  for (const [k, v] of Object.entries(params || {})) if (v !== undefined && v !== null && v !== '') q.set(k, v);
  const s = q.toString();
  return s ? `?${s}` : '';
}

export class Api {
  constructor({ base = '', onStatus = () => {}, fetchImpl = null, timeoutMs = REQUEST_TIMEOUT_MS } = {}) {
    this.base = base;
    this.onStatus = onStatus;
    this.fetch = fetchImpl || ((...a) => window.fetch(...a));
    this.timeoutMs = timeoutMs;
    this.offline = false;
    this._wake = null;
  }

  // Cut the current back-off wait short ("Retry now").
  retryNow() {
    if (this._wake) this._wake();
  }

  _sleep(ms) {
    return new Promise((resolve) => {
      const t = setTimeout(done, ms);
      const self = this;
      function done() {
        clearTimeout(t);
        if (self._wake === done) self._wake = null;
        resolve();
      }
      this._wake = done;
    });
  }

  // One request, retried while the failure is transient. Returns the Response (ok).
  // `signal` (optional): the caller's abort, which ends the request (and the reading of its body) at
  // once and is not retried.
  async request(method, path, { body, raw, params, headers = {}, signal = null } = {}) {
    const url = this.base + path + query(params);
    const init = { method, headers: { ...headers }, cache: 'no-store' };
    // The balancer hashes on X-Session-Id (docs/DEPLOY.md): a session's requests reach the
    // process that holds its scene and refit trees.
    const sid = /^\/api\/sessions\/([^/?]+)/.exec(path);
    if (sid) init.headers['X-Session-Id'] = decodeURIComponent(sid[1]);
    if (body !== undefined) {
      init.body = JSON.stringify(body);
      init.headers['Content-Type'] = 'application/json';
    } else if (raw !== undefined) {   // a file's bytes as the body (a Blob can be sent again on a retry)
      init.body = raw;
      init.headers['Content-Type'] = 'application/octet-stream';
    }
    for (let attempt = 1; ; attempt++) {
      if (signal && signal.aborted) throw new DOMException('The request was stopped', 'AbortError');
      let res = null, failure = null;
      const ctl = new AbortController();
      const timer = setTimeout(() => ctl.abort(), this.timeoutMs);
      if (signal) signal.addEventListener('abort', () => ctl.abort(), { once: true });
      try {
        res = await this.fetch(url, { ...init, signal: ctl.signal });
      } catch (e) {
        if (signal && signal.aborted) throw e;
        failure = e.name === 'AbortError' ? 'The render service did not answer in time' : 'Cannot reach the render service';
      } finally {
        clearTimeout(timer);
      }
      if (res && res.status === 503) {
        const wait = parseRetryAfter(res.headers.get('Retry-After')) ?? backoffDelay(attempt);
        this.onStatus({ state: 'busy', attempt, delayMs: wait, message: 'The render service is busy' });
        await this._sleep(wait);
        continue;
      }
      if (res && (res.status === 502 || res.status === 504)) failure = `The render service is unavailable (${res.status})`;
      if (failure) {
        this.offline = true;
        const wait = backoffDelay(attempt);
        this.onStatus({ state: 'offline', attempt, delayMs: wait, message: failure });
        await this._sleep(wait);
        continue;
      }
      if (this.offline || attempt > 1) {
        this.offline = false;
        this.onStatus({ state: 'online' });
      }
      if (!res.ok) {
        let detail = res.statusText;
        try {
          const j = await res.json();
          detail = j.detail ?? j;
        } catch { /* not JSON */ }
        throw new ApiError(res.status, detail, path);
      }
      return res;
    }
  }

  async json(method, path, opts) {
    const res = await this.request(method, path, opts);
    return res.status === 204 ? null : res.json();
  }

  // ---- endpoints -------------------------------------------------------------
  createSession(scene, settings) {
    const body = { ...scene };
    if (settings && Object.keys(settings).length) body.settings = settings;
    return this.json('POST', '/api/sessions', { body });
  }

  getSession(id) {
    return this.json('GET', `/api/sessions/${encodeURIComponent(id)}`);
  }

  patchSettings(id, partial) {
    return this.json('PATCH', `/api/sessions/${encodeURIComponent(id)}/settings`, { body: partial });
  }

  // A model file (a Blob/File) added to the session's scene: the raw body, no multipart
  // (docs/API.md, "Triangle meshes"). → {version, scene_info, mesh, first_id}.
  addMesh(id, file, params) {
    return this.json('POST', `/api/sessions/${encodeURIComponent(id)}/meshes`, { raw: file, params });
  }

  // A gesture; with frameParams the answer is the new frame (one round trip).
  async gesture(id, gesture, frameParams = null) {
    const path = `/api/sessions/${encodeURIComponent(id)}/gesture`;
    if (!frameParams) return this.json('POST', path, { body: gesture });
    const res = await this.request('POST', path, { body: gesture, params: { frame: 1, ...frameParams } });
    return readFrame(res);
  }

  // The session's frame. With `onPreview`, asked for progressively (docs/API.md, "Progressive
  // frames"): a supersampled frame's pixel-centre image is handed to onPreview(frame) as soon
  // as it arrives, and the final image is returned. `signal` abandons it (a gesture came).
  async frame(id, params, onPreview = null, signal = null) {
    const path = `/api/sessions/${encodeURIComponent(id)}/frame`;
    if (!onPreview) return readFrame(await this.request('GET', path, { params, signal }));
    const res = await this.request('GET', path, { params: { ...params, progressive: 1 }, signal });
    return readParts(res, onPreview);
  }

  // The session's refinement stream (docs/API.md, "Refinement"): each frame, with `refine` (the
  // stream's progress: samples, target_samples, target_ms, elapsed_ms, done, reason), handed to
  // onPart(frame) as it arrives; resolves when the stream ends; `signal` stops it.
  async refine(id, params, onPart, signal) {
    const path = `/api/sessions/${encodeURIComponent(id)}/frame`;
    const res = await this.request('GET', path, { params: { ...params, refine: 1 }, signal });
    const type = res.headers.get('Content-Type') || '';
    const m = /boundary=([^;]+)/.exec(type);
    if (!type.startsWith('multipart/') || !m) return;   // 204: the session changed before a first frame
    for await (const part of multipartParts(res.body, m[1])) {
      const headers = part.headers;
      const frame = frameOf(new Blob([part.body], { type: headers['content-type'] }), (n) => headers[n.toLowerCase()]);
      try {
        frame.refine = JSON.parse(headers['x-refine'] || 'null');
      } catch {
        frame.refine = null;
      }
      if (signal && signal.aborted) return;
      await onPart(frame);
    }
  }

  // What the server offers (GET /api/info: methods, modes, formats, limits), or null.
  async info() {
    try {
      const res = await this.fetch(this.base + '/api/info', { cache: 'no-store' });
      return res.ok ? await res.json() : null;
    } catch {
      return null;
    }
  }
}

async function readFrame(res) {
  return frameOf(await res.blob(), (name) => res.headers.get(name));
}

// A frame from its bytes and a header lookup (a response's, or a multipart part's).
function frameOf(blob, header) {
  let stats = null;
  try {
    stats = JSON.parse(header('X-Stats') || 'null');
  } catch { /* ignore */ }
  const v = header('X-Session-Version');
  return {
    blob,
    version: v === null || v === undefined ? null : Number(v),
    method: header('X-Method'),
    timing: parseServerTiming(header('Server-Timing')),
    stats,
    contentType: header('Content-Type'),
    part: header('X-Frame-Part') || 'final',
  };
}

// A multipart/mixed answer (progressive=1): every part before the last goes to onPreview as it
// arrives; the last (X-Frame-Part: final) is returned. A plain image answer is the final one.
async function readParts(res, onPreview) {
  const type = res.headers.get('Content-Type') || '';
  const m = /boundary=([^;]+)/.exec(type);
  if (!type.startsWith('multipart/') || !m) return readFrame(res);
  let last = null;
  for await (const part of multipartParts(res.body, m[1])) {
    const headers = part.headers;
    const frame = frameOf(new Blob([part.body], { type: headers['content-type'] }), (n) => headers[n.toLowerCase()]);
    if (frame.part === 'preview') await onPreview(frame);
    else last = frame;
  }
  if (!last) throw new ApiError(502, 'the progressive frame ended without its final part', '');
  return last;
}

// The parts of a multipart/mixed stream whose parts carry Content-Length: {headers, body}.
export async function* multipartParts(stream, boundary) {
  const reader = stream.getReader();
  const enc = new TextEncoder(), dec = new TextDecoder();
  const open = enc.encode(`--${boundary}`);
  let buf = new Uint8Array(0), done = false;
  const find = (needle, from = 0) => {
    outer: for (let i = from; i <= buf.length - needle.length; i++) {
      for (let j = 0; j < needle.length; j++) if (buf[i + j] !== needle[j]) continue outer;
      return i;
    }
    return -1;
  };
  const more = async () => {
    const { value, done: end } = await reader.read();
    if (end) { done = true; return; }
    const next = new Uint8Array(buf.length + value.length);
    next.set(buf);
    next.set(value, buf.length);
    buf = next;
  };
  for (;;) {
    let at = find(open);
    while (at < 0 || buf.length < at + open.length + 2) {
      if (done) return;
      await more();
      at = find(open);
    }
    if (buf[at + open.length] === 45 && buf[at + open.length + 1] === 45) return;   // "--": the end
    let head = find(enc.encode('\r\n\r\n'), at);
    while (head < 0) {
      if (done) return;
      await more();
      head = find(enc.encode('\r\n\r\n'), at);
    }
    const headers = {};
    for (const line of dec.decode(buf.subarray(at + open.length + 2, head)).split('\r\n')) {
      const i = line.indexOf(':');
      if (i > 0) headers[line.slice(0, i).trim().toLowerCase()] = line.slice(i + 1).trim();
    }
    const length = Number(headers['content-length']);
    const start = head + 4;
    while (buf.length < start + length) {
      if (done) return;
      await more();
    }
    yield { headers, body: buf.slice(start, start + length) };
    buf = buf.slice(start + length);
  }
}

// ---- the session, kept across reloads and server restarts ---------------------
const STORE_KEY = 'pocketray.session';

export function loadStoredSession(storage = window.localStorage) {
  try {
    return JSON.parse(storage.getItem(STORE_KEY) || 'null');
  } catch {
    return null;
  }
}

export function storeSession(session, storage = window.localStorage) {
  try {
    storage.setItem(STORE_KEY, JSON.stringify(session));
  } catch { /* private mode: the session lasts as long as the page */ }
}

// Same scene? (the scene parameters that were asked for, against the session's scene_info)
export function sameScene(wanted, info) {
  if (!info) return false;
  const kind = meshKind(wanted.scenario);
  if (kind || info.mesh_scene) return !!kind && !!info.mesh_scene && info.mesh_scene.kind === kind;
  if (wanted.scenario === 'museum' || info.museum) {
    const m = info.museum;
    return !!m && wanted.scenario === 'museum' && (wanted.n === undefined || Number(wanted.n) === m.n) &&
      (wanted.seed === undefined || Number(wanted.seed) === m.seed) && (wanted.motion === undefined || wanted.motion === m.kind);
  }
  return ['scenario', 'n', 'seed', 'radius'].every((k) => wanted[k] === undefined || Number(wanted[k]) === Number(info[k]));
}
