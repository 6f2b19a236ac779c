// What the hands do: gestures and keys on the frame (gestures.js), the toolbar's Orbit and
// Reset. In device mode the local camera moves at once (display rate); the server's Model
// always follows (through the scheduler).

import { attach } from '../gestures.js';
import { saveClientSettings } from '../settings.js';

// A one-finger orbit drag turns the camera this many degrees per height of the frame on screen.
export const ORBIT_DEGREES_PER_VIEW = 180;

// A drag in orbit mode by (dx, dy) CSS px on a frame `height` px high: "grab the scene" —
// dragging right turns the scene right (the camera left about its target), dragging down
// turns it down (the camera up).
export function orbitDrag(dx, dy, height) {
  const k = ORBIT_DEGREES_PER_VIEW / height;
  return { type: 'orbit', yaw: -dx * k, pitch: -dy * k };
}

// canvas; orbitButton, resetButton (the toolbar's); hint (ui/hint.js); device (DeviceView);
// scheduler (frames.js); viewportHeight(): the frame's displayed height.
export function attachControls({ canvas, orbitButton, resetButton, state, hint, device, scheduler, viewportHeight }) {
  function userGesture(g) {
    hint.dismiss();   // they found out
    if (!state.render) return;
    if (state.client.renderer === 'device') device.gesture(g);
    scheduler.gesture(g);
  }
  const gestures = attach(canvas, {
    onStart: () => hint.dismiss(),
    onPan: (dx, dy) => userGesture({ type: 'pan', dx, dy }),
    onOrbitDrag: (dx, dy) => userGesture(orbitDrag(dx, dy, viewportHeight())),
    // Two fingers turning clockwise turn the scene as if the near floor followed the lower finger.
    onTwist: (deg) => userGesture({ type: 'orbit', yaw: deg, pitch: 0 }),
    onPinch: (scale) => userGesture({ type: 'pinch', scale }),
    onReset: () => userGesture({ type: 'reset' }),
    onWheel: (scale) => userGesture({ type: 'pinch', scale }),
    onKey: (g) => userGesture(g),
  });
  resetButton.addEventListener('click', () => userGesture({ type: 'reset' }));

  function setDragMode(mode) {
    state.client = { ...state.client, dragMode: mode };
    gestures.recognizer.dragMode = mode;
    orbitButton.setAttribute('aria-pressed', String(mode === 'orbit'));
    document.body.classList.toggle('orbit-mode', mode === 'orbit');
  }
  orbitButton.addEventListener('click', () => {
    setDragMode(state.client.dragMode === 'orbit' ? 'pan' : 'orbit');
    saveClientSettings(state.client);
  });
  setDragMode(state.client.dragMode === 'orbit' ? 'orbit' : 'pan');
}
