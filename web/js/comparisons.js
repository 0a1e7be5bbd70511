// The comparison pages: the list of comparisons, and one comparison: a table sortable by any
// column, the Pareto chart (chart.js), the selected candidate against its reference (a slider
// over two stacked images) with its error heatmap, an image grid of every candidate, and the CSV.
import {ACTIVE, ApiError, api, debug, el, fmtMs, fmtNum, fmtTime, paramText, poll, stateBadge, techniques, token} from './api.js';
import {PALETTE, SHAPE_GLYPH, SHAPES, errorName, paretoChart, plottable, shapeOf, spreadOf} from './chart.js';
import {answerCell, budgetPanel, deviceLabels, deviceText} from './budget.js';

// The image of a candidate's or reference's primary output ("image"), or "ao.png" from a daemon
// that predates typed outputs.
const primaryImage = (links) => links.image || links['ao.png'];

// The technique of a reference; a daemon that predates reference techniques only had rt_ao.
const refTechnique = (r) => r.technique || 'rt_ao';
// A reference's id and label (the server makes both from what defines the reference; a daemon
// that predates them gets its job and technique).
const refId = (r) => r.id || `job ${r.job_id}`;
const refLabel = (r) => r.label || refTechnique(r);

// ---- the list -----------------------------------------------------------------------------------

export function mountComparisons(view) {
  const tbody = el('tbody');
  const status = el('p', {role: 'status', className: 'muted'}, 'loading…');
  view.append(el('h1', {}, 'Comparisons'),
    el('p', {}, 'Each comparison renders one scene with a grid of techniques, backends and parameters and measures ' +
      'every candidate against a converged reference: rt_ao for the AO techniques, path_trace (many paths per pixel) ' +
      'for path_trace, whose radiance is compared on its luminance and per channel. ', el('a', {href: '#/submit?mode=comparison'}, 'Start one.')),
    status,
    el('table', {},
      el('caption', {className: 'sr-only'}, 'Comparisons, newest first'),
      el('thead', {}, el('tr', {}, ...['Comparison', 'Label', 'Scene', 'State', 'Candidates done', 'Created', 'Answer']
        .map((h) => el('th', {scope: 'col'}, h)))),
      tbody));
  const handle = poll(async () => {
    let list;
    try {
      list = await api('/api/v1/comparisons?limit=100');
    } catch (e) {
      status.textContent = e.status === 404 ? 'This server has no comparisons API.' : e.message;
      return false;
    }
    status.textContent = `${list.comparisons.length} comparison${list.comparisons.length === 1 ? '' : 's'}`;
    tbody.replaceChildren(...list.comparisons.map((c) => el('tr', {},
      el('td', {}, el('a', {href: `#/comparisons/${c.id}`}, `Comparison ${c.id}`)),
      el('td', {}, c.label || '–'), el('td', {}, c.scene), el('td', {}, stateBadge(c.state)),
      el('td', {}, el('progress', {max: c.candidates || 1, value: c.done, 'aria-label': `Candidates done in comparison ${c.id}`}),
        ` ${c.done} / ${c.candidates}`),
      el('td', {}, fmtTime(c.created_at)), answerCell(c))));
    return list.comparisons.some((c) => c.state === 'running');
  }, {fast: 1000, slow: 5000});
  return () => handle.stop();
}

// ---- shared pieces ------------------------------------------------------------------------------

// ---- the metric table (GET /api/v1/metrics): every metric column and row is built from it -----

let METRICS = null; // the table once loaded
let metricsLoad = null;
/** The metric table, fetched once (callers await it before drawing metrics). */
export function metricTable() {
  if (!metricsLoad) metricsLoad = api('/api/v1/metrics').then((r) => (METRICS = r.metrics)).catch(() => (METRICS = []));
  return metricsLoad;
}
/** Metric m's value in a candidate's metrics document: at its group, key and array index. */
const metricValue = (metrics, m) => {
  const o = m.json_group ? metrics && metrics[m.json_group] : metrics;
  const v = o ? o[m.json_key] : undefined;
  return m.json_index >= 0 ? (v ? v[m.json_index] : undefined) : v;
};
const BETTER = {lower: 'lower is better', higher: 'higher is better', zero: 'closer to 0 is better'};
const metricTitle = (m) => `${m.definition}${BETTER[m.direction] ? ` (${BETTER[m.direction]})` : ''}`;

/** The table's columns of metrics some candidate has, in the table's order: the reference's noise
 * (information, not a quality) and figures equal to another (same_as) left out; a metric's array
 * entries (RMSE R, G, B) share one column. */
function metricColumns(cands) {
  const cols = [];
  for (const m of METRICS || []) {
    if (m.direction === 'none' || m.same_as || m.json_index > 0) continue;
    if (!cands.some((c) => metricValue(c.metrics, m) !== undefined)) continue;
    if (m.json_index === 0) {
      const parts = METRICS.filter((x) => x.json_group === m.json_group && x.json_key === m.json_key);
      cols.push({key: m.name, label: [m.label, ...parts.slice(1).map((x) => x.label.split(' ').pop())].join(' / '),
        title: metricTitle(m), num: true, nowrap: true,
        get: (c) => (c.metrics && c.metrics[m.json_group] ? c.metrics[m.json_group][m.json_key] : null),
        sortValue: (v) => v.reduce((a, x) => a + (x ?? Infinity), 0),
        fmt: (v) => (v ? v.map((x) => fmtNum(x, m.digits)).join(' / ') : '–')});
    } else {
      cols.push({key: m.name, label: m.unit ? `${m.label} ${m.unit}` : m.label, title: metricTitle(m), num: true,
        get: (c) => metricValue(c.metrics, m) ?? null, fmt: (v) => fmtNum(v, m.digits)});
    }
  }
  return cols;
}

/** Metrics and timings of one candidate as a two-column table (also used by the job page, after
 * metricTable()). */
export function metricsTable(c) {
  const m = c.metrics || {};
  const med = (c.timings_ms && c.timings_ms.median) || {};
  const runs = (c.timings_ms && c.timings_ms.runs) || [];
  const rows = [
    ...(METRICS || []).filter((x) => metricValue(m, x) !== undefined)
      .map((x) => [x.unit ? `${x.label} (${x.unit})` : x.label, fmtNum(metricValue(m, x), x.digits)]),
    ['at reference accuracy', m.at_reference_accuracy ? 'yes (RMSE below 2 × reference noise)' : 'no'],
    ['Pareto-optimal', c.pareto ? 'yes' : 'no'],
    ['median total ms', fmtMs(med.total)], ['total ms, fastest to slowest run', spreadText(c)], ['median build ms', fmtMs(med.build)], ['median render ms', fmtMs(med.render)],
    ['median post ms', fmtMs(med.post)], ['timed runs', String(runs.length)],
  ];
  // Metrics of a primary output that is not AO: which one.
  if (m.output) rows.unshift(['output compared', m.output + (m.rgb ? ' (luminance)' : '')]);
  if (c.machine) rows.push(['machine', [c.machine.cpu_model, c.machine.cores && `${c.machine.cores} cores`, c.machine.vulkan_device].filter(Boolean).join(', ')]);
  return el('table', {className: 'kv metrics'}, el('tbody', {}, ...rows.map(([k, v]) => el('tr', {},
    el('th', {scope: 'row'}, k), el('td', {className: 'num'}, v)))));
}

/** An other output's figures in words: the mean angle for directions, else RMSE, bias and SSIM. */
const measureText = (m) => (m.angle_deg !== undefined ? `mean angle ${fmtNum(m.angle_deg)}°`
  : `RMSE ${fmtNum(m.rmse)}, bias ${fmtNum(m.bias)}, SSIM ${fmtNum(m.ssim)}`);

/** "min–max" of a candidate's total time over its timed runs (the run-to-run spread). */
export function spreadText(c) {
  const sp = spreadOf(c);
  return sp ? `${fmtMs(sp[0])}–${fmtMs(sp[1])}` : '–';
}

/** Parameters that differ between candidates of the same technique (the rest is noise here). */
function varyingParams(cands) {
  const byTech = new Map();
  for (const c of cands) {
    if (!byTech.has(c.technique)) byTech.set(c.technique, new Map());
    const m = byTech.get(c.technique);
    for (const [k, v] of Object.entries(c.params || {})) {
      if (!m.has(k)) m.set(k, new Set());
      m.get(k).add(JSON.stringify(v));
    }
  }
  return (c) => {
    const m = byTech.get(c.technique);
    const out = {};
    for (const [k, v] of Object.entries(c.params || {})) if (m.get(k).size > 1) out[k] = v;
    return paramText(out) || '(defaults)';
  };
}

const COLUMNS = [
  {key: 'index', label: '#', get: (c) => c.index, num: true},
  {key: 'technique', label: 'Technique', get: (c) => c.technique},
  {key: 'backend', label: 'Backend', get: (c) => c.backend},
  {key: 'device', label: 'Timed on', get: (c) => (c.device ? deviceText(c.device) : null)},
  {key: 'params', label: 'Parameters', get: (c, ctx) => ctx.params(c)},
  {key: 'state', label: 'State', get: (c) => c.state},
  {key: 'total', label: 'Median ms', get: (c) => c.timings_ms && c.timings_ms.median ? c.timings_ms.median.total : null, num: true, fmt: fmtMs},
  {key: 'spread', label: 'Spread ms (min–max)', get: (c) => spreadOf(c), num: true, nowrap: true,
   sortValue: (v) => v[1] - v[0], fmt: (v) => (v ? `${fmtMs(v[0])}–${fmtMs(v[1])}` : '–')},
  {key: 'render', label: 'Render ms', get: (c) => c.timings_ms && c.timings_ms.median ? c.timings_ms.median.render : null, num: true, fmt: fmtMs},
  // What the row's figures are measured against: the reference's id (the References list and the
  // cell's title give its label).
  {key: 'reference', label: 'Reference', get: (c) => (c.reference ? c.reference.id : null), cellTitle: (c) => c.reference && c.reference.label},
  {key: 'pareto', label: 'Pareto', get: (c) => (c.pareto ? 1 : 0), num: true, fmt: (v) => (v ? '★ yes' : 'no')},
  // With a common reference: every candidate's error on that one scale.
  {key: 'common_rmse', label: 'RMSE vs common', common: true, get: (c) => c.common && c.common.metrics && c.common.metrics.rmse, num: true, fmt: fmtNum},
  {key: 'common_pareto', label: 'Pareto (common)', common: true, get: (c) => (c.common ? (c.common.pareto ? 1 : 0) : null), num: true,
   fmt: (v) => (v === null ? '–' : v ? '★ yes' : 'no')},
  {key: 'at_ref', label: 'At ref. accuracy', get: (c) => (c.metrics ? (c.metrics.at_reference_accuracy ? 1 : 0) : null), num: true,
   fmt: (v) => (v === null ? '–' : v ? '≈ yes' : 'no')},
];

/** The table's columns: the metric table's (those the candidates have) after the render time; the common ones with a common reference. */
const columnsFor = (cands) => {
  const at = COLUMNS.findIndex((c) => c.key === 'render') + 1;
  return [...COLUMNS.slice(0, at), ...metricColumns(cands), ...COLUMNS.slice(at)]
    .filter((c) => !c.common || cands.some((x) => x.common));
};

/** Downloads url through fetch when a token is needed (a plain link cannot send the header). */
function csvLink(url, name) {
  const a = el('a', {href: url, download: name, className: 'button'}, 'Download CSV');
  const problem = el('span', {role: 'alert', className: 'error'});
  a.addEventListener('click', async (ev) => {
    if (!token) return;
    ev.preventDefault();
    problem.textContent = '';
    try {
      // Through api() for its error handling (a 401 shows the token box); the body is CSV text.
      const text = await api(url, {raw: true});
      const tmp = el('a', {href: URL.createObjectURL(new Blob([text], {type: 'text/csv'})), download: name});
      tmp.click();
      setTimeout(() => URL.revokeObjectURL(tmp.href), 10000);
    } catch (e) {
      problem.textContent = ` CSV download failed: ${e.message}`;
    }
  });
  return el('span', {}, a, problem);
}

// ---- one comparison -----------------------------------------------------------------------------

// The image viewer (viewer.js) on a job's EXR, B the job to compare with (bfile: which of its EXR
// outputs, given as the viewer's "<job>/<file>" spec); Close comes back here.
const viewerHref = (a, b, bfile) => `#/view/${a}?${b ? `b=${encodeURIComponent(bfile ? `${b}/${bfile}` : String(b))}&mode=split&` : ''}` +
  `back=${encodeURIComponent(location.hash)}`;
// A candidate against its reference as the metrics compared them: the mapped reference the
// server wrote beside the candidate when its response changes the reference, else the reference.
const againstHref = (c) => (c.links && c.links['reference_mapped.exr'] ? viewerHref(c.job_id, c.job_id, 'reference_mapped.exr')
  : viewerHref(c.job_id, c.reference_job_id));

// The page's route: the selected candidate and the error scale, so a reload keeps both.
const routeOf = ({id, s}) => `#/comparisons/${id}?` +
  [s.selected !== null && `candidate=${s.selected}`, s.scale === 'common' && 'scale=common'].filter(Boolean).join('&');

function select(pg, index, scroll = true) {
  const {s, id, tbody, detail} = pg;
  s.selected = index;
  history.replaceState(null, '', routeOf(pg));
  if (s.chart) s.chart.select(index);
  for (const tr of tbody.rows) if (tr.dataset.index !== undefined) tr.setAttribute('aria-selected', String(Number(tr.dataset.index) === index));
  renderSelected(pg);
  debug.comparison.selected = index;
  if (scroll) detail.scrollIntoView({block: 'nearest'});
}

function renderFacts(pg) {
  const {s, id, facts} = pg;
  const c = s.c;
  const done = c.candidates.filter((x) => !ACTIVE.has(x.state)).length;
  facts.replaceChildren(
    el('dl', {className: 'facts'},
      el('dt', {}, 'State'), el('dd', {className: 'cmp-state', 'aria-live': 'polite'}, stateBadge(c.state)),
      el('dt', {}, 'Label'), el('dd', {}, c.label || '–'),
      el('dt', {}, 'Scene'), el('dd', {}, c.scene),
      el('dt', {}, 'Image'), el('dd', {}, c.image ? `${c.image.width}×${c.image.height}` : '–'),
      el('dt', {}, 'Timed runs per candidate'), el('dd', {}, String(c.repeats)),
      el('dt', {}, 'Candidates finished'), el('dd', {},
        el('progress', {max: c.candidates.length || 1, value: done, 'aria-label': 'Candidates finished'}), ` ${done} / ${c.candidates.length}`),
      el('dt', {}, 'References'), el('dd', {}, el('ul', {className: 'references'}, ...c.references.map((r) => el('li', {'data-ref': refId(r)},
        el('strong', {}, refId(r)), ': ', el('span', {className: 'ref-label'}, refLabel(r)),
        r.roles && r.roles.includes('common') ? el('em', {}, ' (the common reference)') : '', ' — ',
        el('a', {href: `#/jobs/${r.job_id}?comparison=${id}`}, `job ${r.job_id}`),
        ` (${r.state}, ${paramText({samples: r.params && r.params.samples})})`)))),
      el('dt', {}, 'Error measure'), el('dd', {className: 'error-measure'}, errorName(c.candidates)),
      el('dt', {}, 'Timed on'), el('dd', {className: 'devices'}, deviceLabels(c.candidates).join('; ') || '–'),
      el('dt', {}, 'Created'), el('dd', {}, fmtTime(c.created_at)),
      ...(c.notes && c.notes.length ? [el('dt', {}, 'Derived from the scene\'s size'),
        el('dd', {className: 'notes'}, ...c.notes.map((n) => el('p', {className: 'derived'}, n)))] : [])),
    el('p', {}, csvLink(c.links.csv, `comparison-${id}.csv`)));
}

function renderTable(pg) {
  const {s, thead, tbody} = pg;
  const ctx = {params: varyingParams(s.c.candidates)};
  const cols = columnsFor(s.c.candidates);
  if (!cols.some((c) => c.key === s.sort.key)) s.sort = {key: 'index', dir: 1};
  const {key, dir} = s.sort;
  const col = cols.find((c) => c.key === key);
  const rows = [...s.c.candidates].sort((a, b) => {
    const va = col.get(a, ctx), vb = col.get(b, ctx);
    if (va === null || va === undefined) return vb === null || vb === undefined ? a.index - b.index : 1;
    if (vb === null || vb === undefined) return -1;
    const d = col.sortValue ? col.sortValue(va) - col.sortValue(vb) : col.num ? va - vb : String(va).localeCompare(String(vb));
    return d ? d * dir : a.index - b.index;
  });
  thead.replaceChildren(el('tr', {}, ...cols.map((c) => el('th', {scope: 'col', title: c.title || '', 'aria-sort': c.key === key ? (dir > 0 ? 'ascending' : 'descending') : 'none'},
    el('button', {type: 'button', className: 'sort', onclick: () => {
      s.sort = {key: c.key, dir: s.sort.key === c.key ? -s.sort.dir : 1};
      renderTable(pg);
      thead.querySelector(`button[data-key="${c.key}"]`).focus();
    }, 'data-key': c.key}, c.label, el('span', {'aria-hidden': 'true', className: 'arrow'}, c.key === key ? (dir > 0 ? ' ▲' : ' ▼') : ''))))));
  const focusedIndex = tbody.contains(document.activeElement) ? document.activeElement.closest('tr').dataset.index : null;
  tbody.replaceChildren(...rows.map((c) => {
    const tr = el('tr', {'data-index': c.index, 'aria-selected': String(c.index === s.selected), className: c.pareto ? 'pareto' : ''},
      ...cols.map((col, k) => {
        const v = col.get(c, ctx);
        if (k === 0) {
          return el('td', {className: 'num'}, el('button', {type: 'button', className: 'small pick', 'aria-label': `Show candidate ${c.index}`,
            onclick: () => select(pg, c.index)}, String(c.index)));
        }
        if (col.key === 'state') return el('td', {}, stateBadge(v));
        return el('td', {className: [col.num && 'num', col.nowrap && 'nowrap', col.key].filter(Boolean).join(' '),
                         ...(col.cellTitle && col.cellTitle(c) ? {title: col.cellTitle(c)} : {})}, col.fmt ? col.fmt(v) : String(v ?? '–'));
      }));
    tr.addEventListener('click', (ev) => {
      if (!ev.target.closest('button, a')) select(pg, c.index);
    });
    // The candidate's other outputs, each against its own reference, in rows under it.
    return [tr, ...(c.outputs || []).map((o) => el('tr', {className: 'output-row', 'data-of': c.index},
      el('td', {colSpan: cols.length}, `↳ candidate ${c.index}'s ${o.output} against ${o.reference.id} (${o.reference_output}): `,
        o.metrics ? measureText(o.metrics) : (o.error ? `no metrics: ${o.error}` : 'no metrics yet'))))];
  }).flat());
  if (focusedIndex !== null) {
    const b = tbody.querySelector(`tr[data-index="${focusedIndex}"] button`);
    if (b) b.focus();
  }
}

function renderRanking(pg) {
  const {s, rankNote} = pg;
  const common = s.scale === 'common' && s.c.common;
  const r = common ? s.c.common.ranking : s.c.ranking;
  rankNote.replaceChildren(...(r && r.warning
    ? [el('p', {className: 'warnings noisy-reference', role: 'note'}, el('strong', {}, 'Reference too noisy to rank: '),
      r.warning.replace(/the reference is too noisy to rank the candidates: /g, ''), '.')]
    : []),
  // Candidates of different references on one axis: say that their errors do not compare.
  ...(!common && s.c.comparable === false
    ? [el('p', {className: 'warnings not-comparable', role: 'note'}, el('strong', {}, 'Errors measured against different references are not comparable: '),
      `the candidates are measured against ${s.c.groups.length} references (${s.c.groups.map((g) => g.reference).join(', ')}, listed above); ` +
      'each reference\'s candidates have their own marker colour and Pareto front and are ranked among themselves only' +
      (s.c.common ? '. Choose the common reference above the chart to rank all of them on one scale.' : '. A common reference ranks all of them on one scale.'))]
    : []));
}

// The scale the chart and the ranking use: each candidate's own reference, or, when the
// comparison has one, the common reference every candidate was also measured against.
function renderScale(pg) {
  const {s, scaleBox} = pg;
  if (!s.c.common) {
    scaleBox.replaceChildren();
    return;
  }
  const choice = (value, text) => el('label', {}, el('input', {type: 'radio', name: 'scale', value, checked: s.scale === value,
    onchange: () => {
      s.scale = value;
      history.replaceState(null, '', routeOf(pg));
      renderRanking(pg);
      renderChart(pg);
    }}), ` ${text}`);
  scaleBox.replaceChildren(el('fieldset', {className: 'scale'}, el('legend', {}, 'Errors against'),
    choice('own', 'each candidate\'s own reference'),
    choice('common', `the common reference ${s.c.common.reference.id} (${s.c.common.reference.label})`)));
}

/** The candidates as the chart plots them on the chosen scale. */
function onScale(s) {
  if (s.scale !== 'common' || !s.c.common) return s.c.candidates;
  return s.c.candidates.map((c) => ({...c, metrics: c.common && c.common.metrics, pareto: Boolean(c.common && c.common.pareto),
                                    reference: c.common && c.common.reference}));
}

function renderChart(pg) {
  const {s, chartBox, chartNote, colourOf} = pg;
  // A live update redraws the chart: keep the keyboard on the point it was on.
  const focused = s.chart && s.chart.hasFocus() ? Number(document.activeElement.dataset.index) : null;
  if (s.chart) s.chart.destroy();
  chartBox.replaceChildren();
  const ctx = {params: varyingParams(s.c.candidates)};
  const cands = onScale(s);
  const ranking = s.scale === 'common' && s.c.common ? s.c.common.ranking : s.c.ranking;
  const noise = ranking ? ranking.ref_noise : null;
  const labelOf = (rid) => {
    const r = s.c.references.find((x) => x.id === rid);
    return r ? refLabel(r) : rid;
  };
  s.chart = paretoChart(chartBox, cands, {colourOf, onSelect: (i) => select(pg, i), selected: s.selected, noise, labelOf, budget: s.budget,
    nameOf: (c) => {
      const varying = ctx.params(c);
      return `Candidate ${c.index}: ${c.technique} on ${c.backend}${varying === '(defaults)' ? '' : `, ${varying}`}`;
    }});
  if (s.chart && focused !== null) s.chart.focus(focused);
  const info = s.chart ? s.chart.info : {points: 0, series: [], pareto: 0};
  debug.comparison.chart = info;
  debug.comparison.uplot = s.chart ? s.chart.uplot : null;
  const withMetrics = cands.filter(plottable);
  const times = withMetrics.map((c) => c.timings_ms.median.total), errs = withMetrics.map((c) => c.metrics.rmse);
  chartBox.setAttribute('aria-label', info.points
    ? `Scatter chart, log scales: ${info.points} candidates, median time ${fmtMs(Math.min(...times))} to ${fmtMs(Math.max(...times))} ms, ` +
      `${errorName(withMetrics)} ${fmtNum(Math.min(...errs), 3)} to ${fmtNum(Math.max(...errs), 3)}; ` +
      `series: ${info.series.map((x) => `${x.label} (${x.points})`).join(', ')}; Pareto-optimal candidates: ${s.c.pareto.join(', ') || 'none yet'}.`
    : 'Chart: no candidate has metrics yet.');
  debug.comparison.scale = s.scale;
  chartNote.textContent = info.points < s.c.candidates.length
    ? `${info.points} of ${s.c.candidates.length} candidates plotted; the others have no metrics or no finite time and RMSE` +
      `${s.c.state === 'running' ? ' yet' : ''}.` : '';
}

// The budget input with its readout (budget.js), once per page; each refresh re-reads the answer.
// The shape legend says which device each backend's times came from.
function renderBudget(pg) {
  const {s, id} = pg;
  pg.deviceKey.textContent = `times measured on: ${deviceLabels(s.c.candidates).join('; ') || 'no timed run yet'}`;
  if (!pg.budget) {
    s.budget = Number.isFinite(s.c.answer && s.c.answer.budget_ms) ? s.c.answer.budget_ms : null;
    pg.budget = budgetPanel(id, s.budget, (ms) => {
      s.budget = ms;
      if (s.chart) s.chart.setBudget(ms);
      debug.comparison.budget = ms;
    });
    pg.budgetSlot.replaceChildren(pg.budget.node);
  }
  pg.budget.refresh();
}

function renderGrid(pg) {
  const {s, grid} = pg;
  const ctx = {params: varyingParams(s.c.candidates)};
  grid.replaceChildren(
    ...s.c.references.filter((r) => r.links && primaryImage(r.links)).map((r) => el('figure', {className: 'tile ref'},
      el('a', {href: viewerHref(r.job_id), 'aria-label': `View reference job ${r.job_id} at full resolution`},
        el('img', {src: primaryImage(r.links), alt: `Reference job ${r.job_id}`})),
      el('figcaption', {}, `Reference ${refId(r)}: ${refLabel(r)} (job ${r.job_id}, ${paramText({samples: r.params && r.params.samples})})`))),
    ...s.c.candidates.map((c) => el('figure', {className: 'tile'},
      c.links && primaryImage(c.links)
        ? el('img', {src: primaryImage(c.links), alt: `Candidate ${c.index}: ${c.technique} on ${c.backend}`, onclick: () => select(pg, c.index)})
        : el('div', {className: 'placeholder'}, c.state),
      el('figcaption', {}, el('button', {type: 'button', className: 'link', onclick: () => select(pg, c.index)},
        `#${c.index} ${c.technique}/${c.backend}`), ` ${ctx.params(c)}`, c.metrics ? ` · RMSE ${fmtNum(c.metrics.rmse, 3)}` : ''))));
}

function renderSelected(pg) {
  const {s, id, detail} = pg;
  const c = s.c && s.c.candidates.find((x) => x.index === s.selected);
  if (!c) {
    detail.replaceChildren();
    return;
  }
  const links = c.links || {};
  const parts = [el('h2', {id: 'h-selected'}, `Candidate ${c.index}: ${c.technique} on ${c.backend}`),
    el('p', {}, el('code', {}, paramText(c.params)), ' · ', stateBadge(c.state), ' · ',
      el('a', {href: `#/jobs/${c.job_id}?comparison=${id}`, className: 'open-job'}, `Open job ${c.job_id}`), ' · ',
      el('a', {href: againstHref(c), className: 'open-viewer'}, 'View candidate (A) against reference (B)'))];
  const media = el('div', {className: 'media'});
  if (primaryImage(links) && links['reference.png']) {
    // The reference as the metrics saw it: mapped through the candidate's response when that
    // changes it (the server writes that image), else as rendered.
    const mapped = links['reference_mapped.png'];
    const refWhat = mapped ? `the reference mapped through the ${c.response} response, as the metrics compared it`
      : 'the reference as rendered';
    const ref = el('img', {className: 'ref', src: mapped || links['reference.png'],
                           alt: `Reference job ${c.reference_job_id}${mapped ? ` mapped through ${c.response}` : ''}`});
    const cand = el('img', {className: 'cand', src: primaryImage(links), alt: `Candidate ${c.index}`});
    const line = el('div', {className: 'divider', 'aria-hidden': 'true'});
    const range = el('input', {type: 'range', id: 'split', min: '0', max: '100', step: '1', value: String(s.split)});
    const apply = () => {
      const v = Number(range.value);
      s.split = v;
      // CSSOM properties, which the CSP (no inline styles) allows.
      cand.style.clipPath = `inset(0 ${100 - v}% 0 0)`;
      line.style.left = `${v}%`;
      range.setAttribute('aria-valuetext', `${v}% candidate on the left, ${100 - v}% reference on the right`);
    };
    range.addEventListener('input', apply);
    apply();
    media.append(el('figure', {className: 'compare'},
      el('div', {className: 'stack', title: 'Click to open the viewer', onclick: () => { location.hash = againstHref(c); }}, ref, cand, line),
      el('label', {for: 'split'}, 'Split between candidate (left) and reference (right)'), range,
      el('figcaption', {className: 'compared'}, `Left of the line: the candidate; right: ${refWhat}. Arrow keys move the split.`)));
  }
  if (links['error.png']) {
    media.append(el('figure', {className: 'heatmap'},
      el('img', {className: 'error', src: links['error.png'], alt: `Error heatmap of candidate ${c.index} against its reference`}),
      el('div', {className: 'ramp', 'aria-hidden': 'true'}),
      el('div', {className: 'ramp-labels'}, el('span', {}, '−0.25 blue: too dark'), el('span', {}, '0 white'), el('span', {}, '+0.25 red: too bright')),
      el('figcaption', {}, `Signed error candidate − reference${c.metrics && c.metrics.rgb ? ` (of ${c.metrics.output} luminance)` : ''}, ` +
        'saturating at ±0.25; grey: no geometry in the reference; green: NaN. ',
        links['error.exr'] ? el('a', {href: links['error.exr'], download: `candidate${c.index}-error.exr`}, 'error.exr') : '')));
  }
  parts.push(media, c.metrics ? metricsTable(c)
    : el('p', {className: c.error ? 'error' : 'muted'}, c.error ? `No metrics: ${c.error}` : 'No metrics yet.'));
  // Live updates rebuild the panel: keep the keyboard on the slider if it was there.
  const hadFocus = document.activeElement && document.activeElement.id === 'split';
  detail.replaceChildren(el('section', {'aria-labelledby': 'h-selected', className: 'selected'}, ...parts));
  if (hadFocus && document.getElementById('split')) document.getElementById('split').focus();
}

// The page's sections, into pg: facts, the chart with its legend and notes, the candidate table,
// the selected candidate's panel and the grid of images.
function comparisonLayout(pg, view) {
  pg.facts = el('div');
  // A group of focusable points (chart.js), named by its text summary.
  pg.chartBox = el('div', {className: 'chart', role: 'group'});
  pg.rankNote = el('div', {className: 'rank-note'});
  pg.scaleBox = el('div', {className: 'scale-box'});
  pg.chartNote = el('p', {className: 'muted'});
  pg.budgetSlot = el('div', {className: 'budget-slot'});
  pg.thead = el('thead');
  pg.tbody = el('tbody');
  pg.detail = el('div', {className: 'selected-slot'});
  pg.grid = el('div', {className: 'grid'});
  const {facts, chartBox, rankNote, scaleBox, chartNote, thead, tbody, detail, grid} = pg;
  view.append(
    el('p', {className: 'crumbs'}, el('a', {href: '#/comparisons'}, '← all comparisons')),
    el('h1', {}, `Comparison ${pg.id}`), facts,
    el('section', {'aria-labelledby': 'h-chart'},
      el('h2', {id: 'h-chart'}, 'Time against error'),
      el('p', {className: 'hint'}, 'Each point is a candidate: colour and legend name the technique (the reference it is measured against, when the ' +
        'candidates have several), the shape the backend. ' +
        'Hover a point for its name; click it (or Tab to the chart\'s points, move with ← → and press Enter) to show that ' +
        'candidate below. A bar through a point spans its fastest to slowest timed run; the dotted line is the reference\'s noise. ' +
        'The table holds the same data.'),
      scaleBox, rankNote, pg.budgetSlot, chartBox, el('ul', {className: 'shape-legend', 'aria-label': 'Marker shapes'},
        ...Object.entries(SHAPES).map(([b, sh]) => el('li', {}, el('span', {'aria-hidden': 'true'}, SHAPE_GLYPH[sh]), ` ${sh}: ${b}`)),
        el('li', {}, el('span', {'aria-hidden': 'true'}, SHAPE_GLYPH.triangle), ' triangle: any other backend'),
        pg.deviceKey = el('li', {className: 'device-key'}),
        el('li', {}, el('span', {'aria-hidden': 'true'}, '╌'), ' dashed step line: the Pareto front (nothing is both faster and more accurate)'),
        el('li', {}, el('span', {'aria-hidden': 'true'}, '◯'), ' ring: the selected candidate; larger markers: Pareto-optimal'),
        el('li', {}, el('span', {'aria-hidden': 'true'}, '├─┤'), ' bar: fastest to slowest timed run'),
        el('li', {className: 'noise-key'}, el('span', {'aria-hidden': 'true'}, '┈'),
          ' dotted line: the reference\'s noise (shaded below twice it: at reference accuracy)')),
      chartNote),
    el('section', {'aria-labelledby': 'h-table'},
      el('h2', {id: 'h-table'}, 'Candidates'),
      el('div', {className: 'scroll'}, el('table', {className: 'candidates'},
        el('caption', {className: 'sr-only'}, 'Candidates; column headers sort the table'), thead, tbody))),
    detail,
    el('section', {'aria-labelledby': 'h-grid'}, el('h2', {id: 'h-grid'}, 'All images'), grid));
}

export function mountComparison(view, [id], query) {
  const s = {
    c: null, fingerprint: '', sort: {key: 'index', dir: 1}, split: 50, scale: query.get('scale') === 'common' ? 'common' : 'own',
    selected: query.has('candidate') ? Number(query.get('candidate')) : null, chart: null, colours: new Map(),
  };
  const pg = {s, id};
  comparisonLayout(pg, view);
  const {facts, chartBox} = pg;

  // Arrow keys on a point select the next or previous one in time order and move the focus there.
  chartBox.addEventListener('keydown', (ev) => {
    if (!s.chart || !['ArrowLeft', 'ArrowRight'].includes(ev.key)) return;
    ev.preventDefault();
    const next = s.chart.step(ev.key === 'ArrowRight' ? 1 : -1);
    select(pg, next, false);
    s.chart.focus(next);
  });

  pg.colourOf = (t) => {
    if (!s.colours.has(t)) s.colours.set(t, PALETTE[s.colours.size % PALETTE.length]);
    return s.colours.get(t);
  };
  // Colours follow the registry's order, so a technique keeps its colour across comparisons.
  const ready = Promise.all([metricTable(),
    techniques().then(({techniques: ts}) => ts.forEach((t) => pg.colourOf(t.name))).catch(() => {})]);

  debug.comparison = {id: Number(id), selected: s.selected, chart: null, state: null};
  let dead = false; // set when the page goes: a late answer must not draw (or make a chart)
  const refresh = async () => {
    let c;
    try {
      c = await api(`/api/v1/comparisons/${id}`);
    } catch (e) {
      if (dead) return false;
      facts.replaceChildren(el('p', {className: 'error'}, e instanceof ApiError && e.status === 404
        ? `No comparison ${id} (or this server has no comparisons API).` : e.message));
      return false;
    }
    await ready;
    if (dead) return false;
    s.c = c;
    debug.comparison.state = c.state;
    const fp = JSON.stringify([c.state, c.ranking, c.common, c.candidates.map((x) => [x.state, x.metrics, x.pareto, x.timings_ms, x.links, x.common, x.outputs]),
                               c.references.map((r) => [r.state, r.links])]);
    if (fp !== s.fingerprint) {
      renderFacts(pg);
      renderScale(pg);
      renderBudget(pg);
      renderRanking(pg);
      renderTable(pg);
      renderChart(pg);
      renderGrid(pg);
      renderSelected(pg);
      s.fingerprint = fp; // only once drawn: a render that threw is retried at the next poll
      debug.comparison.rendered = c.candidates.length;
    }
    if (c.state !== 'running') handle.stop();
    return c.state === 'running';
  };
  const observer = new ResizeObserver(() => s.chart && s.chart.resize(chartBox.clientWidth));
  observer.observe(chartBox);
  const handle = poll(refresh, {fast: 1000, slow: 4000});
  return () => {
    dead = true;
    handle.stop();
    observer.disconnect();
    if (s.chart) s.chart.destroy();
  };
}
