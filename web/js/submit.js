// The submit page: one job (POST /api/v1/jobs) or a comparison (POST /api/v1/comparisons) of a
// bundled or pasted scene. Techniques, backends and every parameter field come from
// GET /api/v1/techniques (params_schema), so a new technique needs no change here. Everything is
// checked before sending; a 4xx's problems are shown next to the fields their JSON pointers name.
import {ApiError, api, el, techniques} from './api.js';
import {budgetFields, readBudget} from './budget.js';
import {prefillClone} from './clone.js';
import {lineColumn, locatePointer} from './jsonpos.js';
import {checkValue, describeRule, parseField, parseToken} from './params.js';

const MAX_CANDIDATES = 256;
let uid = 0;

/** A labelled control with its description and error line, both tied to it by aria-describedby. */
function field(labelText, control, {description, pointer} = {}) {
  const id = control.id || (control.id = `f${++uid}`);
  const desc = description ? el('small', {id: `${id}-desc`, className: 'desc'}, description) : null;
  const err = el('span', {id: `${id}-err`, className: 'field-error'});
  control.setAttribute('aria-describedby', [desc && desc.id, err.id].filter(Boolean).join(' '));
  if (pointer) control.dataset.pointer = pointer;
  control._err = err;
  return el('div', {className: 'field'}, el('label', {for: id}, labelText), control, desc, err);
}

/** A group of checkboxes with a legend; the group's fieldset carries the error line. */
function checkGroup(legend, options, {description, pointer, checked = []} = {}) {
  const id = `g${++uid}`;
  const err = el('span', {id: `${id}-err`, className: 'field-error'});
  const boxes = options.map(({value, label, disabled, note}) => {
    const box = el('input', {type: 'checkbox', id: `${id}-${value}`, value: JSON.stringify(value), disabled,
                             checked: checked.includes(value)});
    return el('span', {className: 'check'}, box, el('label', {for: box.id}, label), note ? el('small', {}, ` ${note}`) : null);
  });
  const fs = el('fieldset', {className: 'checks', id, 'aria-describedby': `${description ? `${id}-desc ` : ''}${err.id}`},
    el('legend', {}, legend), ...boxes, description ? el('small', {id: `${id}-desc`, className: 'desc'}, description) : null, err);
  if (pointer) fs.dataset.pointer = pointer;
  fs._err = err;
  fs.values = () => [...fs.querySelectorAll('input:checked')].map((b) => JSON.parse(b.value));
  return fs;
}

function setError(control, message) {
  if (!control._err) return;
  control._err.textContent = message || '';
  if (message) control.setAttribute('aria-invalid', 'true');
  else control.removeAttribute('aria-invalid');
}

/**
 * The technique part of the form: technique, backend(s) and one field per parameter. In
 * comparison mode backends are checkboxes, enum and boolean parameters checkbox groups, and the
 * other parameters take comma-separated lists. `base` is the JSON pointer of the entry in the
 * request ("/technique" or "/candidates/K").
 */
// The backend control of a block: ticks for a comparison, a select (with auto) for a job.
function backendControl(t, registry, comparison, base) {
  const vkNote = registry.vulkan_available ? null : 'not available on this server';
  if (comparison) {
    return checkGroup('Backends', t.backends.map((b) => ({value: b, label: b, disabled: b === 'vulkan' && !registry.vulkan_available,
                                                         note: b === 'vulkan' ? vkNote : null})),
                      {pointer: `${base}/backend`, checked: ['cpu'].filter((b) => t.backends.includes(b)).concat(t.backends.length === 1 ? t.backends : [])});
  }
  const sel = el('select', {}, el('option', {value: 'auto'}, 'auto (the server picks)'),
    ...t.backends.map((b) => el('option', {value: b, disabled: b === 'vulkan' && !registry.vulkan_available}, b + (b === 'vulkan' && vkNote ? ` (${vkNote})` : ''))));
  return field('Backend', sel, {pointer: `${base}/backend`}).querySelector('select');
}

// One parameter's control (ticks for a comparison's choices, a select for a job's, else text that
// a comparison may fill with a list), remembering the request generation it was last edited in.
function paramEntry(name, schema, comparison, state, onChange) {
  const pointer = `${state.base}/params/${name}`;
  const rule = describeRule(schema);
  const description = `${schema.description || ''}${schema.description ? '. ' : ''}${rule}.`;
  const choices = schema.enum || (JSON.stringify(schema.type) === '"boolean"' ? [true, false] : null);
  let control, node;
  if (choices && comparison) {
    control = checkGroup(name, choices.map((v) => ({value: v, label: String(v)})),
                         {description: `${description} None ticked: the default.`, pointer});
    node = control;
  } else if (choices) {
    control = el('select', {}, el('option', {value: ''}, `default (${JSON.stringify(schema.default)})`),
      ...choices.map((v) => el('option', {value: JSON.stringify(v)}, String(v))));
    node = field(name, control, {description, pointer});
  } else {
    control = el('input', {type: 'text', inputMode: 'decimal', autocomplete: 'off', spellcheck: false,
      placeholder: comparison ? `default ${JSON.stringify(schema.default)}; e.g. 4, 16, 64` : `default ${JSON.stringify(schema.default)}`});
    node = field(name, control, {description: comparison ? `${description} A comma-separated list sweeps the values.` : description, pointer});
  }
  const entry = {name, schema, control, node, choices, touched: -1};
  const edited = () => { entry.touched = state.gen; };
  for (const ev of ['change', 'input']) {
    control.addEventListener(ev, edited);
    control.addEventListener(ev, onChange);
  }
  return entry;
}

/**
 * Shows the params a job of this scene starts from (GET /api/v1/scenes/{name}/defaults) as the
 * block's values, and says where they come from in `origin`; d null clears the note. Fields
 * edited since request `gen` started keep what was typed.
 */
function fillBlock(state, origin, d, gen) {
  if (!d) {
    // No bundled scene (a pasted document): the values a bundled scene filled in go, or they
    // would be sent over the pasted document's own; what was typed since stays.
    for (const p of state.params) {
      if (p.filled !== undefined && p.control.value === p.filled) p.control.value = '';
      p.filled = undefined;
    }
    origin.replaceChildren();
    return;
  }
  for (const p of state.params) {
    if (!(p.name in d.params) || p.touched === gen) continue;
    p.control.value = p.filled = JSON.stringify(d.params[p.name]);
  }
  if (d.backend && state.backendTouched !== gen &&
      [...state.backend.options].some((o) => o.value === d.backend && !o.disabled)) state.backend.value = d.backend;
  const own = d.technique === d.scene_technique;
  origin.replaceChildren(el('p', {}, own
    ? `Values: the parameters ${d.scene} declares for ${d.technique}.`
    : `Values: ${d.technique}'s defaults (${d.scene} declares ${d.scene_technique}); lengths are fitted to the scene's size.`),
  ...d.notes.map((n) => el('p', {className: 'derived'}, n)));
}

/** {value, errors: [[control, message]], count}: a block's entry for the request. */
function readBlock(state, comparison) {
  const errors = [];
  const params = {};
  let count = 1;
  for (const p of state.params) {
    setError(p.control, '');
    let values;
    if (p.choices && comparison) values = p.control.values();
    else if (p.choices) values = p.control.value === '' ? [] : [JSON.parse(p.control.value)];
    else {
      const r = parseField(p.schema, p.control.value, {list: comparison});
      if (r.errors.length) errors.push([p.control, r.errors.join('; ')]);
      values = r.values;
    }
    if (values.length) {
      params[p.name] = comparison && values.length > 1 ? values : values[0];
      count *= values.length;
    }
  }
  setError(state.backend, '');
  const value = {};
  if (comparison) {
    const bs = state.backend.values();
    if (!bs.length) errors.push([state.backend, 'tick at least one backend']);
    count *= Math.max(bs.length, 1);
    Object.assign(value, {technique: state.technique.value, backend: bs.length === 1 ? bs[0] : bs, params});
    if (state.against && state.against.value) value.against = state.against.value;
  } else {
    Object.assign(value, {name: state.technique.value, backend: state.backend.value, params});
  }
  return {value, errors, count};
}

function techniqueBlock(registry, {comparison, legend, base, onRemove, onChange, onTechnique}) {
  const ts = registry.techniques;
  const technique = el('select', {}, ...ts.map((t) => el('option', {value: t.name}, t.name)));
  const fs = el('fieldset', {className: 'technique-block'}, el('legend', {}, legend));
  const desc = el('p', {className: 'desc'});
  const backendSlot = el('div');
  const againstSlot = el('div');
  const paramsSlot = el('div', {className: 'params'});
  // Where the values shown come from (the scene's own params, or defaults fitted to its size).
  const origin = el('div', {className: 'hint defaults-note', 'aria-live': 'polite'});
  const state = {technique, backend: null, params: [], base, gen: 0};
  fs.append(field('Technique', technique, {pointer: `${base}/${comparison ? 'technique' : 'name'}`}), desc, backendSlot, againstSlot, origin, paramsSlot);
  if (onRemove) fs.append(el('button', {type: 'button', className: 'small', onclick: onRemove}, `Remove ${legend.toLowerCase()}`));

  const build = () => {
    const t = ts.find((x) => x.name === technique.value);
    desc.textContent = t.description;
    state.backend = backendControl(t, registry, comparison, state.base);
    backendSlot.replaceChildren(state.backend.closest('.field') || state.backend);
    // The other references the registry says a candidate may be compared with (`against`).
    const alts = comparison ? t.against || [] : [];
    state.against = alts.length ? el('select', {}, el('option', {value: ''}, 'its own reference'),
      ...alts.map((a) => el('option', {value: a.technique},
        `${a.technique}, on its ${a.output}${a.needs_false ? ` (needs ${a.needs_false} false)` : ''}`))) : null;
    againstSlot.replaceChildren(...(state.against ? [field('Compare against', state.against, {pointer: `${state.base}/against`,
      description: 'The reference technique the candidates are judged against (docs/comparisons.md).'})] : []));
    state.params = Object.entries(t.params_schema.properties || {})
      .map(([name, schema]) => paramEntry(name, schema, comparison, state, onChange));
    paramsSlot.replaceChildren(el('p', {className: 'hint'}, comparison ? "Parameters: leave empty for the scene's value (its own technique) or the default, lengths fitted to the scene's size."
      : "Parameters: an empty field takes the scene's own value for its own technique (the bundled file's or the pasted document's), else the default fitted to the scene."),
                               ...state.params.map((p) => p.node));
    state.backend.addEventListener('change', onChange);
    state.backendTouched = -1;
    state.backend.addEventListener('change', () => { state.backendTouched = state.gen; });
    origin.replaceChildren();
    onChange();
    if (onTechnique) onTechnique(state);
  };
  technique.addEventListener('change', build);
  build();
  state.fill = (d, gen) => {
    fillBlock(state, origin, d, gen);
    if (d) onChange();
  };
  state.read = () => readBlock(state, comparison);
  state.node = fs;
  return state;
}

function intField(control, {min, max, required = false}) {
  setError(control, '');
  const t = control.value.trim();
  if (t === '') return required ? (setError(control, 'required'), {bad: true}) : {value: undefined};
  const v = parseToken(t);
  const e = checkValue({type: 'integer', minimum: min, maximum: max}, v);
  if (e) {
    setError(control, e);
    return {bad: true};
  }
  return {value: v};
}

export function mountSubmit(view, _args, query) {
  const form = el('form', {id: 'submit-form', noValidate: true, 'aria-labelledby': 'h-submit'});
  view.append(el('h1', {id: 'h-submit'}, 'Submit'), form);
  form.append(el('p', {className: 'muted'}, 'loading the technique registry…'));
  let alive = true;
  Promise.all([techniques(), api('/api/v1/scenes')]).then(([registry, {scenes}]) => {
    if (alive) build(form, registry, scenes, query);
  }).catch((e) => form.replaceChildren(el('p', {className: 'error', role: 'alert'}, e.message)));
  return () => { alive = false; };
}

const radio = (name, value, label, checked) => {
  const r = el('input', {type: 'radio', name, value, id: `${name}-${value}`, checked});
  return el('span', {className: 'check'}, r, el('label', {for: r.id}, label));
};

// The scene (bundled or pasted), the image size, priority and label: controls into f.
function sceneControls(f, scenes) {
  const {form} = f;
  f.sceneSel = el('select', {}, ...scenes.map((s) => el('option', {value: s.name},
    `${s.name} (${s.technique || 'unreadable'}${s.width ? `, ${s.width}×${s.height}` : ''})`)));
  f.sceneJson = el('textarea', {rows: 8, spellcheck: false, placeholder: '{"camera": {...}, "image": {...}, "objects": [...], "technique": {...}}'});
  f.width = el('input', {type: 'text', inputMode: 'numeric', autocomplete: 'off', placeholder: "the scene's"});
  f.height = el('input', {type: 'text', inputMode: 'numeric', autocomplete: 'off', placeholder: "the scene's"});
  const sceneFields = {bundled: field('Scene file', f.sceneSel, {pointer: '/scene_file'}),
                       paste: field('Scene JSON', f.sceneJson, {description: "A scene document (docs/scene-format.md); meshes must be bundled ones (models/…). Its technique is replaced by the one chosen below; for the same technique its params stay where a field is empty."})};
  f.source = el('fieldset', {className: 'inline'}, el('legend', {}, 'Scene'),
    radio('source', 'bundled', 'A bundled scene', true), radio('source', 'paste', 'Paste a scene document', false));
  f.isPaste = () => form.querySelector('input[name=source]:checked').value === 'paste';
  const sceneBox = el('div');
  f.showSource = () => sceneBox.replaceChildren(f.isPaste() ? sceneFields.paste : sceneFields.bundled);
  f.source.addEventListener('change', f.showSource);
  f.priority = el('input', {type: 'text', inputMode: 'numeric', value: '50', autocomplete: 'off'});
  f.label = el('input', {type: 'text', maxLength: 256, autocomplete: 'off'});
  return el('fieldset', {}, el('legend', {}, 'Scene and image'), f.source, sceneBox,
    el('div', {className: 'row'},
      field('Image width (pixels)', f.width, {pointer: '/image/width', description: "Empty: the scene's own."}),
      field('Image height (pixels)', f.height, {pointer: '/image/height', description: "Empty: the scene's own."}),
      field('Priority', f.priority, {pointer: '/priority', description: 'integer 0 to 100; higher runs first'}),
      field('Label', f.label, {pointer: '/label', description: 'free text, up to 256 characters'})));
}

// A comparison's timed runs and reference samples, with the server's defaults (GET
// /api/v1/techniques), not the rt_ao schema's own default samples, which is a job's and not a
// reference's.
function measurementControls(f) {
  const cmpDefaults = f.registry.comparison_defaults || {};
  f.repeats = el('input', {type: 'text', inputMode: 'numeric', value: String(cmpDefaults.repeats ?? ''), autocomplete: 'off'});
  const rtSamples = f.registry.techniques.find((t) => t.name === 'rt_ao');
  f.refSchema = {...((rtSamples && rtSamples.params_schema.properties.samples) || {type: 'integer', minimum: 1}),
    default: cmpDefaults.reference_samples};
  f.refSamples = el('input', {type: 'text', inputMode: 'numeric', value: String(cmpDefaults.reference_samples ?? ''), autocomplete: 'off'});
  return el('fieldset', {}, el('legend', {}, 'Measurement'), el('div', {className: 'row'},
    field('Timed runs per candidate', f.repeats, {pointer: '/repeats', description: `integer 1 to 20, default ${cmpDefaults.repeats}; the reported time is the median (after one warm-up run)`}),
    field('Reference samples', f.refSamples, {pointer: '/reference/samples', description: "the reference technique's samples " +
      `(rays per pixel sample of rt_ao for the AO techniques, paths per pixel sample of path_trace for path_trace): ${describeRule(f.refSchema)}`})));
}

// The single job's fields show what the chosen bundled scene runs with for the chosen technique.
function loadDefaults(f, b) {
  const gen = ++b.gen;
  if (f.isPaste() || !f.sceneSel.value) {
    b.fill(null, gen);
    return;
  }
  api(`/api/v1/scenes/${encodeURIComponent(f.sceneSel.value)}/defaults?technique=${encodeURIComponent(b.technique.value)}`)
    .then((d) => { if (gen === b.gen) b.fill(d, gen); })
    .catch(() => { if (gen === b.gen) b.fill(null, gen); });
}

// The technique block of a job, or a comparison's candidate blocks with Add / Remove and their
// count; f.showMode redraws them for the chosen mode.
function techniqueControls(f) {
  f.count = el('p', {className: 'count', 'aria-live': 'polite'});
  f.techBox = el('div');
  f.blocks = [];
  f.addBtn = el('button', {type: 'button', className: 'small'}, 'Add candidate');
  const recount = () => {
    if (!f.isComparison()) {
      f.count.textContent = '';
      return;
    }
    const n = f.blocks.reduce((a, b) => a + b.read().count, 0);
    f.count.textContent = `${n} candidate${n === 1 ? '' : 's'} (at most ${MAX_CANDIDATES})`;
  };
  // After a removal the later candidates move up: their legends and the JSON pointers that map
  // the server's problems to fields move with them.
  const renumber = () => f.blocks.forEach((b, k) => {
    b.node.querySelector('legend').textContent = `Candidate ${k + 1}`;
    b.base = `/candidates/${k}`;
    for (const x of b.node.querySelectorAll('[data-pointer]')) {
      x.dataset.pointer = x.dataset.pointer.replace(/^\/candidates\/\d+/, `/candidates/${k}`);
    }
  });
  const addCandidate = () => {
    const k = f.blocks.length;
    const b = techniqueBlock(f.registry, {comparison: true, legend: `Candidate ${k + 1}`, base: `/candidates/${k}`, onChange: recount,
      onRemove: () => {
        f.blocks = f.blocks.filter((x) => x !== b);
        b.node.remove();
        renumber();
        recount();
      }});
    f.blocks.push(b);
    f.techBox.append(b.node);
    recount();
    return b;
  };
  f.addBtn.addEventListener('click', () => addCandidate().technique.focus());
  f.showMode = () => {
    f.techBox.replaceChildren();
    f.blocks = [];
    if (f.isComparison()) {
      addCandidate();
    } else {
      const b = techniqueBlock(f.registry, {comparison: false, legend: 'Technique', base: '/technique', onChange: () => {},
                                            onTechnique: (x) => loadDefaults(f, x)});
      f.blocks.push(b);
      f.techBox.append(b.node);
    }
    f.cmpOptions.hidden = f.addBtn.hidden = !f.isComparison();
    // auto picks technique, backend and parameters itself: only the budget is asked.
    f.budget.node.hidden = !f.isBudget();
    f.techBox.hidden = f.isBudget();
    f.submitBtn.textContent = f.isComparison() ? 'Start comparison' : 'Submit job';
    recount();
  };
}

function build(form, registry, scenes, query) {
  const f = {form, registry};
  const mode = el('fieldset', {className: 'inline'}, el('legend', {}, 'What to submit'),
    radio('mode', 'single', 'One job', query.get('mode') !== 'comparison'),
    radio('mode', 'comparison', 'A comparison (techniques × backends × parameter values against a reference)', query.get('mode') === 'comparison'),
    radio('mode', 'budget', 'One job, technique auto (fastest within a time budget)', query.get('mode') === 'budget'));
  f.isComparison = () => form.querySelector('input[name=mode]:checked').value === 'comparison';
  f.isBudget = () => form.querySelector('input[name=mode]:checked').value === 'budget';
  f.budget = budgetFields();
  const common = sceneControls(f, scenes);
  f.cmpOptions = measurementControls(f);
  f.submitBtn = el('button', {type: 'submit', className: 'primary'}, 'Submit job');
  techniqueControls(f);
  mode.addEventListener('change', f.showMode);
  const refill = () => { if (!f.isComparison() && f.blocks[0]) loadDefaults(f, f.blocks[0]); };
  f.sceneSel.addEventListener('change', refill);
  f.source.addEventListener('change', refill);

  f.clientErrors = el('div', {className: 'problems', role: 'alert'});
  f.serverErrors = el('div', {className: 'problems', role: 'alert'});
  form.replaceChildren(mode, common, f.cmpOptions, f.budget.node, f.techBox, f.addBtn, f.count, f.clientErrors, f.serverErrors,
                       el('p', {}, f.submitBtn));
  f.showSource();
  f.showMode();
  if (/^\d+$/.test(query.get('clone') || '') && !f.isComparison()) {
    prefillClone(query.get('clone'), {form, sceneSel: f.sceneSel, sceneJson: f.sceneJson, width: f.width, height: f.height,
                                      priority: f.priority, label: f.label, block: f.blocks[0], showSource: f.showSource});
  }
  form.addEventListener('submit', (ev) => send(f, ev));
}

// The pasted scene document, or null (with the problem in `errors`) when it is not one.
function pastedScene(f, errors) {
  setError(f.sceneJson, '');
  if (!f.isPaste()) return null;
  try {
    const doc = JSON.parse(f.sceneJson.value);
    if (!doc || typeof doc !== 'object' || Array.isArray(doc)) throw new Error('must be a JSON object');
    return doc;
  } catch (e) {
    // JSON.parse says where ("at position 45"): as a line and column, with the place selected.
    const at = /position (\d+)/.exec(e.message);
    const where = at ? lineColumn(f.sceneJson.value, Number(at[1])) : null;
    const msg = `not a scene document: ${where ? `line ${where.line}, column ${where.column}: ` : ''}${e.message}`;
    errors.push([f.sceneJson, msg]);
    setError(f.sceneJson, msg);
    if (at) f.sceneJson.setSelectionRange(Number(at[1]), Number(at[1]) + 1);
    return null;
  }
}

// A comparison's own fields of the request body.
function readComparison(f, body, entries, doc, errors) {
  const rp = intField(f.repeats, {min: 1, max: 20, required: true});
  if (rp.bad) errors.push([f.repeats, f.repeats._err.textContent]);
  setError(f.refSamples, '');
  const rs = parseField(f.refSchema, f.refSamples.value);
  if (rs.errors.length) {
    setError(f.refSamples, rs.errors.join('; '));
    errors.push([f.refSamples, rs.errors.join('; ')]);
  }
  const n = entries.reduce((a, e) => a + e.count, 0);
  if (!entries.length) errors.push([f.addBtn, 'add at least one candidate']);
  if (n > MAX_CANDIDATES) errors.push([f.blocks[0].technique, `${n} candidates: at most ${MAX_CANDIDATES}`]);
  if (doc) body.scene = doc;
  else if (!f.isPaste()) body.scene_file = f.sceneSel.value;
  body.repeats = rp.value;
  if (rs.given) body.reference = {samples: rs.values[0], backend: 'cpu'};
  body.candidates = entries.map((e) => e.value);
}

/** Everything the form says, checked; {body, errors: [[control, message]]}. */
function readForm(f) {
  const errors = [];
  const body = {};
  const doc = pastedScene(f, errors);
  const set = {};
  for (const [ctl, ptr] of [[f.width, '/image/width'], [f.height, '/image/height']]) {
    const r = intField(ctl, {min: 1, max: 16384});
    if (r.bad) errors.push([ctl, ctl._err.textContent]);
    else if (r.value !== undefined) set[ptr] = r.value;
  }
  const pr = intField(f.priority, {min: 0, max: 100});
  if (pr.bad) errors.push([f.priority, f.priority._err.textContent]);
  else if (pr.value !== undefined) body.priority = pr.value;
  if (f.label.value) body.label = f.label.value;
  if (Object.keys(set).length) body.set = set;
  if (f.isBudget()) {
    setError(f.budget.input, '');
    const r = readBudget(f.budget.input, {...body, ...(f.isPaste() ? {} : {scene_file: f.sceneSel.value})});
    if (r.error) {
      setError(f.budget.input, r.error);
      errors.push([f.budget.input, r.error]);
      return {body, errors};
    }
    return {body: r.body, errors};
  }
  const entries = f.blocks.map((b) => b.read());
  for (const e of entries) {
    for (const [ctl, msg] of e.errors) setError(ctl, msg);
    errors.push(...e.errors);
  }
  if (f.isComparison()) {
    readComparison(f, body, entries, doc, errors);
  } else {
    const technique = entries[0].value;
    // A pasted scene's own params stay for its own technique; the form's are set over them.
    const pt = doc && doc.technique;
    if (pt && pt.name === technique.name && pt.params && typeof pt.params === 'object') {
      technique.params = Object.assign({}, pt.params, technique.params);
    }
    if (doc) Object.assign(body, doc, {technique}, f.form.dataset.sceneName ? {scene_name: f.form.dataset.sceneName} : {});
    else if (!f.isPaste()) Object.assign(body, {scene_file: f.sceneSel.value, technique});
  }
  return {body, errors};
}

// Checks the form and sends it: problems at their fields, or on to the new job's or comparison's page.
async function send(f, ev) {
  ev.preventDefault();
  f.serverErrors.replaceChildren();
  const {body, errors} = readForm(f);
  if (errors.length) {
    f.clientErrors.replaceChildren(el('p', {}, `Not sent: ${errors.length} problem${errors.length === 1 ? '' : 's'} to fix.`),
      el('ul', {}, ...errors.map(([ctl, msg]) => el('li', {}, el('button', {type: 'button', className: 'link', onclick: () => focusControl(ctl)},
        `${nameOf(ctl)}: ${msg}`)))));
    focusControl(errors[0][0]);
    return;
  }
  f.clientErrors.replaceChildren();
  f.submitBtn.disabled = true;
  const comparison = f.isComparison();
  try {
    const r = await api(comparison ? '/api/v1/comparisons' : '/api/v1/jobs', {method: 'POST', json: body});
    location.hash = comparison ? `#/comparisons/${r.id}` : `#/jobs/${r.id}`;
  } catch (e) {
    showServerProblems(f, e, comparison);
  } finally {
    f.submitBtn.disabled = false;
  }
}

function focusControl(ctl) {
  const target = ctl.matches('fieldset') ? ctl.querySelector('input:not([disabled])') || ctl : ctl;
  target.focus();
}

function nameOf(ctl) {
  if (ctl.matches('fieldset')) return ctl.querySelector('legend').textContent;
  const l = ctl.labels && ctl.labels[0];
  const block = ctl.closest('.technique-block');
  return `${block ? `${block.querySelector('legend').textContent} › ` : ''}${l ? l.textContent : ctl.textContent}`;
}

// A problem in a pasted document, at its place in the text: a button that selects the value the
// pointer names (or the nearest part of the document that holds it) in the textarea.
function textPlace(ta, pointer, message) {
  const at = locatePointer(ta.value, pointer);
  if (!at) return null;
  const select = () => {
    ta.focus();
    ta.setSelectionRange(at.start, at.end);
  };
  return {at, message: `line ${at.line}, column ${at.column}: ${pointer}: ${message}`,
          button: el('button', {type: 'button', className: 'link text-place', onclick: select},
            `line ${at.line}, column ${at.column}`), select};
}

/**
 * Shows a refusal; each problem whose JSON pointer falls inside a field is also shown there, and
 * with a pasted document every other problem of the document at its line and column in the text.
 */
function showServerProblems(f, e, comparison) {
  const {form} = f;
  const problems = e instanceof ApiError ? e.problems : [];
  const paste = f.isPaste() ? f.sceneJson : null;
  const places = [];
  const fields = [...form.querySelectorAll('[data-pointer]')];
  const items = problems.map((p) => {
    // "<document>: <pointer>: <rule>": "request" names the request's own keys, anything else
    // (a pasted scene is "inline") the scene document.
    const m = /^([^:]*): (\/[^:]*): (.*)$/.exec(p);
    if (!m) return el('li', {}, el('code', {}, p));
    // Longest field pointer that is the problem's pointer or a prefix of it at a segment boundary.
    let best = null;
    for (const x of fields) {
      const fp = x.dataset.pointer;
      if ((m[2] === fp || m[2].startsWith(`${fp}/`)) && (!best || fp.length > best.dataset.pointer.length)) best = x;
    }
    if (best) setError(best, m[3]);
    const place = !best && paste && m[1] !== 'request' ? textPlace(paste, m[2], m[3]) : null;
    if (place) places.push(place);
    return el('li', {}, place ? place.button : null, place ? ' ' : null, el('code', {}, p));
  });
  f.serverErrors.replaceChildren(el('p', {}, e.status === 404 && comparison
    ? 'This server has no comparisons API (POST /api/v1/comparisons answered 404).'
    : `The server refused it (${e.status || 'no answer'}): ${e.message}`),
  items.length ? el('ul', {}, ...items) : null);
  if (places.length) {
    setError(paste, places.map((x) => x.message).join('; '));
    places[0].select();
  }
}
