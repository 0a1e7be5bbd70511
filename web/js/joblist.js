// The job list page: filters and the page kept in the URL's query, pages beyond the newest 50, the
// jobs of a comparison grouped under one row (each job saying which candidate or reference it is),
// per-row and bulk actions (cancel, retry, clone, delete after a confirmation), live progress, and
// arrow-key navigation between jobs.
import {ACTIVE, api, debug, el, fmtMs, fmtTime, paramText, poll, stateBadge, techniques} from './api.js';
import {alertLine, backendOf, confirmDialog, sceneText, jobActions, outputFiles, primaryLabel, progressCell, setAlertEl,
        warningMarker} from './jobs.js';

const PAGE = 50;
const FILTERS = ['state', 'technique', 'backend'];
const COLUMNS = ['Select', 'Job', 'Scene / label', 'Technique', 'Backend', 'State', 'Progress', 'Created', 'Total ms',
                 'Image', 'Actions'];

// What each comparison says about its jobs ("candidate 3: hbao on cpu, steps=4"), fetched once per
// comparison: a job's role and parameters never change.
const comparisonInfo = new Map();
function loadComparison(cid, wake) {
  if (comparisonInfo.has(cid)) return comparisonInfo.get(cid);
  comparisonInfo.set(cid, null);
  api(`/api/v1/comparisons/${cid}`).then((c) => {
    const roles = new Map();
    for (const r of c.references) roles.set(r.job_id, `reference: ${r.technique} ${paramText(r.params)}`);
    for (const x of c.candidates) roles.set(x.job_id, `candidate ${x.index}: ${x.technique} on ${x.backend}, ${paramText(x.params)}`);
    comparisonInfo.set(cid, {label: c.label, scene: c.scene, roles});
    wake();
  }).catch(() => comparisonInfo.delete(cid));
  return null;
}

/** The URL of the list with these filters and cursor (the hash route's query). */
function listUrl(filters, after) {
  const q = new URLSearchParams();
  for (const k of FILTERS) if (filters[k]) q.set(k, filters[k]);
  if (after) q.set('after', after);
  const s = q.toString();
  return `#/jobs${s ? `?${s}` : ''}`;
}

// The page's state: the filters and cursor of the route, the selection, the rows drawn, and the
// poll handle (every part below reads and changes it).
function pageState(query) {
  return {
    filters: Object.fromEntries(FILTERS.map((k) => [k, query.get(k) || ''])),
    after: /^\d+$/.test(query.get('after') || '') ? query.get('after') : '',
    nextCursor: null,
    selected: new Set(),
    shown: [],
    rows: new Map(),
    // Comparisons whose jobs are shown: a group starts folded (its row says what it holds), so a
    // sweep of dozens of jobs does not push the other jobs off the page.
    expanded: new Set(),
    handle: null,
    ui: {},
  };
}

const remember = (s) => history.replaceState(null, '', listUrl(s.filters, s.after));

// Moves to the page after `cursor` ('' = the newest).
function go(s, cursor) {
  s.after = cursor;
  s.selected.clear();
  remember(s);
  s.handle.wake();
}

/** The filter form: state, technique (from the registry) and backend, kept in the URL. */
function filterForm(s) {
  const onFilter = (k, sel) => () => {
    s.filters[k] = sel.value;
    go(s, '');
  };
  const state = el('select', {id: 'filter-state'}, el('option', {value: ''}, 'any'),
    ...['queued', 'running', 'succeeded', 'failed', 'cancelled'].map((v) => el('option', {value: v}, v)));
  const technique = el('select', {id: 'filter-technique'}, el('option', {value: ''}, 'any'));
  const backend = el('select', {id: 'filter-backend'}, el('option', {value: ''}, 'any'),
    ...['cpu', 'vulkan', 'auto'].map((v) => el('option', {value: v}, v)));
  state.value = s.filters.state;
  backend.value = s.filters.backend;
  state.onchange = onFilter('state', state);
  technique.onchange = onFilter('technique', technique);
  backend.onchange = onFilter('backend', backend);
  if (s.filters.technique) technique.append(el('option', {value: s.filters.technique}, s.filters.technique));
  technique.value = s.filters.technique;
  techniques().then(({techniques: ts}) => {
    technique.replaceChildren(el('option', {value: ''}, 'any'), ...ts.map((t) => el('option', {value: t.name}, t.name)));
    technique.value = s.filters.technique;
  }).catch(() => {});
  return el('form', {className: 'filters', 'aria-label': 'Filter jobs', onsubmit: (e) => e.preventDefault()},
    el('label', {for: 'filter-state'}, 'State'), state,
    el('label', {for: 'filter-technique'}, 'Technique'), technique,
    el('label', {for: 'filter-backend'}, 'Backend'), backend);
}

// The page before this one (newer jobs), by the keyset read upwards: the PAGE jobs just above the
// first one shown, under the same filters. Its cursor is one past the highest of them, or the
// newest page when nothing is above them; so any page, one opened from a URL too, has a way back.
async function newer(s) {
  const top = s.shown.length ? s.shown[0].id : Number(s.after) - 1;
  const q = new URLSearchParams({limit: String(PAGE), order: 'asc', after: String(top)});
  for (const k of FILTERS) if (s.filters[k]) q.set(k, s.filters[k]);
  try {
    const up = await api(`/api/v1/jobs?${q}`);
    go(s, up.next === null || !up.jobs.length ? '' : String(up.jobs[up.jobs.length - 1].id + 1));
  } catch (e) {
    s.ui.status.textContent = e.message;
  }
}

/** The pager and the bulk bar, with the header's select-all box; their elements go to s.ui. */
function listTools(s) {
  const u = s.ui;
  u.newest = el('button', {type: 'button', className: 'small', onclick: () => go(s, '')}, '« Newest');
  u.newer = el('button', {type: 'button', className: 'small', onclick: () => newer(s)}, '‹ Newer');
  u.older = el('button', {type: 'button', className: 'small', onclick: () => go(s, s.nextCursor)}, 'Older ›');
  u.bulkCancel = el('button', {type: 'button', className: 'small', onclick: () => bulk(s, 'cancel')}, 'Cancel selected');
  u.bulkDelete = el('button', {type: 'button', className: 'small', onclick: () => bulk(s, 'delete')}, 'Delete selected');
  u.selectAll = el('input', {type: 'checkbox', 'aria-label': 'Select every job on this page', onchange: () => {
    for (const j of s.shown) if (u.selectAll.checked) s.selected.add(j.id); else s.selected.delete(j.id);
    syncChecks(s);
  }});
  u.bulkBar = el('div', {className: 'bulk', role: 'group', 'aria-label': 'Selected jobs'},
    el('span', {className: 'bulk-count', 'aria-live': 'polite'}), u.bulkCancel, u.bulkDelete);
  u.pager = el('nav', {className: 'pager', 'aria-label': 'Pages of jobs'}, u.newest, u.newer, u.older,
    el('span', {className: 'page-where muted'}));
  return el('div', {className: 'list-tools'}, u.bulkBar, u.pager);
}

// Arrow keys move between the jobs' links, so a long list need not be tabbed through.
function arrowKeys(tbody) {
  tbody.addEventListener('keydown', (ev) => {
    if (!['ArrowDown', 'ArrowUp', 'Home', 'End'].includes(ev.key)) return;
    const links = [...tbody.querySelectorAll('a.job-link')].filter((a) => !a.closest('tr').hidden);
    const i = links.indexOf(document.activeElement);
    if (i < 0) return;
    ev.preventDefault();
    const j = ev.key === 'ArrowDown' ? Math.min(i + 1, links.length - 1) : ev.key === 'ArrowUp' ? Math.max(i - 1, 0)
      : ev.key === 'Home' ? 0 : links.length - 1;
    links[j].focus();
  });
}

function syncChecks(s) {
  const u = s.ui;
  for (const box of u.tbody.querySelectorAll('input.pick')) box.checked = s.selected.has(Number(box.dataset.id));
  const n = s.selected.size;
  u.bulkBar.querySelector('.bulk-count').textContent = n ? `${n} selected` : 'none selected';
  u.bulkCancel.disabled = u.bulkDelete.disabled = n === 0;
  u.selectAll.checked = s.shown.length > 0 && s.shown.every((j) => s.selected.has(j.id));
}

// Cancels or deletes the selected jobs that allow it, naming those skipped and those that failed.
async function bulk(s, what) {
  const jobs = s.shown.filter((j) => s.selected.has(j.id));
  const skipped = [];
  let targets;
  if (what === 'cancel') {
    targets = jobs.filter((j) => ACTIVE.has(j.state));
  } else {
    targets = jobs.filter((j) => !ACTIVE.has(j.state) && !j.comparison_id);
    for (const j of jobs) {
      if (ACTIVE.has(j.state)) skipped.push(`job ${j.id} is ${j.state}`);
      else if (j.comparison_id) skipped.push(`job ${j.id} goes with comparison ${j.comparison_id}`);
    }
  }
  if (!targets.length) {
    alertLine(`Nothing to ${what}${skipped.length ? `: ${skipped.join('; ')}` : ''}.`);
    return;
  }
  const ids = targets.map((j) => j.id).join(', ');
  if (what === 'delete' && !await confirmDialog(`Delete ${targets.length} job${targets.length === 1 ? '' : 's'} (${ids}) and ` +
      'their outputs? This cannot be undone.', 'Delete')) return;
  const failed = [];
  for (const j of targets) {
    try {
      await api(what === 'cancel' ? j.links.cancel : j.links.self, {method: what === 'cancel' ? 'POST' : 'DELETE'});
      s.selected.delete(j.id);
    } catch (e) {
      failed.push(`job ${j.id}: ${e.message}`);
    }
  }
  alertLine([...failed, ...skipped.map((x) => `skipped ${x}`)].join('; '));
  s.handle.wake();
}

async function deleteComparison(s, cid) {
  if (!await confirmDialog(`Delete comparison ${cid} with all its jobs and their outputs? This cannot be undone.`,
                           'Delete comparison')) return;
  try {
    await api(`/api/v1/comparisons/${cid}`, {method: 'DELETE'});
    alertLine('');
    comparisonInfo.delete(cid);
  } catch (e) {
    alertLine(e.message);
  }
  s.handle.wake();
}

// The row heading a comparison's jobs: its link, scene and label, counts, hide/show and delete.
function groupRow(s, cid, members) {
  const info = loadComparison(cid, () => s.handle.wake());
  const active = members.filter((j) => ACTIVE.has(j.state)).length;
  const open = s.expanded.has(cid);
  const toggle = el('button', {type: 'button', className: 'small', 'aria-expanded': String(open),
    'aria-label': `${open ? 'Hide' : 'Show'} the jobs of comparison ${cid}`,
    onclick: () => { if (open) s.expanded.delete(cid); else s.expanded.add(cid); s.handle.wake(); }}, open ? '▾' : '▸');
  const what = info ? `${info.scene}${info.label ? ` — ${info.label}` : ''}` : '';
  return [JSON.stringify([open, active, members.length, what]),
    el('td', {colSpan: COLUMNS.length},
      toggle, ' ', el('a', {className: 'comparison-link', href: `#/comparisons/${cid}`}, `Comparison ${cid}`),
      what ? ` ${what}` : '', el('span', {className: 'muted'}, ` · ${members.length} job${members.length === 1 ? '' : 's'} on this page` +
        (active ? `, ${active} queued or running` : '')), ' ',
      el('button', {type: 'button', className: 'small', disabled: active > 0,
                    title: active ? 'cancel or wait for its jobs first' : '',
                    'aria-label': `Delete comparison ${cid}`, onclick: () => deleteComparison(s, cid)}, 'Delete comparison'))];
}

function jobRow(s, j, files) {
  const thumb = j.links.outputs[files.primaryPng[j.technique] || 'ao.png'];
  const info = j.comparison_id ? loadComparison(j.comparison_id, () => s.handle.wake()) : null;
  const role = info && info.roles.get(j.id);
  const key = JSON.stringify([j.state, j.progress, j.cancel_requested, j.backend, j.timings_ms && j.timings_ms.total,
                              thumb, j.warnings, role]);
  const cell = (label, props, ...kids) => el('td', {...props, 'data-label': label}, ...kids);
  return [key, [
    cell('Select', {className: 'pick-cell'}, el('input', {type: 'checkbox', className: 'pick', 'data-id': j.id,
      'aria-label': `Select job ${j.id}`, checked: s.selected.has(j.id),
      onchange: (ev) => { if (ev.target.checked) s.selected.add(j.id); else s.selected.delete(j.id); syncChecks(s); }})),
    cell('Job', {}, el('a', {className: 'job-link', href: `#/jobs/${j.id}`}, `Job ${j.id}`)),
    cell('Scene / label', {className: 'scene'}, j.comparison_id
      ? el('span', {className: 'role'}, role || `comparison ${j.comparison_id}`)
      : sceneText(j) + (j.label ? ` — ${j.label}` : '')),
    cell('Technique', {}, j.technique),
    cell('Backend', {}, backendOf(j)),
    cell('State', {title: j.error || ''}, stateBadge(j.state), warningMarker(j)),
    cell('Progress', {className: 'progress'}, progressCell(j)),
    cell('Created', {className: 'created'}, fmtTime(j.created_at)),
    cell('Total ms', {className: 'num'}, j.timings_ms ? fmtMs(j.timings_ms.total) : '–'),
    cell('Image', {}, thumb
      ? el('img', {className: 'thumb', src: thumb, alt: `${primaryLabel(files, j.technique)} of job ${j.id}`}) : ''),
    cell('Actions', {className: 'actions'}, jobActions(j, () => s.handle.wake()))]];
}

// One <tr> into place: rebuilt only when what it shows changed (its key), keeping the focus on the
// control of the same name, and moved to follow `prev` (listing order, newest first).
function placeRow(s, k, cls, key, cells, hidden, prev) {
  let tr = s.rows.get(k);
  if (!tr) {
    tr = el('tr', {'data-id': k, className: cls});
    s.rows.set(k, tr);
  }
  tr.hidden = !!hidden;
  if (tr.dataset.key !== key) {
    const focused = tr.contains(document.activeElement) ? document.activeElement.getAttribute('aria-label') ||
      document.activeElement.className : null;
    tr.dataset.key = key;
    tr.replaceChildren(...[cells].flat());
    if (focused) {
      const again = [...tr.querySelectorAll('[aria-label]')].find((e) => e.getAttribute('aria-label') === focused) ||
        tr.querySelector(`.${focused.split(' ')[0]}`) || tr.querySelector('a');
      if (again) again.focus();
    }
  }
  const tbody = s.ui.tbody;
  if (prev ? prev.nextSibling !== tr : tbody.firstChild !== tr) {
    if (prev) prev.after(tr);
    else tbody.prepend(tr);
  }
  return tr;
}

// Rows are kept by key (a job id, or "c" and a comparison id) and rebuilt only when what they
// show changed, so focus and the keyboard position survive the once-a-second refresh.
function render(s, jobs, files) {
  const order = [];
  for (let i = 0; i < jobs.length; i++) {
    const cid = jobs[i].comparison_id;
    if (cid && (i === 0 || jobs[i - 1].comparison_id !== cid)) {
      const members = [];
      for (let k = i; k < jobs.length && jobs[k].comparison_id === cid; k++) members.push(jobs[k]);
      order.push([`c${cid}`, 'group', groupRow(s, cid, members)]);
    }
    order.push([String(jobs[i].id), cid ? 'member' : '', jobRow(s, jobs[i], files), cid && !s.expanded.has(cid)]);
  }
  const keep = new Set(order.map(([k]) => k));
  for (const [k, tr] of s.rows) if (!keep.has(k)) { tr.remove(); s.rows.delete(k); }
  let prev = null;
  for (const [k, cls, [key, cells], hidden] of order) prev = placeRow(s, k, cls, key, cells, hidden, prev);
}

// An empty install says how to start instead of showing an empty table; an empty filter result
// says so.
function emptyState(s, list) {
  const u = s.ui;
  const none = list.jobs.length === 0;
  const filtered = FILTERS.some((k) => s.filters[k]) || s.after;
  u.table.hidden = none;
  u.empty.hidden = !none;
  if (!none) return;
  u.empty.replaceChildren(...(filtered
    ? [el('p', {}, 'No jobs match these filters.')]
    : [el('h2', {}, 'No jobs yet'),
       el('p', {}, 'Submit a first job: pick a bundled scene (the Cornell box renders in a second or two) and a ' +
         'technique on the ', el('a', {href: '#/submit', className: 'button'}, 'Submit page'),
         ', or compare techniques there against a converged reference.'),
       el('p', {}, 'From the command line: ', el('code', {}, 'build/obscura submit scenes/cornell_box.json --wait'),
         ' (', el('code', {}, 'obscura help submit'), ' shows the options).')]));
}

// The status line, pager and debug hook after a listing arrived.
function showListing(s, list) {
  const u = s.ui;
  const active = list.jobs.filter((j) => ACTIVE.has(j.state)).length;
  const page = s.after ? `older jobs (below ${s.after})` : 'the newest';
  u.status.textContent = `${list.jobs.length} job${list.jobs.length === 1 ? '' : 's'}, ${page}` +
    (active ? `, ${active} queued or running` : '');
  emptyState(s, list);
  // The header's counts (main.js) come from another poll, which may be on its slow beat: when a
  // job here starts or ends, or the first listing already shows active jobs, it asks again at
  // once, so "N running" agrees with the rows.
  const states = JSON.stringify(list.jobs.filter((j) => ACTIVE.has(j.state)).map((j) => [j.id, j.state]));
  if (states !== (s.activeStates ?? '[]')) window.dispatchEvent(new Event('obscura:jobs-moved'));
  s.activeStates = states;
  u.pager.querySelector('.page-where').textContent = list.jobs.length
    ? `jobs ${list.jobs[list.jobs.length - 1].id}–${list.jobs[0].id}` : '';
  u.newest.disabled = u.newer.disabled = !s.after;
  u.older.disabled = !list.next;
  debug.jobs = list.jobs.map((j) => ({id: j.id, state: j.state, progress: j.progress, comparison_id: j.comparison_id}));
  return active;
}

export function mountJobs(view, _args, query) {
  const s = pageState(query);
  const u = s.ui;
  const tools = listTools(s);
  u.tbody = el('tbody');
  u.status = el('p', {role: 'status', className: 'muted'}, 'loading…');
  const alertP = setAlertEl(el('p', {role: 'alert', className: 'error'}));
  view.append(
    el('h1', {}, 'Jobs'), filterForm(s), u.status, alertP,
    el('p', {className: 'hint'}, 'Tab to a job and press Enter to open it; ↑/↓ move between jobs.'),
    tools,
    u.empty = el('div', {className: 'empty-state', hidden: true}),
    u.table = el('table', {className: 'jobs'},
      el('caption', {className: 'sr-only'}, 'Jobs, newest first; the jobs of a comparison under its row'),
      el('thead', {}, el('tr', {}, el('th', {scope: 'col'}, u.selectAll),
                         ...COLUMNS.slice(1).map((h) => el('th', {scope: 'col'}, h)))),
      u.tbody));
  arrowKeys(u.tbody);

  // Only the newest request may draw: a filter change starts a new one while an old one may still
  // be in flight, and nothing draws once the page is gone.
  let seq = 0, dead = false;
  const refresh = async () => {
    const q = new URLSearchParams({limit: String(PAGE)});
    for (const k of FILTERS) if (s.filters[k]) q.set(k, s.filters[k]);
    if (s.after) q.set('after', s.after);
    const mine = ++seq;
    let list;
    try {
      list = await api(`/api/v1/jobs?${q}`);
    } catch (e) {
      if (dead || mine !== seq) return false;
      u.status.textContent = e.message;
      return false;
    }
    const files = await outputFiles();
    if (dead || mine !== seq) return false;
    s.shown = list.jobs;
    s.nextCursor = list.next;
    render(s, list.jobs, files);
    for (const id of [...s.selected]) if (!list.jobs.some((j) => j.id === id)) s.selected.delete(id);
    syncChecks(s);
    return showListing(s, list) > 0;
  };
  s.handle = poll(refresh, {fast: 1000, slow: 4000});
  return () => {
    dead = true;
    s.handle.stop();
  };
}
