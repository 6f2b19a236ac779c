// The test hook, window.pocketray: what the browser tests observe — the frames shown, the
// requests, the errors and notices, the session, the status — and device mode's entry points
// (renderOnce, bench, probe). The client writes it; nothing in the client reads it back but
// `status` and `serverRenderer`.

const LOG_LENGTH = 100;          // frames kept in `log`

export function createHook(state) {
  return {
    frameCount: 0,
    lastFrameVersion: null,
    lastFrame: null,
    sessionId: null,
    errors: [],
    notices: [],
    log: [],                      // the last frames shown: level, size, content type, version
    status: 'starting',           // starting | ready | offline | busy | failed
    state,
  };
}

// The parts the hook reports on: the frame scheduler (frames.js) and device mode (device/device.js).
export function observe(hook, { scheduler, device }) {
  Object.defineProperties(hook, {
    idle: { get: () => scheduler.idle && device.idle && hook.status === 'ready', enumerable: true },
    requests: { get: () => scheduler.requests, enumerable: true },
    dropped: { get: () => scheduler.dropped, enumerable: true },
    refining: { get: () => !!scheduler.refining, enumerable: true },   // a refinement stream is on its way
  });
  hook.device = {
    renderOnce: (params) => device.renderOnce(params),
    bench: (params) => device.bench(params),
    probe: () => device.probe(),
    get camera() { return device.camera; },
    get path() { return device.path ?? null; },   // the loaded data's path integrator ({samples_per_pass, guides}) or null
    get accumulation() { return device.accumulation; },   // the resting view's sum: {samples, target, shown} or null
    readback: () => device.readback(),   // the last device frame's arrays (base64)
    get fallback() { return hook.deviceFallback ?? null; },
    get counts() { return { ...device.counts }; },
    get job() { return device.job && { level: device.job.level, rowsDone: device.job.rowsDone, rowsTotal: device.job.rowsTotal }; },
  };
}

// A frame is on screen: `lastFrame` describes it (display.js's describeFrame), the log keeps it.
export function recordFrame(hook, lastFrame) {
  const { level, width, height, contentType, version, renderer, camera, part, clientMs } = lastFrame;
  hook.frameCount++;
  hook.lastFrameVersion = version;
  hook.lastFrame = lastFrame;
  hook.log.push({ level, width, height, contentType, version, renderer, camera, part, clientMs });
  if (hook.log.length > LOG_LENGTH) hook.log.shift();
}
