// The toolbar's Play/Pause (an animated scene only) and the space key: they start and stop the
// scene clock (clock.js). onPlay(): the animation started (the app asks for the next frame).

import { setClock } from '../clock.js';

export class Player {
  // button: #play-button; animatedRows: the sheet's settings of animated scenes ([data-animated]).
  constructor({ button, animatedRows, state, onPlay }) {
    Object.assign(this, { button, animatedRows, state, onPlay });
    button.addEventListener('click', () => this.set(!state.anim.playing));
    window.addEventListener('keydown', (e) => {
      if (e.key !== ' ' || !state.anim.animated || e.target.closest?.('input, select, textarea, button, [data-no-gesture-keys]')) return;
      e.preventDefault();
      this.set(!state.anim.playing);
    });
  }

  set(playing) {
    if (!setClock(this.state.anim, playing, performance.now())) return;
    // The icon (style.css, by aria-pressed) and the label say what a press does next.
    const button = this.button;
    button.setAttribute('aria-pressed', String(playing));
    const label = playing ? 'Pause the animation' : 'Play the animation';
    button.setAttribute('aria-label', label);
    button.title = `${label} (space)`;
    button.querySelector('[data-label]').textContent = playing ? 'Pause' : 'Play';
    if (playing) this.onPlay();
  }

  // A session was adopted: whether its scene is animated, and the scene time it is at.
  adoptScene(animated, time) {
    const anim = this.state.anim;
    if (anim.animated !== animated || !animated) this.set(false);
    anim.animated = animated;
    anim.time = time;
    this.button.hidden = !animated;
    this.animatedRows.hidden = !animated;
  }
}
