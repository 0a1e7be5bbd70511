// The image viewer page (#/view/ID): a job's EXR decoded in the browser and shown at full
// resolution on a canvas (zoom, pan), a readout of every channel's float value at a pixel, an
// exposure control for radiance, and A/B against a second job of the same size (toggle or split
// wipe) with the values of both and their difference. The route's query keeps what is shown:
// b (the second job), output, view, mode, exposure, back (the page Close returns to).
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
async function loadJob(id) {
  const [job, reg] = await Promise.all([api(`/api/v1/jobs/${id}`), techniques().catch(() => ({techniques: []}))]);
  if (job.state !== 'succeeded') throw new Error(`job ${id} is ${job.state}: only a finished job has images`);
  const tech = reg.techniques.find((t) => t.name === job.technique) || {};
  const exrs = (job.outputs || []).filter((o) => o.name.endsWith('.exr'));
  const file = exrs.find((o) => o.name === tech.exr) || exrs[0];
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

export function mountViewer(view, [id], query) {
  const back = SAFE_BACK.test(query.get('back') || '') ? query.get('back') : `#/jobs/${id}`;
  const status = el('p', {role: 'alert', className: 'error'});
  const note = el('p', {className: 'muted viewer-note'}, `Loading the EXR of job ${id}…`);
  const canvas = el('canvas', {className: 'viewer-canvas', tabindex: '0', role: 'img',
    'aria-label': `Job ${id} at full resolution. Keys: + and − zoom, F fits, 1 shows actual size, arrows pan, ` +
      'P pins the centre pixel and Shift+arrows move it, B flips A and B, S splits, Escape closes.'});
  const readout = el('div', {className: 'readout-box', 'aria-live': 'polite'});
  const close = el('a', {href: back, className: 'button small'}, '✕ Close');
  const title = el('h1', {}, `Job ${id}: viewer`);
  const on = {
    output: () => { chooseOutput(tools.output.value); redraw(); },
    view: () => { st.view = tools.view.value; redraw(); },
    exposure: () => { st.stops = Number(tools.exposure.value); redraw(); },
    compare: () => setB(tools.compare.value ? Number(tools.compare.value) : null),
    mode: () => setMode(tools.mode.value),
    split: () => v.setSplit(Number(tools.split.value) / 100),
    flip: () => v.flip(), zoom: (f) => v.zoomBy(f), fit: () => v.fit(), one: () => v.oneToOne(),
  };
  const tools = toolbar(on);
  view.append(el('p', {className: 'crumbs'}, close, ' ', el('a', {href: `#/jobs/${id}`}, `job ${id}`)), title, status,
    tools.bar, note, el('div', {className: 'viewer-main'}, canvas, el('section', {className: 'readout-panel', 'aria-label': 'Pixel values'}, readout)));
  const v = createView(canvas, {pixel: (p, click) => onPixel(p, click), change: () => onChange()});
  const st = {a: null, b: null, output: null, view: null, stops: 0, hover: null, pin: null, dead: false, rows: []};
  debug.viewer = {ready: false, view: v.state, st};
  const page = {view: v, close: () => { location.hash = back; }, flip: () => { v.flip(); }, setMode, movePin, pinCentre};
  const onKey = keyHandler(page);
  document.addEventListener('keydown', onKey);

  function onPixel(p, click) {
    if (click) st.pin = p && st.pin && p.x === st.pin.x && p.y === st.pin.y ? null : p;
    else st.hover = p;
    showReadout();
  }
  function showReadout() {
    if (!st.a) return;
    const p = st.pin || st.hover;
    st.rows = renderReadout(readout, st.a, st.b, p, !!st.pin && p === st.pin);
    debug.viewer.readout = p ? {x: p.x, y: p.y, pinned: p === st.pin, rows: st.rows} : null;
  }
  function movePin(dx, dy) {
    if (!st.a) return;
    const p = st.pin || st.hover || {x: 0, y: 0};
    st.pin = {x: Math.min(st.a.img.width - 1, Math.max(0, p.x + dx)), y: Math.min(st.a.img.height - 1, Math.max(0, p.y + dy))};
    showReadout();
  }
  function pinCentre() {
    const p = v.pixelAt(canvas.width / 2, canvas.height / 2);
    st.pin = st.pin ? null : p;
    showReadout();
  }
  function onChange() {
    const s = v.state;
    tools.zoomText.textContent = `${s.zoom >= 1 ? Math.round(s.zoom * 100) : (s.zoom * 100).toPrecision(2)} %${s.fitted ? ' (fit)' : ''}` +
      (st.b ? ` · showing ${s.mode === 'split' ? `${s.showing} left, ${s.showing === 'A' ? 'B' : 'A'} right` : s.showing}` : '');
    tools.split.value = String(Math.round(s.split * 100));
    debug.viewer.draws = (debug.viewer.draws || 0) + 1;
  }
  function setMode(m) {
    tools.mode.value = m;
    v.setMode(m);
    tools.splitWrap.hidden = m !== 'split';
    keepUrl();
  }

  // The route's query follows the choices, so a view can be linked (replaceState: no new route).
  function keepUrl() {
    const q = new URLSearchParams();
    if (st.b) q.set('b', String(st.b.id));
    if (st.output) q.set('output', st.output.name);
    if (st.view) q.set('view', st.view);
    if (st.b) q.set('mode', v.state.mode);
    if (st.stops) q.set('exposure', String(st.stops));
    if (query.get('back')) q.set('back', back);
    history.replaceState(null, '', `#/view/${id}${q.size ? `?${q}` : ''}`);
  }

  /** B's output for A's: the same name when B has it, else B's primary, else its first. */
  const outputOfB = () => st.b && (st.b.outputs.find((o) => o.name === st.output.name) ||
    st.b.outputs.find((o) => o.primary) || st.b.outputs[0]);

  function redraw() {
    const views = viewsOf(st.output);
    const bOut = outputOfB();
    const bView = bOut && (viewsOf(bOut).includes(st.view) ? st.view : viewsOf(bOut)[0]);
    tools.exposureWrap.hidden = st.view !== 'tonemap' && bView !== 'tonemap';
    tools.exposureText.textContent = `${st.stops > 0 ? '+' : ''}${st.stops} EV`;
    v.setImages(toCanvas(displayBytes(st.a.img, st.output, views.includes(st.view) ? st.view : views[0], st.stops)),
                st.b ? toCanvas(displayBytes(st.b.img, bOut, bView, st.stops)) : null);
    tools.abWrap.hidden = !st.b;
    note.textContent = `${st.a.job.technique} on ${st.a.job.backend.actual}, ${st.a.img.width}×${st.a.img.height}, ` +
      `${st.a.file.name} (${st.a.img.compression}, ${st.a.img.channels.length} channels)` +
      (st.b ? `; B: job ${st.b.id}, ${st.b.job.technique} on ${st.b.job.backend.actual}, output ${bOut.name}` : '') + '.';
    showReadout();
    keepUrl();
    Object.assign(debug.viewer, {a: st.a, b: st.b, output: st.output.name, mode: st.view, stops: st.stops});
  }

  function chooseOutput(name) {
    st.output = st.a.outputs.find((o) => o.name === name) || st.a.outputs.find((o) => o.primary) || st.a.outputs[0];
    const views = viewsOf(st.output);
    if (!views.includes(st.view)) st.view = views[0];
    tools.view.replaceChildren(...views.map((x) => el('option', {value: x, selected: x === st.view}, VIEW_NAMES[x])));
  }

  async function setB(bid) {
    tools.compare.value = bid ? String(bid) : '';
    if (!bid) {
      st.b = null;
      redraw();
      return;
    }
    status.textContent = '';
    try {
      const b = await loadJob(bid);
      if (st.dead) return;
      if (b.img.width !== st.a.img.width || b.img.height !== st.a.img.height) {
        throw new Error(`job ${bid} is ${b.img.width}×${b.img.height}, job ${id} ${st.a.img.width}×${st.a.img.height}: A/B needs the same size`);
      }
      st.b = b;
    } catch (e) {
      st.b = null;
      tools.compare.value = '';
      status.textContent = `Cannot compare with job ${bid}: ${e.message}`;
    }
    redraw();
  }

  (async () => {
    try {
      st.a = await loadJob(id);
    } catch (e) {
      if (st.dead) return;
      note.textContent = '';
      status.textContent = `Cannot show job ${id}: ${e.message}`;
      debug.viewer.error = e.message;
      return;
    }
    if (st.dead) return;
    title.textContent = `Job ${id}: ${st.a.job.technique} at full resolution`;
    const png = query.get('png');
    chooseOutput(query.get('output') || (st.a.outputs.find((o) => o.png && o.png === png) || {}).name);
    if (query.get('view')) {
      st.view = viewsOf(st.output).includes(query.get('view')) ? query.get('view') : st.view;
      tools.view.value = st.view;
    }
    tools.output.replaceChildren(...st.a.outputs.map((o) => el('option', {value: o.name, selected: o === st.output},
      `${o.name} (${o.channels.join(', ')})`)));
    // The slider starts at the exposure the PNG was made with, so the first view is the PNG.
    const param = st.a.outputs.find((o) => o.exposure_param);
    const made = param && st.a.summary ? Number(st.a.summary.params[param.exposure_param]) || 0 : 0;
    st.stops = query.has('exposure') ? Number(query.get('exposure')) || 0 : made;
    tools.exposure.value = String(st.stops);
    setMode(query.get('mode') === 'split' ? 'split' : 'toggle');
    redraw();
    const bid = /^\d+$/.test(query.get('b') || '') ? Number(query.get('b')) : null;
    if (bid) await setB(bid);
    sameSizeJobs(st.a).then((jobs) => {
      if (st.dead) return;
      tools.compare.replaceChildren(el('option', {value: ''}, 'nothing'), ...jobs.map((j) => el('option', {value: String(j.id)},
        `job ${j.id}: ${j.technique} on ${j.backend.actual}${j.label ? ` (${j.label})` : ''}`)));
      tools.compare.value = st.b ? String(st.b.id) : '';
      debug.viewer.candidates = jobs.map((j) => j.id);
    }).catch((e) => { status.textContent = `Cannot list jobs to compare with: ${e.message}`; });
    if (query.get('compare')) tools.compare.focus();
    else canvas.focus({preventScroll: true});
    debug.viewer.ready = true;
  })();

  return () => {
    st.dead = true;
    v.destroy();
    document.removeEventListener('keydown', onKey);
  };
}
