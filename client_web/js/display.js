// Shows a frame: draws it on the canvas, tells the test hook, labels the canvas for screen
// readers, and feeds the legend and the overlay. A frame describes itself (version, timing,
// stats, renderer) and carries `t0` and `meta`, when and with what it was asked for
// (transport.js): the overlay and the legend describe the frame on screen, never the
// settings of a request still on its way.

import { recordFrame } from './hook.js';
import { meshKind, skyScenario } from './settings.js';

// Where a frame of aspect `aspect` (width / height) is drawn inside a box of width × height
// (object-fit: contain), CSS pixels.
export function containedSize(width, height, aspect = width / height) {
  return width / height > aspect ? { width: height * aspect, height } : { width, height: width / aspect };
}

// Where the frame is drawn inside the stage, CSS pixels (the session's aspect; the stage's before there is one).
export function displayedSize(stage, render) {
  const cw = stage.clientWidth || window.innerWidth, ch = stage.clientHeight || window.innerHeight;
  return containedSize(cw, ch, render ? render.width / render.height : cw / ch);
}

// The canvas's aria-label: the scene and mode of the frame on screen.
export function sceneLabel(meta, { n, triangles, mode, scenario }) {
  const withTriangles = (triangles ? `, ${triangles} triangles in ${meta.meshes || 1} mesh${meta.meshes > 1 ? 'es' : ''}` : '')
    + (meta.shapes ? `, ${meta.shapes} analytic shape${meta.shapes > 1 ? 's' : ''}` : '');
  const kind = meshKind(meta.scenario);
  return meta.scenario === 'museum'
    ? `Ray-traced animated museum: ${n} spheres (${meta.motion}), ${mode} mode`
    : kind ? `Ray-traced mesh scene: ${kind}, ${n} spheres${withTriangles}, ${mode} mode`
      : skyScenario(meta.scenario ?? scenario)
        ? `Ray-traced scene: scenario ${skyScenario(meta.scenario ?? scenario)} under the sky, ${n} spheres${withTriangles}, ${mode} mode`
        : `Ray-traced scene: scenario ${meta.scenario ?? scenario}, ${n} spheres${withTriangles}, ${mode} mode`;
}

// A frame shown at `level` on a canvas of `size`, `now` (ms, the clock of frame.t0):
// → {lastFrame (the test hook's), overlay (Overlay.frame's argument), label, legend (a mode or null)}.
export function describeFrame(frame, level, { width, height }, state, serverRenderer, now) {
  const meta = frame.meta || {};
  const clientMs = now - frame.t0;
  const renderer = frame.renderer || 'server';
  const renderedBy = renderer === 'device' ? `device (${frame.rendererInfo})` : `server (${serverRenderer || 'OpenGL'})`;
  // one short line for the overlay (the GL renderer's name without its version): the title has all
  const renderedShort = `${renderer} (${String(renderer === 'device' ? frame.rendererInfo : serverRenderer || 'OpenGL')
    .replace(/\s*\(.*$/, '').slice(0, 24)})`;
  const n = frame.stats?.n_spheres ?? meta.n;
  const method = frame.method || meta.method;
  const time = frame.stats && Number.isFinite(frame.stats.time) ? frame.stats.time : null;
  const mode = meta.mode || state.render.mode;
  // (the device's frames are of the data it fetched for the scene as it is now)
  const triangles = frame.stats?.n_triangles ?? meta.triangles ?? (renderer === 'device' ? state.scene.n_triangles : 0) ?? 0;
  const lastFrame = {
    level, width, height, version: frame.version,
    contentType: frame.contentType, method, timing: frame.timing, stats: frame.stats, clientMs,
    renderer, renderedBy, n, mode: meta.mode, samples: meta.samples, camera: frame.camera ?? null,
    part: frame.part || 'final', time, triangles,
  };
  const overlay = {
    level, width, height, clientMs, timing: frame.timing, stats: frame.stats,
    method, n, triangles, shapes: frame.stats?.n_shapes ?? meta.shapes ?? (renderer === 'device' ? state.scene.n_shapes : 0) ?? 0, version: frame.version, renderedBy, renderer,
    samples: meta.samples, minWeight: meta.minWeight,
    // a refinement stream's frame: its samples and the time the stream has refined for (its
    // clientMs is the stream's age, not a time to image)
    refine: frame.refine ? { samples: frame.refine.samples, ms: frame.refine.elapsed_ms ?? clientMs } : null,
    time: state.anim.animated ? time : null, playing: state.anim.playing, renderedShort,
  };
  return {
    lastFrame, overlay,
    label: sceneLabel(meta, { n, triangles, mode, scenario: state.scene.scenario }),
    legend: mode === 'recursion' || mode === 'heat' ? mode : null,
  };
}

// onShown(meta, level): after each frame (the session learns its new scene is on screen; an animation asks for the next).
export class Display {
  constructor({ canvas, state, hook, legend, overlay, onShown = () => {} }) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    Object.assign(this, { state, hook, legend, overlay, onShown });
  }

  // frame.image: the device's canvas; else frame.blob, the service's encoded image.
  async show(frame, level) {
    const canvas = this.canvas;
    const bitmap = frame.image || await createImageBitmap(frame.blob);
    if (canvas.width !== bitmap.width || canvas.height !== bitmap.height) {
      canvas.width = bitmap.width;
      canvas.height = bitmap.height;
    }
    this.ctx.drawImage(bitmap, 0, 0);
    if (!frame.image) bitmap.close?.();
    const d = describeFrame(frame, level, canvas, this.state, this.hook.serverRenderer, performance.now());
    recordFrame(this.hook, d.lastFrame);
    canvas.setAttribute('aria-label', d.label);
    this.legend.show(d.legend);
    this.overlay.frame(d.overlay);
    this.onShown(frame.meta || {}, level);
  }
}
