// The image viewer page (#/view/ID): a job's EXR decoded in the browser and shown at full
// resolution on a canvas (zoom, pan), a readout of every channel's float value at a pixel, an
// exposure control for radiance, and A/B against a second job of the same size (toggle or split
// wipe) with the values of both and their difference. The route's query keeps what is shown:
// b (the second job; bfile, which of its EXRs), output, view, mode, exposure, back (the page Close
// returns to).
import {api, debug, el, token, techniques} from './api.js';
import {decodeExr} from './exr.js';
import {createView, displayBytes, toCanvas, viewsOf} from './viewcanvas.js';

const VIEW_NAMES = {tonemap: 'tone-mapped (as the PNG)', grey: 'grey (as the PNG)', normal: 'normal as colour',
                    depth: 'depth (as the PNG)', false_colour: 'false colour (covered range)'};
// Close returns to a dashboard page only, never to an address given from outside.
const SAFE_BACK = /^#\/(jobs|comparisons)(\/\d+)?(\?[\w=&%.-]*)?$/;

/** The EXR bytes at `url` with the API's credentials (the bearer header, else the cookie). */
async function fetchBytes(url) {
  const res = await fetch(url, {headers: token ? {Authorization: 'Bearer ' + token} : {}});
  if (!res.ok) throw new Error(`${url}: HTTP ${res.status}`);
  return res.arrayBuffer();
}

/**
 * One job's image: its document, its registry entry, its EXR decoded and the outputs whose
 * channels the file has (the registry's typed_outputs; channels no output claims become outputs
 * of their own, so every channel can be looked at).
 */
async function loadJob(id, name = null) {
  const [job, reg] = await Promise.all([api(`/api/v1/jobs/${id}`), techniques().catch(() => ({techniques: []}))]);
  if (job.state !== 'succeeded') throw new Error(`job ${id} is ${job.state}: only a finished job has images`);
  const tech = reg.techniques.find((t) => t.name === job.technique) || {};
  const exrs = (job.outputs || []).filter((o) => o.name.endsWith('.exr'));
  const file = name ? exrs.find((o) => o.name === name) : exrs.find((o) => o.name === tech.exr) || exrs[0];
  if (name && !file) throw new Error(`job ${id} has no output ${name}`);
  if (!file) throw new Error(`job ${id} has no EXR output`);
  const summaryUrl = job.links.outputs['summary.json'];
  const [img, summary] = await Promise.all([fetchBytes(file.url).then(decodeExr),
    summaryUrl ? api(summaryUrl).catch(() => null) : null]);
  const have = new Set(img.channels.map((c) => c.name));
  const outputs = (tech.typed_outputs || []).filter((o) => o.channels && o.channels.length && o.channels.every((c) => have.has(c)));
  const claimed = new Set(outputs.flatMap((o) => o.channels));
  for (const c of img.channels) {
    if (!claimed.has(c.name)) outputs.push({name: c.name, kind: 'scalar', show: 'grey', channels: [c.name]});
  }
  return {id: Number(id), job, tech, file, img, summary, outputs};
}

const fmt = (v) => (v === undefined ? '–' : Number.isNaN(v) ? 'NaN' : String(Number(v.toPrecision(7))));
const valueAt = (img, name, i) => {
  const c = img && img.channels.find((x) => x.name === name);
  return c ? c.data[i] : undefined;
};

/** The readout table of pixel p: every channel of A, and with B its value and A − B. */
function readoutRows(a, b, p) {
  const i = p.y * a.img.width + p.x;
  const names = a.img.channels.map((c) => c.name);
  if (b) for (const c of b.img.channels) if (!names.includes(c.name)) names.push(c.name);
  return names.map((name) => {
    const va = valueAt(a.img, name, i), vb = b ? valueAt(b.img, name, i) : undefined;
    return {name, a: va, b: vb, diff: va !== undefined && vb !== undefined ? va - vb : undefined};
  });
}

function renderReadout(box, a, b, p, pinned) {
  if (!p) {
    box.replaceChildren(el('p', {className: 'muted'}, 'Point at a pixel for its values; click (or press P) to pin one.'));
    return [];
  }
  const rows = readoutRows(a, b, p);
  box.replaceChildren(
    el('p', {className: 'readout-where'}, el('strong', {}, `x ${p.x}, y ${p.y}`), pinned ? ' (pinned; Shift+arrows move it)' : ''),
    el('table', {className: 'kv readout'},
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, 'Channel'), el('th', {scope: 'col', className: 'num'}, `A (job ${a.id})`),
        b ? el('th', {scope: 'col', className: 'num'}, `B (job ${b.id})`) : null, b ? el('th', {scope: 'col', className: 'num'}, 'A − B') : null)),
      el('tbody', {}, ...rows.map((r) => el('tr', {'data-channel': r.name},
        el('th', {scope: 'row'}, r.name), el('td', {className: 'num a'}, fmt(r.a)),
        b ? el('td', {className: 'num b'}, fmt(r.b)) : null, b ? el('td', {className: 'num diff'}, fmt(r.diff)) : null)))));
  return rows;
}

/** Finished jobs of A's size (newest 500), for the "Compare with" list. */
async function sameSizeJobs(a) {
  const list = await api('/api/v1/jobs?state=succeeded&limit=500');
  return list.jobs.filter((j) => j.id !== a.id && j.image.width === a.img.width && j.image.height === a.img.height);
}

function labelled(id, text, control) {
  control.id = id;
  return el('span', {className: 'tool'}, el('label', {for: id}, text), ' ', control);
}

/** The toolbar's controls; `on` holds the handlers the page fills in. */
function toolbar(on) {
  const c = {
    output: el('select', {onchange: () => on.output()}),
    view: el('select', {onchange: () => on.view()}),
    exposure: el('input', {type: 'range', min: '-8', max: '8', step: '0.25', value: '0', oninput: () => on.exposure()}),
    exposureText: el('output', {className: 'exposure-text'}, '0 EV'),
    compare: el('select', {onchange: () => on.compare()}, el('option', {value: ''}, 'nothing')),
    mode: el('select', {onchange: () => on.mode()}, el('option', {value: 'toggle'}, 'toggle A/B'), el('option', {value: 'split'}, 'split wipe')),
    split: el('input', {type: 'range', min: '0', max: '100', step: '1', value: '50', oninput: () => on.split()}),
    flip: el('button', {type: 'button', onclick: () => on.flip(), 'aria-keyshortcuts': 'B'}, 'A/B'),
    zoomText: el('output', {className: 'zoom-text', 'aria-live': 'polite'}, ''),
  };
  const btn = (text, label, keys, fn) => el('button', {type: 'button', className: 'small', 'aria-label': label, 'aria-keyshortcuts': keys, onclick: fn}, text);
  c.bar = el('div', {className: 'viewer-tools', role: 'toolbar', 'aria-label': 'Viewer'},
    el('span', {className: 'tool'}, btn('−', 'Zoom out', '-', () => on.zoom(0.5)), btn('+', 'Zoom in', '+', () => on.zoom(2)),
      btn('Fit', 'Fit to the window', 'F 0', () => on.fit()), btn('1:1', 'Actual size: one image pixel per screen pixel', '1', () => on.one()), ' ', c.zoomText),
    labelled('v-output', 'Output', c.output), labelled('v-view', 'View', c.view),
    c.exposureWrap = el('span', {className: 'tool'}, el('label', {for: 'v-exposure'}, 'Exposure (stops)'), ' ', c.exposure, ' ', c.exposureText),
    labelled('v-compare', 'Compare with', c.compare),
    c.abWrap = el('span', {className: 'tool'}, labelled('v-mode', 'Mode', c.mode), ' ', c.flip, ' ',
      c.splitWrap = el('span', {}, el('label', {for: 'v-split'}, 'Split position (%)'), ' ', c.split)));
  c.exposure.id = 'v-exposure';
  c.split.id = 'v-split';
  return c;
}

/** Keys of the viewer (none while a form control has the focus, except Escape). */
function keyHandler(page) {
  return (ev) => {
    if (ev.key === 'Escape') {
      ev.preventDefault();
      page.close();
      return;
    }
    const t = ev.target;
    if (ev.altKey || ev.ctrlKey || ev.metaKey || (t && /^(INPUT|SELECT|TEXTAREA)$/.test(t.tagName))) return;
    const arrows = {ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1]};
    const v = page.view;
    if (arrows[ev.key]) {
      const [dx, dy] = arrows[ev.key];
      if (ev.shiftKey) page.movePin(dx, dy);
      else v.panBy(-dx * 40, -dy * 40); // the arrow moves the view over the image
    } else if (ev.key === '+' || ev.key === '=') v.zoomBy(2);
    else if (ev.key === '-' || ev.key === '_') v.zoomBy(0.5);
    else if (ev.key === '0' || ev.key === 'f' || ev.key === 'F') v.fit();
    else if (ev.key === '1') v.oneToOne();
    else if (ev.key === 'b' || ev.key === 'B') page.flip();
    else if (ev.key === 's' || ev.key === 'S') page.setMode(v.state.mode === 'split' ? 'toggle' : 'split');
    else if (ev.key === 'p' || ev.key === 'P') page.pinCentre();
    else return;
    ev.preventDefault();
  };
}

/** The viewer page of job `id`: its DOM, state and handlers; destroy() when the route changes. */
class ViewerPage {
  constructor(view, id, query) {
    this.id = id;
    this.query = query;
    this.back = SAFE_BACK.test(query.get('back') || '') ? query.get('back') : `#/jobs/${id}`;
    this.st = {a: null, b: null, output: null, view: null, stops: 0, made: 0, hover: null, pin: null, dead: false};
    this.status = el('p', {role: 'alert', className: 'error'});
    this.note = el('p', {className: 'muted viewer-note'}, `Loading the EXR of job ${id}…`);
    this.canvas = el('canvas', {className: 'viewer-canvas', tabindex: '0', role: 'img',
      'aria-label': `Job ${id} at full resolution. Keys: + and − zoom, F fits, 1 shows actual size, arrows pan, ` +
        'P pins the centre pixel and Shift+arrows move it, B flips A and B, S splits, Escape closes.'});
    this.readout = el('div', {className: 'readout-box'});
    // Screen readers hear a pinned pixel's values, not every pixel the pointer crosses.
    this.pinned = el('p', {className: 'sr-only', 'aria-live': 'polite'});
    this.title = el('h1', {}, `Job ${id}: viewer`);
    this.tools = toolbar({
      output: () => { this.chooseOutput(this.tools.output.value); this.redraw(); },
      view: () => { this.st.view = this.tools.view.value; this.redraw(); },
      exposure: () => { this.st.stops = Number(this.tools.exposure.value); this.redraw(); },
      compare: () => this.setB(this.tools.compare.value ? Number(this.tools.compare.value) : null),
      mode: () => this.setMode(this.tools.mode.value),
      split: () => this.view.setSplit(Number(this.tools.split.value) / 100),
      flip: () => this.view.flip(), zoom: (f) => this.view.zoomBy(f), fit: () => this.view.fit(), one: () => this.view.oneToOne(),
    });
    view.append(el('p', {className: 'crumbs'}, el('a', {href: this.back, className: 'button small'}, '✕ Close'), ' ',
      el('a', {href: `#/jobs/${id}`}, `job ${id}`)), this.title, this.status, this.tools.bar, this.note,
      el('div', {className: 'viewer-main'}, this.canvas,
        el('section', {className: 'readout-panel', 'aria-label': 'Pixel values'}, this.readout, this.pinned)));
    this.view = createView(this.canvas, {pixel: (p, click) => this.onPixel(p, click), change: () => this.onChange()});
    debug.viewer = {ready: false, view: this.view.state, st: this.st};
    this.onKey = keyHandler(this);
    document.addEventListener('keydown', this.onKey);
  }

  close() {
    location.hash = this.back;
  }
  flip() {
    this.view.flip();
  }

  onPixel(p, click) {
    const {st} = this;
    if (click) st.pin = p && st.pin && p.x === st.pin.x && p.y === st.pin.y ? null : p;
    else st.hover = p;
    this.showReadout();
  }
  showReadout() {
    const {st} = this;
    if (!st.a) return;
    const p = st.pin || st.hover;
    const rows = renderReadout(this.readout, st.a, st.b, p, !!st.pin && p === st.pin);
    const said = st.pin ? `Pinned x ${st.pin.x}, y ${st.pin.y}` : 'No pixel pinned';
    if (p === st.pin || !st.pin) this.pinned.textContent = st.pin ? `${said}: ${rows.map((r) => `${r.name} ${fmt(r.a)}`).join(', ')}` : said;
    debug.viewer.readout = p ? {x: p.x, y: p.y, pinned: p === st.pin, rows} : null;
  }
  movePin(dx, dy) {
    const {st} = this;
    if (!st.a) return;
    const p = st.pin || st.hover || {x: 0, y: 0};
    st.pin = {x: Math.min(st.a.img.width - 1, Math.max(0, p.x + dx)), y: Math.min(st.a.img.height - 1, Math.max(0, p.y + dy))};
    this.showReadout();
  }
  pinCentre() {
    this.st.pin = this.st.pin ? null : this.view.pixelAt(this.canvas.width / 2, this.canvas.height / 2);
    this.showReadout();
  }

  onChange() {
    const s = this.view.state, other = s.showing === 'A' ? 'B' : 'A';
    this.tools.zoomText.textContent = `${s.zoom >= 1 ? Math.round(s.zoom * 100) : (s.zoom * 100).toPrecision(2)} %${s.fitted ? ' (fit)' : ''}` +
      (this.st.b ? ` · showing ${s.mode === 'split' ? `${s.showing} left, ${other} right` : s.showing}` : '');
    this.tools.split.value = String(Math.round(s.split * 100));
  }
  setMode(m) {
    this.tools.mode.value = m;
    this.view.setMode(m);
    this.tools.splitWrap.hidden = m !== 'split';
    this.keepUrl();
  }

  // The route's query follows the choices, so a view can be linked (replaceState: no new route).
  keepUrl() {
    const {st} = this, q = new URLSearchParams();
    if (st.b) q.set('b', String(st.b.id));
    if (st.b && st.b.file.name !== st.b.tech.exr) q.set('bfile', st.b.file.name);
    if (st.output) q.set('output', st.output.name);
    if (st.view) q.set('view', st.view);
    if (st.b) q.set('mode', this.view.state.mode);
    if (st.stops !== st.made) q.set('exposure', String(st.stops));
    if (this.query.get('back')) q.set('back', this.back);
    history.replaceState(null, '', `#/view/${this.id}${q.toString() ? `?${q}` : ''}`);
  }

  /** B's output for A's: the same name when B has it, else B's primary, else its first. */
  outputOfB() {
    const {st} = this;
    return st.b && (st.b.outputs.find((o) => o.name === st.output.name) || st.b.outputs.find((o) => o.primary) || st.b.outputs[0]);
  }

  redraw() {
    const {st, tools} = this;
    const bOut = this.outputOfB();
    const bView = bOut && (viewsOf(bOut).includes(st.view) ? st.view : viewsOf(bOut)[0]);
    tools.exposureWrap.hidden = st.view !== 'tonemap' && bView !== 'tonemap';
    tools.exposureText.textContent = `${st.stops > 0 ? '+' : ''}${st.stops} EV`;
    this.view.setImages(toCanvas(displayBytes(st.a.img, st.output, st.view, st.stops)),
                        st.b ? toCanvas(displayBytes(st.b.img, bOut, bView, st.stops)) : null);
    tools.abWrap.hidden = !st.b;
    this.note.textContent = `${st.a.job.technique} on ${st.a.job.backend.actual}, ${st.a.img.width}×${st.a.img.height}, ` +
      `${st.a.file.name} (${st.a.img.compression}, ${st.a.img.channels.length} channels)` +
      (st.b ? `; B: job ${st.b.id}, ${st.b.job.technique} on ${st.b.job.backend.actual}, output ${bOut.name}` : '') + '.';
    this.showReadout();
    this.keepUrl();
    Object.assign(debug.viewer, {a: st.a, b: st.b, output: st.output.name, mode: st.view, stops: st.stops});
  }

  chooseOutput(name, view) {
    const {st} = this;
    st.output = st.a.outputs.find((o) => o.name === name) || st.a.outputs.find((o) => o.primary) || st.a.outputs[0];
    const views = viewsOf(st.output);
    if (views.includes(view)) st.view = view;
    if (!views.includes(st.view)) st.view = views[0];
    this.tools.view.replaceChildren(...views.map((x) => el('option', {value: x, selected: x === st.view}, VIEW_NAMES[x])));
  }

  async setB(bid, bfile = null) {
    const {st, tools} = this;
    tools.compare.value = bid ? String(bid) : '';
    st.b = null;
    this.status.textContent = '';
    try {
      const b = bid ? await loadJob(bid, bfile) : null;
      if (st.dead) return;
      if (b && (b.img.width !== st.a.img.width || b.img.height !== st.a.img.height)) {
        throw new Error(`job ${bid} is ${b.img.width}×${b.img.height}, job ${this.id} ${st.a.img.width}×${st.a.img.height}: A/B needs the same size`);
      }
      st.b = b;
    } catch (e) {
      tools.compare.value = '';
      this.status.textContent = `Cannot compare with job ${bid}: ${e.message}`;
    }
    this.redraw();
  }

  /** The compare list: finished jobs of A's size. */
  async listCandidates() {
    const jobs = await sameSizeJobs(this.st.a);
    if (this.st.dead) return;
    const none = jobs.length ? 'nothing' : `nothing (no other finished job is ${this.st.a.img.width}×${this.st.a.img.height})`;
    this.tools.compare.replaceChildren(el('option', {value: ''}, none), ...jobs.map((j) => el('option', {value: String(j.id)},
      `job ${j.id}: ${j.technique} on ${j.backend.actual}${j.label ? ` (${j.label})` : ''}`)));
    this.tools.compare.value = this.st.b ? String(this.st.b.id) : '';
    debug.viewer.candidates = jobs.map((j) => j.id);
  }

  async start() {
    const {st, query, tools} = this;
    try {
      st.a = await loadJob(this.id);
    } catch (e) {
      if (st.dead) return;
      this.note.textContent = '';
      this.status.textContent = `Cannot show job ${this.id}: ${e.message}`;
      debug.viewer.error = e.message;
      return;
    }
    if (st.dead) return;
    this.title.textContent = `Job ${this.id}: ${st.a.job.technique} at full resolution`;
    const fromPng = st.a.outputs.find((o) => o.png && o.png === query.get('png'));
    this.chooseOutput(query.get('output') || (fromPng && fromPng.name), query.get('view'));
    tools.output.replaceChildren(...st.a.outputs.map((o) => el('option', {value: o.name, selected: o === st.output},
      `${o.name} (${o.channels.join(', ')})`)));
    // The slider starts at the exposure the PNG was made with, so the first view is the PNG.
    const param = st.a.outputs.find((o) => o.exposure_param);
    st.made = param && st.a.summary ? Number(st.a.summary.params[param.exposure_param]) || 0 : 0;
    st.stops = query.has('exposure') ? Number(query.get('exposure')) || 0 : st.made;
    tools.exposure.value = String(st.stops);
    this.setMode(query.get('mode') === 'split' ? 'split' : 'toggle');
    this.redraw();
    // bfile: another EXR output of job b than its technique's (a candidate's mapped reference).
    if (/^\d+$/.test(query.get('b') || '')) await this.setB(Number(query.get('b')), /^[\w.-]+\.exr$/.test(query.get('bfile') || '') ? query.get('bfile') : null);
    this.listCandidates().catch((e) => { this.status.textContent = `Cannot list jobs to compare with: ${e.message}`; });
    if (query.get('compare')) tools.compare.focus();
    else this.canvas.focus({preventScroll: true});
    debug.viewer.ready = true;
  }

  destroy() {
    this.st.dead = true;
    this.view.destroy();
    document.removeEventListener('keydown', this.onKey);
  }
}

export function mountViewer(view, [id], query) {
  const page = new ViewerPage(view, id, query);
  page.start();
  return () => page.destroy();
}
