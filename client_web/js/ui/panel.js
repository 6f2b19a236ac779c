// The settings sheet: shows the session's settings, hides the ones that do not apply,
// refuses (and marks, next to the field) values the service would refuse, and puts
// marked fields back to the session's values when it closes without them applied.
//
// callbacks: onScene(scene) (a new session), onRender(partial) (PATCH), onClient(partial)
// (this browser's levels), onModel(file, format) (a model file to add to the session's scene;
// the app marks a refusal next to the picker with mark('model', text)). The app calls show(state) with {scene, render, client, anim}
// whenever they change, setInfo(info) once GET /api/info answered, and refused(explained)
// with a 422 in the panel's words (messages.js).
//
// The render settings it shows are those GET /api/info declares for the sheet (renderer/config/settings.py):
// their names, types and labels come from there; a declared setting the page has no field for gets
// one, made from its declaration (a number input within its bounds, or a select of its choices).

import { applies, check, integratorValues, modesOf, range, sampleChoices, samplesAllowed, subpixels } from './limits.js';
import {
  DEFAULT_MUSEUM_N, DEFAULT_SCENE, FALLBACK_METHODS, FIELD_LABELS, FALLBACK_MODES, MODEL_FORMATS,
  MUSEUM_KINDS, PREVIEW_SCALES, RESOLUTIONS, UPDATE_SCHEMES, learnScenes, learnSettings, meshKind, methodLabel, modeLabel, pickerScenes,
  sceneValue, withRestDenoiser,
  parseResolution, renderSettings, settingValue,
} from '../settings.js';
import { modelFileProblem } from './messages.js';
import { planUpload, uploadBody } from '../model_upload.js';

const SCENE_KEYS = ['scenario', 'n', 'seed', 'radius', 'motion'];
const CLIENT_KEYS = ['previewScale', 'previewFormat', 'previewQuality', 'refineDelayMs', 'renderer'];
// The sheet's size fields: set through the resolution (its 'custom' choice shows them).
const SIZE_KEYS = ['width', 'height'];

function fillSelect(select, items, labelOf = (v) => v) {
  const cur = select.value;
  select.replaceChildren(...items.map((it) => {
    const o = document.createElement('option');
    const value = typeof it === 'object' ? it.value : it;
    o.value = String(value);
    o.textContent = typeof it === 'object' ? it.label : labelOf(it);
    return o;
  }));
  if (cur) select.value = cur;
}

const isMuseum = (scenario) => String(scenario) === 'museum';

export class SettingsPanel {
  constructor(root, openButton, callbacks) {
    this.root = root;
    this.openButton = openButton;
    this.cb = callbacks;
    this.form = root.querySelector('form');
    this.el = (name) => this.form.elements.namedItem(name);
    this.info = null;
    this.state = null;
    this.invalid = new Map();      // field → message shown next to it
    this.nByKind = { thesis: null, museum: null };   // each kind of scene keeps its own n
    fillSelect(this.el('scenario'), pickerScenes);
    fillSelect(this.el('motion'), MUSEUM_KINDS);
    fillSelect(this.el('update'), UPDATE_SCHEMES);
    fillSelect(this.el('method'), FALLBACK_METHODS, (m) => methodLabel(null, m));
    fillSelect(this.el('mode'), FALLBACK_MODES, (m) => modeLabel(null, m));
    fillSelect(this.el('resolution'), RESOLUTIONS);
    fillSelect(this.el('previewScale'), PREVIEW_SCALES);
    this._fillSamples({});

    openButton.addEventListener('click', () => this.setOpen(!this.open));
    root.querySelector('[data-close]').addEventListener('click', () => this.setOpen(false));
    // Escape closes the sheet wherever the focus is (a marked field does not take it).
    document.addEventListener('keydown', (e) => {
      if (e.key === 'Escape' && this.open) this.setOpen(false);
    });
    this.form.addEventListener('submit', (e) => e.preventDefault());
    this.form.addEventListener('change', (e) => this._changed(e.target));
    this.setOpen(false);
  }

  setOpen(open) {
    this.open = open;
    this.root.hidden = !open;
    this.openButton.setAttribute('aria-expanded', String(open));
    document.body.classList.toggle('sheet-open', open);
    if (open) {
      this.el('scenario').focus({ preventScroll: true });
    } else if (this.invalid.size) {
      // Closed without the marked values applied: the form shows the session again.
      for (const name of [...this.invalid.keys()]) this.clear(name);
      if (this.state) this.show(this.state, { force: true });
    }
  }

  // GET /api/info: the method, mode and samples lists, the limits, what applies to which method.
  setInfo(info) {
    this.info = info;
    learnSettings(info.settings);
    // The picker is the service's list of demo scenes, when it gives one.
    if (learnScenes(info.scenes)) fillSelect(this.el('scenario'), pickerScenes);
    for (const spec of this._specs()) if (!this.el(spec.name)) this._addField(spec);
    if (Array.isArray(info.methods) && info.methods.length) fillSelect(this.el('method'), info.methods, (m) => methodLabel(info, m));
    if (Array.isArray(info.modes) && info.modes.length) fillSelect(this.el('mode'), info.modes, (m) => modeLabel(info, m));
    if (this.state) this.show(this.state);
  }

  // The render settings the sheet offers (GET /api/info's declarations), the size fields aside.
  _specs() {
    return renderSettings.filter((x) => x.sheet && !SIZE_KEYS.includes(x.name));
  }

  _spec(name) {
    return this._specs().find((x) => x.name === name) || null;
  }

  // A field for a declared setting the page has none for, in the rendering part of the sheet.
  _addField(spec) {
    const id = `f-${spec.name}`;
    const wrap = document.createElement('div');
    wrap.className = 'field';
    wrap.dataset.setting = spec.name;
    wrap.dataset.declared = '';
    const label = document.createElement('label');
    label.htmlFor = id;
    // the unit once: a label may say it already ("Refine to (samples)")
    label.textContent = spec.unit && !spec.label.includes(`(${spec.unit})`) ? `${spec.label} (${spec.unit})` : spec.label;
    if (spec.doc) label.title = spec.doc;
    let input;
    if (spec.choices || spec.type === 'boolean') {
      input = document.createElement('select');
      fillSelect(input, spec.choices || [true, false], String);
    } else {
      input = document.createElement('input');
      input.type = 'number';
      input.inputMode = spec.type === 'integer' ? 'numeric' : 'decimal';
      input.step = spec.type === 'integer' ? '1' : 'any';
      input.required = true;
      if (spec.minimum !== null && spec.minimum !== undefined) input.min = String(spec.minimum);
      if (spec.maximum !== null && spec.maximum !== undefined) input.max = String(spec.maximum);
    }
    input.id = id;
    input.name = spec.name;
    if (spec.default !== null && spec.default !== undefined) input.value = String(spec.default);
    wrap.append(label, input);
    const last = [...this.form.querySelectorAll('.field[data-setting]')].filter((f) => this._spec(f.dataset.setting)).pop();
    if (last) last.after(wrap);
    else this.form.append(wrap);
  }

  // The form's context with `change` applied ({scene?, render?, client?}).
  _ctx(change = {}) {
    const s = this.state;
    const client = { ...s.client, ...change.client };
    return {
      info: this.info, scene: { ...s.scene, ...change.scene }, render: { ...s.render, ...change.render },
      animated: !!(s.anim && s.anim.animated), renderer: client.renderer, client,
    };
  }

  // Show the current state: {scene, render, client, anim}. Marked (refused) fields keep what the
  // user typed, unless `force` (the sheet closed).
  show(state, { force = false } = {}) {
    this.state = state;
    const { scene, render, client } = state;
    const kind = isMuseum(scene.scenario) ? 'museum' : 'thesis';
    const mesh = !!meshKind(scene.scenario);   // n, seed, radius mean nothing there: the form keeps the last ones
    if (Number.isFinite(scene.n) && !mesh) this.nByKind[kind] = scene.n;
    const set = (name, v) => {
      const el = this.el(name);
      if (!el || v === undefined || v === null) return;
      if (!force && (document.activeElement === el || this.invalid.has(name))) return;
      el.value = String(v);
    };
    for (const k of SCENE_KEYS) if (!mesh || k === 'scenario' || k === 'motion') set(k, scene[k]);
    this._fillSamples(render);
    for (const spec of this._specs()) set(spec.name, render[spec.name]);
    const known = RESOLUTIONS.some((r) => r.value === client.resolution);
    set('resolution', known ? client.resolution : 'custom');
    set('width', render.width);
    set('height', render.height);
    const scale = PREVIEW_SCALES.find((p) => Math.abs(p.value - client.previewScale) < 1e-6);
    if (!scale && ![...this.el('previewScale').options].some((o) => Number(o.value) === client.previewScale)) {
      const o = document.createElement('option');
      o.value = String(client.previewScale);
      o.textContent = `×${client.previewScale}`;
      this.el('previewScale').append(o);
    }
    set('previewScale', client.previewAuto ? 'auto' : scale ? scale.value : client.previewScale);
    for (const k of ['previewFormat', 'previewQuality', 'refineDelayMs', 'renderer']) set(k, client[k]);
    this._layout();
  }

  // Visibility, bounds and offered options, for what the form shows now (a choice made in the
  // form counts at once, before the service has answered it; refused values do not).
  _layout() {
    const render = {};
    for (const spec of this._specs()) {
      const el = this.el(spec.name);
      if (!el || this.invalid.has(spec.name) || el.value === '') continue;
      render[spec.name] = settingValue(spec, el.value);
    }
    const ctx = this._ctx({ scene: this._formScene(), render });
    for (const wrap of this.root.querySelectorAll('.field[data-setting]')) {
      const name = wrap.dataset.setting;
      let show = applies(name, ctx);
      if (SIZE_KEYS.includes(name)) show = this.el('resolution').value === 'custom';
      if ('declared' in wrap.dataset) show = show && this._reads(this._spec(name), ctx.render);
      wrap.hidden = !show;
    }
    this.root.querySelector('[data-label-n]').textContent = isMuseum(ctx.scene.scenario) ? 'Moving spheres (n)' : FIELD_LABELS.n;
    for (const name of ['n', 'seed', 'radius', ...SIZE_KEYS, ...this._specs().map((x) => x.name), 'previewQuality',
      'refineDelayMs']) {
      const rg = range(name, ctx), el = this.el(name);
      if (!rg || !el) continue;
      el.min = String(rg.min);
      el.max = String(Math.max(rg.min, rg.max));
    }
    this._fillSamples(ctx.render);
    const allowed = samplesAllowed(ctx, [...this.el('samples_per_pixel').options].map((o) => Number(o.value)));
    for (const o of this.el('samples_per_pixel').options) o.disabled = !allowed.includes(Number(o.value));
    const modes = modesOf(ctx);
    for (const o of this.el('mode').options) {
      o.disabled = !!modes && !modes.includes(o.value);
      // colour is the integrator's: its name with it (the other modes are the first hit's)
      if (o.value === 'color') o.textContent = `${modeLabel(ctx.info, 'color')} (${ctx.render.integrator === 'path' ? 'path traced' : 'Whitted'})`;
    }
  }

  // The samples select offers the integrator's counts as the service declares them (GET /api/info's
  // settings: Whitted's sub-pixel grids, the path integrator's paths) — and the session's own count of
  // paths when a link asked for one the list does not have.
  _fillSamples(render) {
    const select = this.el('samples_per_pixel');
    const ctx = { info: this.info, render };
    const values = [...sampleChoices(ctx)];
    const anyCount = !integratorValues('samples_per_pixel', ctx)?.choices;   // bounded, not listed: paths
    const own = Number(render.samples_per_pixel);
    if (anyCount && Number.isInteger(own) && own > 0 && !values.includes(own)) values.push(own);
    values.sort((a, b) => a - b);
    const have = [...select.options].map((o) => Number(o.value));
    if (have.length === values.length && have.every((v, i) => v === values[i])) return;
    fillSelect(select, values.map((v) => {
      const k = subpixels(v, ctx);
      return { value: v, label: k > 1 ? `${v} (${k} × ${k} sub-pixels)` : String(v) };
    }));
  }

  // Whether the method and mode at hand read a setting (its declaration names them).
  _reads(spec, render) {
    if (!spec) return false;
    const inList = (list, v) => !Array.isArray(list) || v === undefined || list.includes(v);
    return inList(spec.methods, render.method) && inList(spec.modes, render.mode);
  }

  // The scene as the form has it now.
  _formScene() {
    const f = this.form.elements;
    const scenario = sceneValue(f.scenario.value);
    return {
      scenario, n: Number(f.n.value),
      seed: Number(f.seed.value), radius: Number(f.radius.value), motion: f.motion.value,
    };
  }

  // Mark `name` as refused with `text` next to it (aria-invalid + a described-by message).
  mark(name, text) {
    const el = this.el(name);
    const wrap = this.root.querySelector(`.field[data-setting="${name}"]`);
    if (!el || !wrap) return false;
    let p = wrap.querySelector('.field-error');
    if (!p) {
      p = document.createElement('p');
      p.className = 'field-error';
      p.id = `f-${name}-error`;
      p.setAttribute('role', 'alert');
      wrap.append(p);
    }
    p.textContent = text;
    el.setAttribute('aria-invalid', 'true');
    el.setAttribute('aria-describedby', p.id);
    this.invalid.set(name, text);
    return true;
  }

  clear(name) {
    const el = this.el(name);
    const p = this.root.querySelector(`.field[data-setting="${name}"] .field-error`);
    if (p) p.remove();
    if (el) {
      el.removeAttribute('aria-invalid');
      el.removeAttribute('aria-describedby');
    }
    this.invalid.delete(name);
  }

  // The service refused a change ({field, text} from messages.js). → whether it is shown
  // next to its field (the sheet is open and shows it); else the app shows a notice.
  refused({ field, text }) {
    if (!field || !this.open) return false;
    const wrap = this.root.querySelector(`.field[data-setting="${field}"]`);
    if (!wrap || wrap.hidden) return false;
    return this.mark(field, text);
  }

  _problem(name, value, ctx) {
    const text = check(name, value, ctx) || this._outOfBounds(this._spec(name), value);
    if (text) this.mark(name, text);
    else this.clear(name);
    return text;
  }

  // A declared number outside its declared bounds (the checks of limits.js, which know the
  // settings' relations, come first).
  _outOfBounds(spec, value) {
    if (!spec || (spec.type !== 'integer' && spec.type !== 'number') || spec.choices) return null;
    const x = Number(value), lo = spec.minimum ?? -Infinity, hi = spec.maximum ?? Infinity;
    const whole = spec.type === 'integer';
    if (value !== '' && Number.isFinite(x) && (!whole || Number.isInteger(x)) && x >= lo && x <= hi) return null;
    return `${FIELD_LABELS[spec.name] || spec.name}: ${whole ? 'a whole number' : 'a number'} ${lo} … ${hi}`;
  }

  _changed(target) {
    const name = target.name;
    if (!name || !this.state) return;
    const v = target.value;
    if (SCENE_KEYS.includes(name)) return this._sceneChanged(name);
    if (name === 'model') return this._modelChosen(target);
    const spec = this._spec(name);
    if (spec) {
      const value = spec.type === 'integer' || spec.type === 'number' ? Number(v) : settingValue(spec, v);
      const render = { [name]: value };
      const ctx = this._ctx({ render });
      if (this._problem(name, v, ctx)) return;
      // A method that cannot draw the mode on screen: back to colour rather than a refusal.
      if (name === 'method') {
        const modes = modesOf(ctx);
        if (modes && !modes.includes(ctx.render.mode)) render.mode = 'color';
      }
      // Another integrator: samples and depth it cannot take go to the nearest it can, in the same change.
      if (name === 'integrator') {
        const spp = ctx.render.samples_per_pixel;
        if (check('samples_per_pixel', spp, ctx)) {
          const ok = samplesAllowed(ctx).filter((x) => x <= spp);
          render.samples_per_pixel = ok.length ? ok[ok.length - 1] : 1;
        }
        const rg = range('max_recursion_depth', this._ctx({ render }));
        if (ctx.render.max_recursion_depth > rg.max) render.max_recursion_depth = Math.max(1, rg.max);
        // The path integrator's resting image is denoised unless the denoiser was chosen off.
        const denoised = withRestDenoiser({ ...ctx.render, ...render });
        if (denoised.denoise !== ctx.render.denoise) render.denoise = denoised.denoise;
      }
      this._layout();
      this.cb.onRender(render);
    } else if (name === 'resolution') {
      const size = parseResolution(v);
      if (size) {
        for (const side of ['width', 'height']) {
          const text = check(side, size[side], this._ctx({ render: size }));
          if (text) {
            this.mark('resolution', text);
            return;
          }
        }
      }
      this.clear('resolution');
      this._layout();
      this.cb.onClient({ resolution: v });
    } else if (name === 'width' || name === 'height') {
      if (this._problem(name, v, this._ctx({ render: { [name]: Number(v) } }))) return;
      this.cb.onClient({ resolution: 'custom' });
      this.cb.onRender({ [name]: Number(v) });
    } else if (CLIENT_KEYS.includes(name)) {
      if (this._problem(name, v, this._ctx())) return;
      const value = name === 'previewScale' ? parseFloat(v) : ['previewQuality', 'refineDelayMs'].includes(name) ? parseInt(v, 10) : v;
      if (name === 'previewScale') this.cb.onClient(v === 'auto' ? { previewAuto: true } : { previewScale: value, previewAuto: false });
      else this.cb.onClient({ [name]: value });
      this._layout();
    }
  }

  // Model files chosen: one model file or zip, or a model file with its side files (zipped here,
  // model_upload.js); refused here when they make no one model or their suffix or size cannot be
  // right (the service's limit, GET /api/info), else handed to the app, which uploads them.
  _modelChosen(input) {
    const plan = planUpload(input.files, MODEL_FORMATS);
    if (!plan.main && !plan.problem) return;
    const limit = this.info && this.info.limits && this.info.limits.max_body_bytes;
    const problem = plan.problem ? `${FIELD_LABELS.model}: ${plan.problem}`
      : modelFileProblem(plan.main.name, plan.size, plan.format, MODEL_FORMATS, limit);
    if (problem) {
      this.mark('model', problem);
      input.value = '';
      return;
    }
    this.clear('model');
    Promise.resolve(uploadBody(plan).then((body) => this.cb.onModel(body, plan.format)))
      .finally(() => { input.value = ''; });   // the same file again: a change
  }

  _sceneChanged(name) {
    const prevKind = isMuseum(this.state.scene.scenario) ? 'museum' : 'thesis';
    if (name === 'scenario') {
      const kind = isMuseum(this.el('scenario').value) ? 'museum' : 'thesis';
      if (kind !== prevKind) {
        // The museum's n is moving spheres; a thesis n carried over could be thousands of them.
        const n = this.nByKind[kind] ?? (kind === 'museum' ? DEFAULT_MUSEUM_N : DEFAULT_SCENE.n);
        this.el('n').value = String(n);
        this.clear('n');
      }
    }
    const scene = this._formScene();
    const ctx = this._ctx({ scene });
    this._layout();
    let bad = false;
    for (const k of ['n', 'seed', 'radius']) {
      if (applies(k, ctx) && this._problem(k, this.el(k).value, ctx)) bad = true;
    }
    if (!bad) this.cb.onScene(scene);
  }
}
