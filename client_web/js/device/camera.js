// The Controller's camera math (server/sessions/controller.py), ported for device mode: the local
// camera moves at display rate and must end where the server's Model does. Float64 and
// the same order of operations as the Python, so both agree to rounding
// (tests/browser/test_device_mode.py compares them).

export const MIN_TARGET_DISTANCE = 1e-3;   // POCKETRAY_MIN_TARGET_DISTANCE's default
export const MAX_COORDINATE = 1e7;         // renderer.geometry.scene.MAX_COORDINATE
export const MIN_POLAR_DEG = 1.0;          // controller.MIN_POLAR_DEG

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.sqrt(dot(a, a));
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const radians = (deg) => deg * (Math.PI / 180);   // as CPython's math.radians
const degrees = (rad) => rad * (180 / Math.PI);   // as math.degrees

// Camera.basis(): (right, true_up, forward), orthonormal.
export function cameraBasis(cam) {
  const d = sub(cam.target, cam.position);
  const n = norm(d);
  const forward = d.map((x) => x / n);
  const r = cross(forward, cam.up);
  const rn = norm(r);
  const right = r.map((x) => x / rn);
  return { right, up: cross(right, forward), forward };
}

export function targetDistance(cam) {
  return norm(sub(cam.target, cam.position));
}

function inRange(cam) {
  return [...cam.position, ...cam.target].every((x) => Number.isFinite(x) && Math.abs(x) <= MAX_COORDINATE);
}

// controller.pan: camera and target move by (−dx·right + dy·up)·world_per_pixel.
export function panCamera(cam, dx, dy, viewportHeight) {
  const { right, up } = cameraBasis(cam);
  const k = 2.0 * targetDistance(cam) * Math.tan(radians(cam.fov_y) / 2.0) / viewportHeight;
  const delta = [0, 1, 2].map((i) => (-dx * right[i] + dy * up[i]) * k);
  return {
    ...cam, position: cam.position.map((x, i) => x + delta[i]), target: cam.target.map((x, i) => x + delta[i]),
  };
}

// controller.pinch: along the view axis to distance d / scale (never closer than minDistance).
export function pinchCamera(cam, scale, minDistance = MIN_TARGET_DISTANCE) {
  const offset = sub(cam.position, cam.target);
  const distance = norm(offset);
  let nd = distance / scale;
  if (scale > 1) nd = Math.max(nd, Math.min(distance, minDistance));
  return { ...cam, position: cam.target.map((t, i) => t + offset[i] * (nd / distance)) };
}

// controller._rotate: v about the unit axis by `deg` degrees (right-handed, Rodrigues).
function rotate(v, axis, deg) {
  const a = radians(deg);
  const c = Math.cos(a), s = Math.sin(a);
  const axv = cross(axis, v), k = dot(axis, v);
  return v.map((x, i) => x * c + axv[i] * s + axis[i] * k * (1.0 - c));
}

// controller.polar_angle: degrees between up and the target→camera offset.
export function polarAngle(cam) {
  const offset = sub(cam.position, cam.target);
  const cos = dot(offset, cam.up) / (norm(offset) * norm(cam.up));
  return degrees(Math.acos(Math.max(-1.0, Math.min(1.0, cos))));
}

// controller.clamp_pitch: the part of `pitch` that keeps the view short of the poles.
export function clampPitch(cam, pitch) {
  const theta = polarAngle(cam);
  const lo = Math.min(theta, MIN_POLAR_DEG), hi = Math.max(theta, 180.0 - MIN_POLAR_DEG);
  return Math.max(lo, Math.min(hi, theta + pitch)) - theta;
}

// controller.orbit: yaw degrees about up, pitch (clamped) about right; target and distance stay.
export function orbitCamera(cam, yaw, pitch) {
  let offset = sub(cam.position, cam.target);
  const un = norm(cam.up);
  const up = cam.up.map((x) => x / un);
  const p = clampPitch(cam, pitch);
  offset = rotate(offset, cameraBasis(cam).right, p);
  offset = rotate(offset, up, yaw);
  return { ...cam, position: cam.target.map((t, i) => t + offset[i]) };
}

// A gesture ({type: pan|pinch|orbit|reset}) applied to `cam`; out-of-range results leave it as it
// was (the server answers those with 422 and changes nothing).
export function applyGesture(cam, g, { viewportHeight, home }) {
  let out = cam;
  if (g.type === 'pan') out = panCamera(cam, g.dx || 0, g.dy || 0, viewportHeight);
  else if (g.type === 'pinch' && g.scale > 0 && Number.isFinite(g.scale)) out = pinchCamera(cam, g.scale);
  else if (g.type === 'orbit' && Number.isFinite(g.yaw ?? 0) && Number.isFinite(g.pitch ?? 0)) {
    out = orbitCamera(cam, g.yaw || 0, g.pitch || 0);
  } else if (g.type === 'reset' && home) out = structuredClone(home);
  return inRange(out) ? out : cam;
}
