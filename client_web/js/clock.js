// The clock of an animated scene, kept in state.anim: frames are posed at `time` (seconds of
// scene time, ms resolution); while playing, time = time0 + wall-clock seconds since clock0.
// Pure: `now` is performance.now() in the page.

// The scene time of the next frame at `now` (ms), kept in anim.time.
export function sceneTime(anim, now) {
  if (anim.playing) anim.time = Math.round((anim.time0 + (now - anim.clock0) / 1000) * 1000) / 1000;
  return anim.time;
}

// Starts or stops the clock at `now`. → false (nothing changed) when there is nothing to play.
export function setClock(anim, playing, now) {
  if (playing && !anim.animated) return false;
  if (playing && !anim.playing) {
    anim.time0 = anim.time;
    anim.clock0 = now;
  } else if (!playing && anim.playing) {
    sceneTime(anim, now);
  }
  anim.playing = playing;
  return true;
}
