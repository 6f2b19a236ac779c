// The refinement counter: while the camera rests and the service streams ever better frames
// (docs/API.md, "Refinement"), how many samples the image on screen holds of the target, as text
// ("64 / 256 samples") and a bar; it goes at the next gesture. Made here, inside the stage, so
// the page's markup needs nothing for it.

// The counter's words for a stream's progress {samples, target_samples, target_ms, elapsed_ms, done,
// reason, noise, target_noise}: the noise estimate is said when the stream has a noise target.
export function refineText(p) {
  if (!p) return '';
  const noise = p.target_noise > 0 && p.noise != null ? ` · noise ${(100 * p.noise).toFixed(1)} %` : '';
  const of = `${p.samples} / ${p.target_samples} samples${noise}`;
  if (!p.done) return of;
  if (p.reason === 'time') return `${p.samples} samples (${Math.round(p.target_ms / 1000)} s)`;
  if (p.reason === 'held') return `${p.samples} samples (memory full)`;
  if (p.reason === 'noise') return `${p.samples} samples (noise ${(100 * p.noise).toFixed(1)} %)`;
  return `${p.samples} samples`;
}

// The bar's fraction: samples of the target, or the time spent of the time allowed, the further one.
export function refineFraction(p) {
  if (!p) return 0;
  if (p.done) return 1;
  const bySamples = p.samples / Math.max(1, p.target_samples);
  const byTime = p.target_ms > 0 ? p.elapsed_ms / p.target_ms : 0;
  return Math.max(0, Math.min(1, Math.max(bySamples, byTime)));
}

export class RefineBadge {
  constructor(stage) {
    const root = document.createElement('div');
    root.id = 'refine';
    root.hidden = true;
    root.setAttribute('role', 'status');
    root.setAttribute('aria-live', 'polite');
    root.innerHTML = '<span data-field="samples"></span><progress max="1" value="0"></progress>';
    stage.appendChild(root);
    this.root = root;
    this.text = root.querySelector('[data-field="samples"]');
    this.bar = root.querySelector('progress');
  }

  // A part of the stream is on screen (p: its progress), or the stream is gone (null).
  show(p) {
    if (!p) {
      this.root.hidden = true;
      return;
    }
    this.root.hidden = false;
    this.root.classList.toggle('done', !!p.done);
    this.text.textContent = refineText(p);
    this.bar.value = refineFraction(p);
  }
}
