// The image viewer page (#/view/ID): a stack of EXRs (any outputs of any jobs of one size, a
// running job's preview among them) decoded in the browser and shown at full resolution on a
// canvas (zoom, pan), number keys 1..9 switching the image shown; a readout of every channel's
// float value at a pixel; an exposure control for radiance; the shown image (A) against the
// stack's reference (B): toggle or split wipe, or an error map (signed, absolute, relative,
// squared, FLIP) through a colour ramp with its legend and the histogram of the covered pixels.
// The route's query keeps what is shown: stack (the other images, "<job>" or "<job>/<file>.exr"),
// ref and cur (1-based places in the stack), b (a reference to add: the comparison page's way
// in), output, view, mode, show, max, exposure, back (the page Close returns to).
import {api, debug, el, token} from './api.js';
import {decodeExr} from './exr.js';
import {ERROR_MODES, errorBytes, errorMap, histogram, histogramFigure, legend, mapFromChannel, rampRange} from './errormap.js';
import {createView, displayBytes, toCanvas, viewsOf} from './viewcanvas.js';
import {loadEntry, outputFor, parseSpec, refreshEntry, specOf} from './viewstack.js';

const VIEW_NAMES = {tonemap: 'tone-mapped (as the PNG)', grey: 'grey (as the PNG)', normal: 'normal as colour',
                    depth: 'depth (as the PNG)', false_colour: 'false colour (covered range)'};
// Close returns to a dashboard page only, never to an address given from outside.
const SAFE_BACK = /^#\/(jobs|comparisons)(\/\d+)?(\?[\w=&%.-]*)?$/;
const REFRESH_MS = 700; // a running job's preview changes at most every 500 ms on the server
const MAX_STACK = 9;    // one number key each

const fmt = (v) => (v === undefined ? '–' : Number.isNaN(v) ? 'NaN' : String(Number(v.toPrecision(7))));
const valueAt = (img, name, i) => {
  const c = img && img.channels.find((x) => x.name === name);
  return c ? c.data[i] : undefined;
};
const entryName = (e) => `job ${e.id}${e.given ? ` ${e.file}` : ''}`;

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

function renderReadout(box, a, b, p, pinned, err) {
  if (!p) {
    box.replaceChildren(el('p', {className: 'muted'}, 'Point at a pixel for its values; click (or press P) to pin one.'));
    return [];
  }
  const rows = readoutRows(a, b, p);
  const e = err && err.map.covered[p.y * a.img.width + p.x] ? err.map.data[p.y * a.img.width + p.x] : undefined;
  box.replaceChildren(
    el('p', {className: 'readout-where'}, el('strong', {}, `x ${p.x}, y ${p.y}`), pinned ? ' (pinned; Shift+arrows move it)' : ''),
    el('table', {className: 'kv readout'},
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, 'Channel'), el('th', {scope: 'col', className: 'num'}, `A (${entryName(a)})`),
        b ? el('th', {scope: 'col', className: 'num'}, `B (${entryName(b)})`) : null, b ? el('th', {scope: 'col', className: 'num'}, 'A − B') : null)),
      el('tbody', {}, ...rows.map((r) => el('tr', {'data-channel': r.name},
        el('th', {scope: 'row'}, r.name), el('td', {className: 'num a'}, fmt(r.a)),
        b ? el('td', {className: 'num b'}, fmt(r.b)) : null, b ? el('td', {className: 'num diff'}, fmt(r.diff)) : null)))),
    err ? el('p', {className: 'readout-error'}, `${ERROR_MODES[err.mode].label} of ${err.output}: `,
      el('span', {className: 'num err-value'}, err.map.covered[p.y * a.img.width + p.x] ? fmt(e) : 'not covered')) : null);
  return rows;
}

/** Finished jobs of the size w × h (newest 500), for the "Compare with" and "Add" lists. */
async function sameSizeJobs(w, h) {
  const list = await api('/api/v1/jobs?state=succeeded&limit=500');
  return list.jobs.filter((j) => j.image.width === w && j.image.height === h);
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
    add: el('select', {onchange: () => on.add()}, el('option', {value: ''}, 'choose a job…')),
    addName: el('input', {type: 'text', size: 12, placeholder: 'job/file.exr', className: 'add-name',
      onkeydown: (ev) => { if (ev.key === 'Enter') on.addName(); }}),
    show: el('select', {onchange: () => on.show(), 'aria-keyshortcuts': 'E'}, el('option', {value: 'image'}, 'none: the image (A/B)'),
      ...Object.entries(ERROR_MODES).map(([k, m]) => el('option', {value: k}, m.label))),
    max: el('input', {type: 'number', min: '0', step: 'any', placeholder: 'automatic', className: 'ramp-max', onchange: () => on.max()}),
    mode: el('select', {onchange: () => on.mode()}, el('option', {value: 'toggle'}, 'toggle A/B'), el('option', {value: 'split'}, 'split wipe')),
    split: el('input', {type: 'range', min: '0', max: '100', step: '1', value: '50', oninput: () => on.split()}),
    flip: el('button', {type: 'button', onclick: () => on.flip(), 'aria-keyshortcuts': 'B'}, 'A/B'),
    zoomText: el('output', {className: 'zoom-text', 'aria-live': 'polite'}, ''),
  };
  const btn = (text, label, keys, fn) => el('button', {type: 'button', className: 'small', 'aria-label': label, 'aria-keyshortcuts': keys, onclick: fn}, text);
  c.bar = el('div', {className: 'viewer-tools', role: 'toolbar', 'aria-label': 'Viewer'},
    el('span', {className: 'tool'}, btn('−', 'Zoom out', '-', () => on.zoom(0.5)), btn('+', 'Zoom in', '+', () => on.zoom(2)),
      btn('Fit', 'Fit to the window', 'F 0', () => on.fit()), btn('1:1', 'Actual size: one image pixel per screen pixel', 'A', () => on.one()), ' ', c.zoomText),
    labelled('v-output', 'Output', c.output), labelled('v-view', 'View', c.view),
    c.exposureWrap = el('span', {className: 'tool'}, el('label', {for: 'v-exposure'}, 'Exposure (stops)'), ' ', c.exposure, ' ', c.exposureText),
    labelled('v-compare', 'Compare with', c.compare), labelled('v-add', 'Add to the stack', c.add),
    labelled('v-add-name', 'or by name', c.addName),
    c.showWrap = el('span', {className: 'tool'}, labelled('v-show', 'Error map', c.show), ' ',
      c.maxWrap = labelled('v-max', 'Ramp maximum', c.max)),
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
    } else if (/^[1-9]$/.test(ev.key)) page.select(Number(ev.key) - 1);
    else if (ev.key === '+' || ev.key === '=') v.zoomBy(2);
    else if (ev.key === '-' || ev.key === '_') v.zoomBy(0.5);
    else if (ev.key === '0' || ev.key === 'f' || ev.key === 'F') v.fit();
    else if (ev.key === 'a' || ev.key === 'A') v.oneToOne();
    else if (ev.key === 'b' || ev.key === 'B') page.flip();
    else if (ev.key === 'e' || ev.key === 'E') page.nextShow();
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
    this.st = {stack: [], cur: 0, ref: null, output: null, view: null, show: 'image', max: 0, stops: 0, made: 0,
               hover: null, pin: null, err: null, flips: new Map(), dead: false};
    this.status = el('p', {role: 'alert', className: 'error'});
    this.note = el('p', {className: 'muted viewer-note', 'aria-live': 'polite'}, `Loading the EXR of job ${id}…`);
    this.canvas = el('canvas', {className: 'viewer-canvas', tabindex: '0', role: 'img',
      'aria-label': `Job ${id} at full resolution. Keys: 1 to 9 show the stack's images, + and − zoom, F fits, A shows actual ` +
        'size, arrows pan, P pins the centre pixel and Shift+arrows move it, B flips A and B, S splits, E steps through the error maps, Escape closes.'});
    this.readout = el('div', {className: 'readout-box'});
    this.stackBox = el('section', {className: 'stack-panel', 'aria-label': 'Image stack'});
    this.errorBox = el('section', {className: 'error-panel', 'aria-label': 'Error map scale and histogram'});
    // Screen readers hear a pinned pixel's values, not every pixel the pointer crosses.
    this.pinned = el('p', {className: 'sr-only', 'aria-live': 'polite'});
    this.title = el('h1', {}, `Job ${id}: viewer`);
    this.tools = toolbar({
      output: () => { this.chooseOutput(this.tools.output.value); this.redraw(); },
      view: () => { this.st.view = this.tools.view.value; this.redraw(); },
      exposure: () => { this.st.stops = Number(this.tools.exposure.value); this.redraw(); },
      compare: () => this.compareWith(this.tools.compare.value ? Number(this.tools.compare.value) : null),
      add: () => { const v = this.tools.add.value; this.tools.add.value = ''; if (v) this.addEntry(v, false); },
      addName: () => { const v = this.tools.addName.value.trim(); if (v) this.addEntry(v, false).then(() => { this.tools.addName.value = ''; }); },
      show: () => this.setShow(this.tools.show.value),
      max: () => { this.st.max = Number(this.tools.max.value) > 0 ? Number(this.tools.max.value) : 0; this.redraw(); },
      mode: () => this.setMode(this.tools.mode.value),
      split: () => this.view.setSplit(Number(this.tools.split.value) / 100),
      flip: () => this.view.flip(), zoom: (f) => this.view.zoomBy(f), fit: () => this.view.fit(), one: () => this.view.oneToOne(),
    });
    view.append(el('p', {className: 'crumbs'}, el('a', {href: this.back, className: 'button small'}, '✕ Close'), ' ',
      el('a', {href: `#/jobs/${id}`}, `job ${id}`)), this.title, this.status, this.tools.bar, this.note,
      el('div', {className: 'viewer-main'}, this.canvas,
        el('div', {className: 'readout-panel'}, this.stackBox, this.errorBox,
          el('section', {'aria-label': 'Pixel values'}, this.readout, this.pinned))));
    this.view = createView(this.canvas, {pixel: (p, click) => this.onPixel(p, click), change: () => this.onChange()});
    debug.viewer = {ready: false, view: this.view.state, st: this.st,
                    errorAt: (x, y) => (this.st.err && this.st.err.map.covered[y * this.a().img.width + x] ? this.st.err.map.data[y * this.a().img.width + x] : null)};
    this.onKey = keyHandler(this);
    document.addEventListener('keydown', this.onKey);
  }

  a() {
    return this.st.stack[this.st.cur];
  }
  /** The reference, when it is not the image shown. */
  b() {
    const {st} = this;
    return st.ref !== null && st.ref !== st.cur && st.stack[st.ref] && st.stack[st.ref].img ? st.stack[st.ref] : null;
  }

  close() {
    location.hash = this.back;
  }
  flip() {
    if (this.st.show === 'image') this.view.flip();
  }
  select(k) {
    if (k >= this.st.stack.length || !this.st.stack[k].img || k === this.st.cur) return;
    this.st.cur = k;
    this.redraw();
  }
  nextShow() {
    const modes = ['image', ...Object.keys(ERROR_MODES)];
    this.setShow(modes[(modes.indexOf(this.st.show) + 1) % modes.length]);
  }
  setShow(m) {
    this.st.show = m;
    this.tools.show.value = m;
    this.redraw();
  }

  onPixel(p, click) {
    const {st} = this;
    if (click) st.pin = p && st.pin && p.x === st.pin.x && p.y === st.pin.y ? null : p;
    else st.hover = p;
    this.showReadout();
  }
  showReadout() {
    const {st} = this, a = this.a();
    if (!a || !a.img) return;
    const p = st.pin || st.hover;
    const rows = renderReadout(this.readout, a, this.b(), p, !!st.pin && p === st.pin, st.err);
    const said = st.pin ? `Pinned x ${st.pin.x}, y ${st.pin.y}` : 'No pixel pinned';
    if (p === st.pin || !st.pin) this.pinned.textContent = st.pin ? `${said}: ${rows.map((r) => `${r.name} ${fmt(r.a)}`).join(', ')}` : said;
    debug.viewer.readout = p ? {x: p.x, y: p.y, pinned: p === st.pin, rows} : null;
  }
  movePin(dx, dy) {
    const {st} = this, a = this.a();
    if (!a || !a.img) return;
    const p = st.pin || st.hover || {x: 0, y: 0};
    st.pin = {x: Math.min(a.img.width - 1, Math.max(0, p.x + dx)), y: Math.min(a.img.height - 1, Math.max(0, p.y + dy))};
    this.showReadout();
  }
  pinCentre() {
    this.st.pin = this.st.pin ? null : this.view.pixelAt(this.canvas.width / 2, this.canvas.height / 2);
    this.showReadout();
  }

  onChange() {
    const s = this.view.state, other = s.showing === 'A' ? 'B' : 'A';
    this.tools.zoomText.textContent = `${s.zoom >= 1 ? Math.round(s.zoom * 100) : (s.zoom * 100).toPrecision(2)} %${s.fitted ? ' (fit)' : ''}` +
      (s.hasB ? ` · showing ${s.mode === 'split' ? `${s.showing} left, ${other} right` : s.showing}` : '');
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
    if (st.stack.length > 1) q.set('stack', st.stack.slice(1).map(specOf).join(','));
    if (st.ref !== null) q.set('ref', String(st.ref + 1));
    if (st.cur) q.set('cur', String(st.cur + 1));
    if (st.output) q.set('output', st.output.name);
    if (st.view) q.set('view', st.view);
    if (this.b()) q.set('mode', this.view.state.mode);
    if (st.show !== 'image') q.set('show', st.show);
    if (st.max) q.set('max', String(st.max));
    if (st.stops !== st.made) q.set('exposure', String(st.stops));
    if (this.query.get('back')) q.set('back', this.back);
    history.replaceState(null, '', `#/view/${this.id}${q.toString() ? `?${q}` : ''}`);
  }

  /** The display image of entry e's output for A's: its own view when it offers A's, else its first. */
  display(e) {
    const out = outputFor(e, this.st.output.name), views = viewsOf(out);
    return {out, canvas: toCanvas(displayBytes(e.img, out, views.includes(this.st.view) ? this.st.view : views[0], this.st.stops))};
  }

  redraw() {
    const {st, tools} = this, a = this.a(), b = this.b();
    if (!a || !a.img) return;
    const bOut = b && outputFor(b, st.output.name);
    tools.exposureWrap.hidden = st.output.kind !== 'rgb' && !(bOut && bOut.kind === 'rgb');
    tools.exposureText.textContent = `${st.stops > 0 ? '+' : ''}${st.stops} EV`;
    st.err = null;
    if (st.show !== 'image' && b) this.drawError(a, b);
    else this.view.setImages(this.display(a).canvas, b ? this.display(b).canvas : null);
    if (st.show === 'image' || !b) this.errorBox.replaceChildren(st.show !== 'image' ? el('p', {className: 'muted'},
      'An error map needs a reference other than the image shown: choose one in the stack.') : '');
    tools.abWrap.hidden = !b || st.show !== 'image';
    tools.maxWrap.hidden = st.show === 'image';
    const live = a.live ? ` Running: the preview of the tiles rendered so far (${Math.round(100 * (a.job.progress || 0))} %).` : '';
    this.note.textContent = `${a.job.technique} on ${a.job.backend.actual || a.job.backend.requested}, ${a.img.width}×${a.img.height}, ` +
      `${a.live ? 'preview.exr' : a.file} (${a.compression}, ${a.img.channels.length} channels)` +
      (b ? `; B: ${entryName(b)}, ${b.job.technique} on ${b.job.backend.actual}, output ${bOut.name}` : '') + '.' + live;
    this.renderStack();
    this.showReadout();
    this.keepUrl();
    Object.assign(debug.viewer, {a, b, output: st.output.name, mode: st.view, stops: st.stops, cur: st.cur, ref: st.ref, show: st.show});
  }

  /** The error map of A against B for the output shown (FLIP from the server, the rest here). */
  drawError(a, b) {
    const {st} = this, out = st.output, bOut = outputFor(b, out.name);
    const same = out.channels.length === bOut.channels.length && out.channels.every((c, k) => c === bOut.channels[k]);
    let map = null, why = '', mean = null;
    if (!same) why = `B has no output ${out.name}: an error map compares the same channels`;
    else if (st.show !== 'flip') map = errorMap(a.img, b.img, out.channels, st.show);
    else {
      const got = this.flipMap(a, b, out);
      if (got && got.map) [map, mean] = [got.map, got.mean];
      else why = got ? got.why : 'FLIP: asking the server…';
    }
    if (!map) {
      this.view.setImages(this.display(a).canvas, null);
      this.errorBox.replaceChildren(el('p', {className: why.startsWith('FLIP: asking') ? 'muted' : 'error'}, why));
      debug.viewer.error = {mode: st.show, why};
      return;
    }
    const [lo, hi] = rampRange(map, st.show, st.max), hist = histogram(map, lo, hi);
    st.err = {mode: st.show, output: out.name, map, lo, hi, hist};
    this.view.setImages(toCanvas(errorBytes(map, st.show, lo, hi, a.img.width, a.img.height)), null);
    this.errorBox.replaceChildren(legend(st.show, lo, hi), histogramFigure(hist, st.show),
      mean !== null ? el('p', {className: 'flip-mean'}, `Mean FLIP over every pixel (the server's): ${fmt(mean)}`) : '');
    debug.viewer.error = {mode: st.show, output: out.name, lo, hi, counts: hist.counts, total: hist.total, mean};
  }

  /** FLIP's map of A against B from GET /api/v1/diff, cached; null while it is being fetched. */
  flipMap(a, b, out) {
    if (a.live || b.live) return {why: 'FLIP is computed by the server from finished jobs\' files: this image is a running job\'s preview'};
    if (out.kind === 'vector' || out.kind === 'depth') return {why: `FLIP compares display values or colours; ${out.name} is a ${out.kind}`};
    const hdr = out.kind === 'rgb' ? 1 : 0, channel = hdr ? out.channels[0].replace(/\.[^.]*$/, '') : out.channels[0];
    const key = `${a.id}/${a.file}|${b.id}/${b.file}|${channel}|${hdr}`;
    const got = this.st.flips.get(key);
    if (got) return got.pending ? null : got;
    this.st.flips.set(key, {pending: true});
    const url = `/api/v1/diff?a=${a.id}/${a.file}&b=${b.id}/${b.file}&channel=${encodeURIComponent(channel)}&hdr=${hdr}`;
    fetch(url, {headers: token ? {Authorization: 'Bearer ' + token} : {}}).then(async (res) => {
      if (!res.ok) throw new Error((await res.json().catch(() => ({}))).error || `HTTP ${res.status}`);
      const mean = Number(res.headers.get('X-Obscura-Flip-Mean'));
      return {map: mapFromChannel(await decodeExr(await res.arrayBuffer()), 'flip', a.img, b.img), mean};
    }).then((r) => this.st.flips.set(key, r), (e) => this.st.flips.set(key, {why: `FLIP: ${e.message}`}))
      .then(() => { if (!this.st.dead && this.st.show === 'flip') this.redraw(); });
    return null;
  }

  /** The stack's list: number key, job, file, reference radio, remove button. */
  renderStack() {
    const {st} = this;
    const items = st.stack.map((e, k) => el('li', {'data-index': String(k), className: k === st.cur ? 'current' : ''},
      el('button', {type: 'button', className: 'small show-entry', 'aria-pressed': String(k === st.cur), 'aria-keyshortcuts': String(k + 1),
        disabled: !e.img, onclick: () => this.select(k)}, `${k + 1}`),
      ` ${entryName(e)}: ${e.job.technique}${e.job.label ? ` (${e.job.label})` : ''}${e.live ? (e.img ? ' · running, preview' : ' · running, no tile yet') : ''} `,
      el('label', {}, el('input', {type: 'radio', name: 'v-ref', checked: k === st.ref, disabled: !e.img,
        'aria-label': `${entryName(e)} as the reference (B)`, onchange: () => { st.ref = k; this.redraw(); }}), ' reference'),
      k ? el('button', {type: 'button', className: 'small', 'aria-label': `Remove ${entryName(e)} from the stack`, onclick: () => this.removeEntry(k)}, '✕') : null));
    debug.viewer.stack = st.stack.map((e) => ({id: e.id, file: e.file, live: e.live, version: e.version}));
    this.stackBox.replaceChildren(el('h2', {}, 'Stack'), el('ol', {className: 'image-stack'}, ...items),
      el('p', {className: 'muted'}, 'Keys 1–9 show an image; the reference (B) is what the error maps and A/B compare against.'));
  }

  chooseOutput(name, view) {
    const {st} = this, a = this.a();
    st.output = outputFor(a, name);
    const views = viewsOf(st.output);
    if (views.includes(view)) st.view = view;
    if (!views.includes(st.view)) st.view = views[0];
    this.tools.view.replaceChildren(...views.map((x) => el('option', {value: x, selected: x === st.view}, VIEW_NAMES[x])));
    this.tools.output.replaceChildren(...a.outputs.map((o) => el('option', {value: o.name, selected: o === st.output},
      `${o.name} (${o.channels.join(', ')})`)));
  }

  /** Adds the image `spec` to the stack (at most MAX_STACK); `asRef` makes it the reference. */
  async addEntry(spec, asRef) {
    const {st} = this;
    this.status.textContent = '';
    const s = parseSpec(spec);
    const have = s && st.stack.findIndex((e) => e.id === s.id && (s.file ? e.file === s.file : !e.given));
    try {
      if (have >= 0) {
        if (asRef) st.ref = have;
      } else {
        if (st.stack.length >= MAX_STACK) throw new Error(`the stack holds ${MAX_STACK} images (one number key each)`);
        const e = await loadEntry(spec);
        if (st.dead) return;
        const a0 = st.stack[0];
        if (e.job.image.width !== a0.job.image.width || e.job.image.height !== a0.job.image.height) {
          throw new Error(`job ${e.id} is ${e.job.image.width}×${e.job.image.height}, job ${this.id} ${a0.job.image.width}×${a0.job.image.height}: ` +
            'the images of a stack have one size');
        }
        st.stack.push(e);
        if (asRef) st.ref = st.stack.length - 1;
        this.keepRefreshing();
      }
    } catch (err) {
      this.status.textContent = `Cannot add ${spec}: ${err.message}`;
    }
    this.tools.compare.value = this.b() ? String(this.b().id) : '';
    this.redraw();
  }
  removeEntry(k) {
    const {st} = this;
    st.stack.splice(k, 1);
    if (st.ref === k) st.ref = null;
    else if (st.ref > k) st.ref--;
    if (st.cur >= k && st.cur) st.cur--;
    this.tools.compare.value = this.b() ? String(this.b().id) : '';
    this.redraw();
  }
  /** "Compare with": job `bid` as the reference (added when missing), or none. */
  async compareWith(bid) {
    if (!bid) {
      this.st.ref = null;
      this.redraw();
      return;
    }
    await this.addEntry(String(bid), true);
    if (!this.b() || this.b().id !== bid) this.tools.compare.value = '';
  }

  /** The compare and add lists: finished jobs of A's size. */
  async listCandidates() {
    const a0 = this.st.stack[0];
    const jobs = (await sameSizeJobs(a0.job.image.width, a0.job.image.height)).filter((j) => j.id !== a0.id);
    if (this.st.dead) return;
    const none = jobs.length ? 'nothing' : `nothing (no other finished job is ${a0.job.image.width}×${a0.job.image.height})`;
    const opts = () => jobs.map((j) => el('option', {value: String(j.id)}, `job ${j.id}: ${j.technique} on ${j.backend.actual}${j.label ? ` (${j.label})` : ''}`));
    this.tools.compare.replaceChildren(el('option', {value: ''}, none), ...opts());
    this.tools.add.replaceChildren(el('option', {value: ''}, 'choose a job…'), ...opts());
    this.tools.compare.value = this.b() ? String(this.b().id) : '';
    debug.viewer.candidates = jobs.map((j) => j.id);
  }

  /** Refreshes the running jobs' previews (and swaps in their final EXRs once they finish). */
  async refresh() {
    const {st} = this;
    const live = st.stack.filter((e) => e.live);
    for (const e of live) {
      const before = e.version;
      try {
        await refreshEntry(e);
      } catch (err) {
        this.status.textContent = `${entryName(e)}: ${err.message}`;
      }
      if (st.dead) return;
      if (e.version !== before || !e.live) {
        if (e === st.stack[0] && !st.output && e.img) this.firstImage();
        else this.redraw();
      }
    }
    this.timer = null;
    this.keepRefreshing();
  }
  /** Schedules the next refresh while any entry is a running job's. */
  keepRefreshing() {
    if (!this.timer && !this.st.dead && this.st.stack.some((e) => e.live)) this.timer = setTimeout(() => this.refresh(), REFRESH_MS);
  }

  /** Once the first entry has an image: outputs, exposure, the rest of the query, the first draw. */
  firstImage() {
    const {st, query, tools} = this, a = st.stack[0];
    this.title.textContent = `Job ${this.id}: ${a.job.technique} at full resolution`;
    const fromPng = a.outputs.find((o) => o.png && o.png === query.get('png'));
    this.chooseOutput(query.get('output') || (fromPng && fromPng.name), query.get('view'));
    // The slider starts at the exposure the PNG was made with, so the first view is the PNG.
    const param = a.outputs.find((o) => o.exposure_param);
    st.made = param && a.summary ? Number(a.summary.params[param.exposure_param]) || 0 : 0;
    st.stops = query.has('exposure') ? Number(query.get('exposure')) || 0 : st.made;
    tools.exposure.value = String(st.stops);
    this.setMode(query.get('mode') === 'split' ? 'split' : 'toggle');
    this.redraw();
  }

  async start() {
    const {st, query, tools} = this;
    try {
      st.stack.push(await loadEntry(String(this.id)));
    } catch (e) {
      if (st.dead) return;
      this.note.textContent = '';
      this.status.textContent = `Cannot show job ${this.id}: ${e.message}`;
      debug.viewer.error = e.message;
      return;
    }
    if (st.dead) return;
    const a = st.stack[0];
    if (a.img) this.firstImage();
    else this.note.textContent = `Job ${this.id} is ${a.job.state}: waiting for its first tiles…`;
    this.renderStack();
    for (const spec of (query.get('stack') || '').split(',').filter(Boolean)) await this.addEntry(spec, false);
    const ref = Number(query.get('ref')), cur = Number(query.get('cur'));
    if (ref >= 1 && ref <= st.stack.length) st.ref = ref - 1;
    if (cur >= 1 && cur <= st.stack.length && st.stack[cur - 1].img) st.cur = cur - 1;
    if (query.get('b')) await this.addEntry(query.get('b'), true);
    if (query.get('show') in ERROR_MODES) tools.show.value = st.show = query.get('show');
    if (Number(query.get('max')) > 0) tools.max.value = String(st.max = Number(query.get('max')));
    if (st.dead) return;
    this.redraw();
    this.keepRefreshing();
    this.listCandidates().catch((e) => { this.status.textContent = `Cannot list jobs to compare with: ${e.message}`; });
    if (query.get('compare')) tools.compare.focus();
    else this.canvas.focus({preventScroll: true});
    debug.viewer.ready = true;
  }

  destroy() {
    this.st.dead = true;
    clearTimeout(this.timer);
    this.view.destroy();
    document.removeEventListener('keydown', this.onKey);
  }
}

export function mountViewer(view, [id], query) {
  const page = new ViewerPage(view, id, query);
  page.start();
  return () => page.destroy();
}
