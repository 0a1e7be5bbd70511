// One job's page (its warnings, every PNG output, downloads, timings per stage, statistics, the
// parameters it ran with, its metrics when it belongs to a comparison, and its log), and what the job list
// (joblist.js) shares with it: the actions on a job, the confirmation dialog, warning markers.
import {ACTIVE, api, debug, el, fmtBytes, fmtMs, fmtNum, fmtTime, paramText, poll, stateBadge, techniques} from './api.js';
import {choiceSection, deviceText} from './budget.js';
import {metricTable, metricsTable} from './comparisons.js';

export {mountJobs} from './joblist.js';

export const backendOf = (j) => j.backend.actual || j.backend.requested;
/** The scene as people know it: the bundled file, or an inline scene's name (its file's). */
export const sceneText = (j) => (j.scene === 'inline' && j.scene_name ? `${j.scene_name} (inline)` : j.scene);

// What the registry declares about output files (GET /api/v1/techniques, typed_outputs): each
// technique's PNG captions, and each technique's primary output and its PNG (the list's thumbnail). An
// unreachable registry leaves the pages working with file names only.
let outputFilesP = null;
export const primaryLabel = (files, technique) => {
  const name = files.primaryName[technique];
  return !name || name === 'ao' ? 'AO' : name;
};
export function outputFiles() {
  if (!outputFilesP) {
    outputFilesP = techniques().then((reg) => {
      const f = {captions: {}, primaryPng: {}, primaryName: {}};
      for (const t of reg.techniques || []) {
        for (const o of t.typed_outputs || []) {
          // Per technique: two techniques may write one file name (bent_normal.png) for
          // quantities they derive differently.
          if (o.png) (f.captions[t.name] ||= {})[o.png] = o.description;
          if (o.primary) {
            f.primaryName[t.name] = o.name;
            if (o.png) f.primaryPng[t.name] = o.png;
          }
        }
      }
      return f;
    }).catch(() => {
      outputFilesP = null;
      return {captions: {}, primaryPng: {}, primaryName: {}};
    });
  }
  return outputFilesP;
}

// A render outside the range its technique guarantees still succeeds, with warnings
// (docs/accuracy.md, "Guaranteed ranges"): the list marks such jobs, the job page lists them.
export function warningMarker(j) {
  const w = j.warnings || [];
  if (!w.length) return null;
  const what = `${w.length} warning${w.length === 1 ? '' : 's'}`;
  return el('span', {className: 'warn-marker', role: 'img', title: w.join('\n'), 'aria-label': what}, ' ⚠');
}

// Parameters the server derived from the scene's size rather than the technique's defaults.
function notesSection(j) {
  if (!j.notes || !j.notes.length) return null;
  return el('section', {className: 'notes', 'aria-labelledby': 'h-notes'},
    el('h2', {id: 'h-notes'}, 'Derived parameters'),
    el('p', {}, 'The scene was made for another technique, so these lengths follow its size instead of the technique\'s defaults:'),
    el('ul', {}, ...j.notes.map((t) => el('li', {className: 'derived'}, t))));
}

function warningsSection(j) {
  const w = j.warnings || [];
  if (!w.length) return null;
  return el('section', {className: 'warnings', 'aria-labelledby': 'h-warnings'},
    el('h2', {id: 'h-warnings'}, 'Warnings'),
    el('p', {}, 'The renderer warned about this job: its output is not guaranteed where a quantity ' +
      'lies outside the technique\'s range (see docs/accuracy.md, Guaranteed ranges).'),
    el('ul', {}, ...w.map((t) => el('li', {className: 'warning'}, t))));
}

export function progressCell(j) {
  const pct = Math.round(j.progress * 100);
  return [el('progress', {max: 1, value: j.progress, 'aria-label': `Progress of job ${j.id}`}),
          el('span', {className: 'pct'}, ` ${pct}%`)];
}

async function act(url, method, after) {
  let ok = true;
  try {
    await api(url, {method});
    alertLine('');
  } catch (e) {
    ok = false;
    alertLine(e.message);
  }
  after(ok);
}

let alertEl = null;
/** The page's alert line (each page makes its own); returns it. */
export function setAlertEl(e) {
  alertEl = e;
  return e;
}
export function alertLine(text) {
  if (alertEl) alertEl.textContent = text;
}

/**
 * A modal question with two buttons; resolves true for `okLabel`, false for "Keep" or Escape.
 * The focus starts on "Keep", so an Enter pressed by habit deletes nothing.
 */
export function confirmDialog(message, okLabel) {
  return new Promise((resolve) => {
    const ok = el('button', {type: 'button', className: 'danger'}, okLabel);
    const keep = el('button', {type: 'button'}, 'Keep');
    const d = el('dialog', {className: 'confirm', 'aria-labelledby': 'confirm-text'},
      el('p', {id: 'confirm-text'}, message), el('p', {className: 'buttons'}, ok, ' ', keep));
    const done = (v) => {
      d.close();
      d.remove();
      resolve(v);
    };
    ok.onclick = () => done(true);
    keep.onclick = () => done(false);
    d.addEventListener('cancel', (ev) => {
      ev.preventDefault();
      done(false);
    });
    document.body.append(d);
    d.showModal();
    keep.focus();
  });
}

/**
 * The actions of a job: Cancel while queued or running; Retry when failed or cancelled (the same
 * job back in the queue); Clone (the submit form filled from its document); Delete when finished
 * and not part of a comparison (those go with their comparison), after a confirmation.
 * after(ok, what) runs when an action is done.
 */
export function jobActions(j, after) {
  const out = [];
  if (ACTIVE.has(j.state)) {
    out.push(el('button', {type: 'button', className: 'small', 'aria-label': `Cancel job ${j.id}`,
                           disabled: j.cancel_requested, onclick: () => act(j.links.cancel, 'POST', (ok) => after(ok, 'cancel'))}, 'Cancel'));
  }
  if (j.state === 'failed' || j.state === 'cancelled') {
    out.push(el('button', {type: 'button', className: 'small', 'aria-label': `Retry job ${j.id}`,
                           onclick: () => act(j.links.retry || `${j.links.self}/retry`, 'POST', (ok) => after(ok, 'retry'))}, 'Retry'));
  }
  out.push(el('a', {className: 'button small', href: `#/submit?clone=${j.id}`, 'aria-label': `Clone job ${j.id} into the submit form`}, 'Clone'));
  if (!ACTIVE.has(j.state) && !j.comparison_id) {
    out.push(el('button', {type: 'button', className: 'small', 'aria-label': `Delete job ${j.id}`, onclick: async () => {
      if (await confirmDialog(`Delete job ${j.id} and its outputs? This cannot be undone.`, 'Delete')) {
        act(j.links.self, 'DELETE', (ok) => after(ok, 'delete'));
      }
    }}, 'Delete'));
  }
  return out;
}

// ---- one job ------------------------------------------------------------------------------------

// Captions of the comparison's own images; every technique's come from its declared outputs.
const COMPARISON_CAPTIONS = {
  'error.png': 'Error against the reference: blue = too dark, white = equal, red = too bright (scale ±0.25)',
};

function outputsSection(j, files) {
  const outs = j.outputs || [];
  const CAPTIONS = {...(files.captions[j.technique] || {}), ...COMPARISON_CAPTIONS};
  const pngs = outs.filter((o) => o.name.endsWith('.png'));
  return el('section', {'aria-labelledby': 'h-outputs'},
    el('h2', {id: 'h-outputs'}, 'Outputs'),
    pngs.length ? el('div', {className: 'gallery'}, ...pngs.map((o) => el('figure', {},
      // A click opens the viewer (viewer.js) on the EXR output this PNG shows.
      el('a', {href: `#/view/${j.id}?png=${encodeURIComponent(o.name)}`, className: 'to-viewer', 'aria-label': `View ${o.name} at full resolution`},
        el('img', {className: 'output', src: o.url, alt: CAPTIONS[o.name] || o.name, 'data-name': o.name})),
      el('figcaption', {}, el('strong', {}, o.name), ' ', CAPTIONS[o.name] || ''))))
      : el('p', {className: 'muted'}, ACTIVE.has(j.state) ? 'Outputs appear when the job has succeeded.' : 'No outputs.'),
    j.state === 'succeeded' && pngs.length ? el('p', {}, el('a', {href: `#/view/${j.id}?compare=1`, className: 'button small'}, 'Compare with…'),
      ' a job of the same size, in the viewer (or click an image: zoom, pixel values, exposure).') : null,
    outs.length ? el('ul', {className: 'downloads', 'aria-label': 'Downloads'}, ...outs.map((o) => el('li', {},
      el('a', {href: o.url, download: `job${j.id}-${o.name}`}, o.name), ` ${o.content_type}, ${fmtBytes(o.size)}`))) : null);
}

function timingsSection(t, device) {
  const rows = [];
  for (const k of ['load', 'build', 'render', 'write', 'total']) if (t[k] !== undefined) rows.push([k, t[k], false]);
  for (const [k, v] of Object.entries(t.stages || {})) rows.push([k, v, true]);
  return el('section', {'aria-labelledby': 'h-timings'},
    el('h2', {id: 'h-timings'}, 'Timings'),
    device ? el('p', {className: 'device'}, `Measured on ${deviceText(device)}; the stages sum to the total.`) : null,
    el('table', {className: 'kv timings'},
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, 'Stage'), el('th', {scope: 'col'}, 'ms'))),
      el('tbody', {}, ...rows.map(([k, v, sub]) => el('tr', {className: sub ? 'sub' : ''},
        el('th', {scope: 'row'}, sub ? `${k} (stage)` : k), el('td', {className: 'num'}, fmtMs(v)))))));
}

// What the render built for the technique, with its memory (summary.json built): one row per
// structure, the columns any of them has.
const BUILT_COLUMNS = [['object', 'object'], ['triangles', 'triangles'], ['spheres', 'spheres'], ['dims', 'voxels'],
  ['occupied', 'occupied'], ['iterations', 'iterations'], ['peak_bytes', 'peak memory']];
function builtSection(built) {
  const cols = BUILT_COLUMNS.filter(([k]) => built.some((b) => b[k] !== undefined));
  const text = (k, v) => (v === undefined ? '' : Array.isArray(v) ? v.join(' × ') : k.endsWith('bytes') ? fmtBytes(v) : String(v));
  const total = built.reduce((a, b) => a + (Number.isFinite(b.bytes) ? b.bytes : 0), 0);
  return el('section', {'aria-labelledby': 'h-built'},
    el('h2', {id: 'h-built'}, `Built (${fmtBytes(total)})`),
    el('table', {className: 'kv built'},
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, 'structure'), ...cols.map(([, h]) => el('th', {scope: 'col'}, h)),
        el('th', {scope: 'col'}, 'memory'))),
      el('tbody', {}, ...built.map((b) => el('tr', {}, el('th', {scope: 'row'}, String(b.name)),
        ...cols.map(([k]) => el('td', {className: 'num'}, text(k, b[k]))),
        el('td', {className: 'num'}, Number.isFinite(b.bytes) ? fmtBytes(b.bytes) : ''))))));
}

// The figures of each frame of a scene with moving objects, as the technique reported them
// (summary.json frames): one row per frame, one column per figure any frame has.
const FRAME_LABELS = {bvh_ms: 'BVH ms', update_ms: 'update ms', patches_updated: 'patches updated', full_ms: 'full ms',
  speedup: 'speed-up', rmse_vs_full: 'RMSE vs full', max_abs_vs_full: 'max |Δ| vs full', patches_differing: 'patches differing'};
function framesSection(frames) {
  const keys = [...new Set(frames.flatMap((f) => Object.keys(f)))].filter((k) => k !== 'frame');
  const cell = (k, v) => {
    if (typeof v !== 'number') return '';
    if (k.endsWith('_ms')) return fmtMs(v);
    if (k === 'speedup') return `${fmtNum(v, 3)}×`;
    return Number.isInteger(v) ? String(v) : fmtNum(v, 4);
  };
  return el('section', {'aria-labelledby': 'h-frames'},
    el('h2', {id: 'h-frames'}, `Frames (${frames.length})`),
    el('table', {className: 'kv frames'},
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, 'frame'), ...keys.map((k) => el('th', {scope: 'col'}, FRAME_LABELS[k] || k)))),
      el('tbody', {}, ...frames.map((f) => el('tr', {}, el('th', {scope: 'row'}, String(f.frame)),
        ...keys.map((k) => el('td', {className: 'num'}, cell(k, f[k]))))))));
}

// The registry's entry of a technique (its needs and cost rule), null when unknown.
async function techniqueOf(name) {
  try {
    return (await techniques()).techniques.find((t) => t.name === name) || null;
  } catch {
    return null;
  }
}

/** Where a render ran: the device as the server labels it (budget.js), else the CPU threads one render used. */
function ranOn(summary, machine, device) {
  if (device) return deviceText(device);
  if (summary.backend === 'vulkan') return `vulkan (device ${(machine && machine.vulkan_device) || 'unknown'})`;
  return `${summary.backend}, ${summary.threads} thread${summary.threads === 1 ? '' : 's'}`;
}

/**
 * The work per pixel sample a render did: the technique's cost rule evaluated by the renderer
 * (summary.json's work_per_pixel_sample), else a product rule ("directions x steps") evaluated
 * here, else a phrase (a rule is never shown as if it were a number).
 */
function workPerPixel(cost, summary) {
  const params = summary.params || {};
  const names = cost.split(/\s*x\s*/);
  const vals = names.map((n) => params[n]);
  if (names.length > 1 && vals.every((v) => typeof v === 'number')) {
    return `${vals.join(' × ')} = ${vals.reduce((a, b) => a * b, 1)}`;
  }
  if (typeof summary.work_per_pixel_sample === 'number') return String(Number(summary.work_per_pixel_sample.toPrecision(4)));
  return vals.length === 1 && typeof vals[0] === 'number' ? String(vals[0]) : 'not reported by this render';
}

/** What a pixel sample's `samples` are, from the parameter's description ("paths per pixel sample …"). */
function samplesUnit(technique) {
  const d = technique && technique.params_schema && technique.params_schema.properties &&
    technique.params_schema.properties.samples && technique.params_schema.properties.samples.description;
  const m = /^(.*?) per pixel sample/.exec(d || '');
  return m ? m[1] : null;
}

/**
 * The image line: size and pixel samples (image.spp, the points of each pixel rendered), and, for
 * a technique whose `samples` are per pixel sample (paths, rays), what that makes per pixel.
 */
function imageText(j, technique, params) {
  const spp = j.image.spp;
  const base = `${j.image.width}×${j.image.height}, ${spp} pixel sample${spp === 1 ? '' : 's'} (image.spp)`;
  const unit = samplesUnit(technique);
  const n = params && params.samples;
  return unit && typeof n === 'number' ? `${base} × ${n} ${unit} = ${spp * n} ${unit} per pixel` : base;
}

function statsSection(j, technique) {
  const s = j.stats || {};
  // Techniques that trace rays count them; the others' work per pixel sample is the registry's
  // cost rule, shown evaluated when the summary arrives (a G-buffer technique's is depth-buffer
  // samples).
  const traces = !technique || (technique.needs || []).includes('bvh');
  // A product of parameters reads as a label ("(directions × steps)"); a longer rule is the
  // value's tooltip only.
  const product = /^[a-z_]+( x [a-z_]+)*$/.test((technique && technique.cost) || '');
  const work = traces ? ['rays traced', j.rays]
    : [((technique.needs || []).includes('gbuffer') ? 'depth-buffer samples per pixel' : 'work per pixel sample') +
       (product ? ` (${technique.cost.replace(/ x /g, ' × ')})` : ''),
       el('span', {className: 'work-per-pixel', 'data-cost': technique.cost,
                   title: `the technique's cost rule: ${technique.cost.replace(/ x /g, ' × ')}`}, '…')];
  const rows = [work, ['AO mean', s.ao && fmtNum(s.ao.mean)], ['AO min', s.ao && fmtNum(s.ao.min)],
                ['AO max', s.ao && fmtNum(s.ao.max)], ['AO standard error (mean)', s.ao_stderr_mean !== undefined ? fmtNum(s.ao_stderr_mean) : null],
                ['non-finite values', s.nan_count]].filter(([, v]) => v !== null && v !== undefined);
  return el('section', {'aria-labelledby': 'h-stats'},
    el('h2', {id: 'h-stats'}, 'Statistics'),
    el('table', {className: 'kv'}, el('tbody', {}, ...rows.map(([k, v]) => el('tr', {},
      el('th', {scope: 'row'}, k), el('td', {className: 'num'}, typeof v === 'object' ? v : String(v)))))));
}

export function mountJob(view, [id], query) {
  const head = el('div');
  const body = el('div');
  view.append(el('p', {className: 'crumbs'}, el('a', {href: '#/jobs'}, '← all jobs')),
              el('h1', {}, `Job ${id}`), setAlertEl(el('p', {role: 'alert', className: 'error'})), head, body);
  let lastState = null, summaryDone = false, metricsDone = false, dead = false;
  // The image line's technique and params, once the summary arrived (the facts are redrawn on
  // every poll).
  let imageOf = null;
  // Only a comparison id, never a path: it is put into an API URL.
  const comparisonId = /^\d+$/.test(query.get('comparison') || '') ? query.get('comparison') : null;

  const refresh = async () => {
    let j;
    try {
      j = await api(`/api/v1/jobs/${id}`);
    } catch (e) {
      if (dead) return false;
      head.replaceChildren(el('p', {className: 'error'}, e.message));
      return false;
    }
    if (dead) return false;
    // The facts are rebuilt every poll: put the keyboard focus back on the same control.
    const focused = head.contains(document.activeElement) ? document.activeElement.getAttribute('aria-label') : null;
    debug.job = {id: j.id, state: j.state, progress: j.progress};
    head.replaceChildren(
      el('dl', {className: 'facts'},
        el('dt', {}, 'State'), el('dd', {className: 'job-state', 'aria-live': 'polite'}, stateBadge(j.state),
          j.cancel_requested && ACTIVE.has(j.state) ? ' (cancel requested)' : ''),
        el('dt', {}, 'Progress'), el('dd', {}, progressCell(j)),
        el('dt', {}, 'Scene'), el('dd', {}, sceneText(j)),
        el('dt', {}, 'Label'), el('dd', {}, j.label || '–'),
        el('dt', {}, 'Technique'), el('dd', {}, j.technique),
        el('dt', {}, 'Backend'), el('dd', {}, `${j.backend.requested}${j.backend.actual ? ` → ran on ${j.backend.actual}` : ''}`),
        el('dt', {}, 'Image'), el('dd', {className: 'image-text'}, imageOf ? imageText(j, imageOf.t, imageOf.params) : imageText(j, null, null)),
        el('dt', {}, 'Priority'), el('dd', {}, String(j.priority)),
        el('dt', {}, 'Attempts'), el('dd', {}, String(j.attempts)),
        // The daemon (node) that ran the last attempt: on a shared store, any node's dashboard
        // shows jobs that others rendered.
        el('dt', {}, 'Node'), el('dd', {className: 'job-node'}, j.node || '–'),
        el('dt', {}, 'Created'), el('dd', {}, fmtTime(j.created_at)),
        el('dt', {}, 'Started'), el('dd', {}, fmtTime(j.started_at)),
        el('dt', {}, 'Finished'), el('dd', {}, fmtTime(j.finished_at)),
        j.error ? el('dt', {}, 'Error') : null, j.error ? el('dd', {className: 'error'}, j.error) : null),
      el('p', {className: 'actions'}, jobActions(j, (ok, what) => {
        // A deleted job has no page any more: back to the list.
        if (ok && what === 'delete') location.hash = '#/jobs';
        else handle.wake();
      })));
    if (focused) {
      const again = [...head.querySelectorAll('[aria-label]')].find((e) => e.getAttribute('aria-label') === focused);
      if (again) again.focus();
    }
    if (j.state !== lastState) {
      lastState = j.state;
      // Sections a job does not have yet are left out (replaceChildren would print a null).
      body.replaceChildren(...[choiceSection(j), notesSection(j), warningsSection(j), outputsSection(j, await outputFiles()),
        j.timings_ms ? timingsSection(j.timings_ms, j.device) : null,
        Array.isArray(j.frames) && j.frames.length ? framesSection(j.frames) : null,
        Array.isArray(j.built) && j.built.length ? builtSection(j.built) : null,
        j.stats ? statsSection(j, await techniqueOf(j.technique)) : null,
        el('div', {className: 'params-slot'}), el('div', {className: 'metrics-slot'}),
        el('section', {className: 'log-slot', 'aria-labelledby': 'h-log'}, el('h2', {id: 'h-log'}, 'Log'),
          el('pre', {className: 'job-log', tabIndex: 0, 'aria-label': `Log of job ${j.id}`}, '…'))].filter(Boolean));
      summaryDone = metricsDone = false;
    }
    // The log grows while the job is queued or running: read it on every poll until it ends.
    const logPre = body.querySelector('pre.job-log');
    api(j.links.log || `${j.links.self}/log`).then((l) => {
      if (dead || !logPre.isConnected) return;
      const text = l.lines.length ? l.lines.join('\n') : 'No log lines (a job submitted before logs were kept).';
      if (logPre.textContent !== text) logPre.textContent = text;
    }).catch((e) => { logPre.textContent = `Cannot read the log: ${e.message}`; });
    const summary = j.links.outputs['summary.json'];
    if (summary && !summaryDone) {
      summaryDone = true;
      api(summary).then((s) => {
        body.querySelector('.params-slot').replaceChildren(el('section', {'aria-labelledby': 'h-params'},
          el('h2', {id: 'h-params'}, 'Parameters'),
          el('p', {}, `${s.technique} on ${ranOn(s, j.machine, j.device)}: `, el('code', {}, paramText(s.params)))));
        const work = body.querySelector('.work-per-pixel');
        if (work) work.textContent = workPerPixel(work.dataset.cost, s);
        techniqueOf(j.technique).then((t) => {
          imageOf = {t, params: s.params};
          const img = head.querySelector('.image-text');
          if (img && !dead) img.textContent = imageText(j, t, s.params);
        });
      }).catch(() => {});
    }
    const cid = comparisonId || j.comparison_id || (j.comparison && j.comparison.id);
    if (cid && !metricsDone && !ACTIVE.has(j.state)) {
      metricsDone = true;
      showMetrics(body.querySelector('.metrics-slot'), cid, j.id);
    }
    if (!ACTIVE.has(j.state)) handle.stop();
    return ACTIVE.has(j.state);
  };
  const handle = poll(refresh, {fast: 1000, slow: 4000});
  return () => {
    dead = true;
    handle.stop();
  };
}

async function showMetrics(slot, cid, jobId) {
  let c;
  try {
    [c] = await Promise.all([api(`/api/v1/comparisons/${cid}`), metricTable()]);
  } catch {
    return;
  }
  const cand = c.candidates.find((x) => x.job_id === jobId);
  const ref = c.references.find((x) => x.job_id === jobId);
  const back = el('a', {href: `#/comparisons/${cid}`}, `comparison ${cid}${c.label ? ` (${c.label})` : ''}`);
  if (cand) {
    slot.replaceChildren(el('section', {'aria-labelledby': 'h-metrics'},
      el('h2', {id: 'h-metrics'}, 'Metrics against the reference'),
      el('p', {}, `Candidate ${cand.index} of `, back, `; reference job `,
        el('a', {href: `#/jobs/${cand.reference_job_id}?comparison=${cid}`}, String(cand.reference_job_id)), '.'),
      cand.metrics ? metricsTable(cand)
        : el('p', {className: cand.error ? 'error' : 'muted'}, cand.error ? `No metrics: ${cand.error}` : 'No metrics yet.')));
  } else if (ref) {
    slot.replaceChildren(el('section', {'aria-labelledby': 'h-metrics'},
      el('h2', {id: 'h-metrics'}, 'Comparison'), el('p', {}, 'Reference job of ', back, '.')));
  }
}
