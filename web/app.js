// The minimal obscura dashboard: lists bundled scenes and techniques, submits jobs, and polls the
// job list once a second. Plain DOM, no dependencies; issue 5 replaces it with the full dashboard.
'use strict';

const $ = (id) => document.getElementById(id);
let token = localStorage.getItem('obscura-token') || '';

async function api(path, options = {}) {
  const headers = Object.assign({}, options.headers);
  if (token) headers.Authorization = 'Bearer ' + token;
  const res = await fetch(path, Object.assign({}, options, { headers }));
  if (res.status === 401) $('token-box').hidden = false;
  const body = res.status === 204 ? null : await res.json().catch(() => null);
  if (!res.ok) {
    const err = new Error((body && body.error) || res.statusText);
    err.problems = (body && body.problems) || [];
    throw err;
  }
  return body;
}

function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  Object.assign(e, props);
  for (const c of children) e.append(c);
  return e;
}

async function loadCatalogue() {
  const [{ scenes }, { techniques }] = await Promise.all([
    api('/api/v1/scenes'), api('/api/v1/techniques')]);
  $('scene').replaceChildren(...scenes.map((s) =>
    el('option', { value: s.name, textContent: `${s.name} (${s.technique}, ${s.width}×${s.height})` })));
  $('technique').replaceChildren(el('option', { value: '', textContent: "scene's own" }),
    ...techniques.map((t) => el('option', { value: t.name, textContent: t.name })));
}

function jobRow(j) {
  const actions = el('td');
  if (j.state === 'queued' || j.state === 'running') {
    actions.append(el('button', { textContent: 'cancel', onclick: () => act(j.links.cancel, 'POST') }));
  } else {
    actions.append(el('button', { textContent: 'delete', onclick: () => act(j.links.self, 'DELETE') }));
  }
  const image = el('td');
  if (j.links.outputs['ao.png']) {
    image.append(el('a', { href: j.links.outputs['ao.exr'] || j.links.outputs['ao.png'] },
      el('img', { src: j.links.outputs['ao.png'], alt: `job ${j.id}` })));
  }
  const state = el('td', { className: j.state, textContent: j.state, title: j.error || '' });
  return el('tr', {},
    el('td', { textContent: j.id }),
    el('td', { textContent: j.scene + (j.label ? ` — ${j.label}` : '') }),
    el('td', { textContent: j.technique }),
    el('td', { textContent: j.backend.actual || j.backend.requested }),
    state,
    el('td', {}, el('progress', { max: 1, value: j.progress })),
    el('td', { textContent: new Date(j.created_at).toLocaleTimeString() }),
    el('td', { textContent: j.timings_ms ? j.timings_ms.total.toFixed(1) : '' }),
    image, actions);
}

async function act(url, method) {
  try { await api(url, { method }); } catch (e) { $('submit-result').textContent = e.message; }
  refresh();
}

async function refresh() {
  try {
    const [{ jobs }, health] = await Promise.all([api('/api/v1/jobs?limit=100'), api('/api/v1/health')]);
    $('jobs').replaceChildren(...jobs.map(jobRow));
    $('health').textContent = `${health.status} · ${health.queue_depth} queued · ${health.running} running`;
  } catch (e) {
    $('health').textContent = e.message;
  }
}

$('submit').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const job = { scene_file: $('scene').value, priority: Number($('priority').value) };
  if ($('label').value) job.label = $('label').value;
  if ($('technique').value) {
    job.technique = { name: $('technique').value };
    if ($('backend').value) job.technique.backend = $('backend').value;
  } else if ($('backend').value) {
    job.set = { '/technique/backend': $('backend').value };
  }
  try {
    const r = await api('/api/v1/jobs', {
      method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(job) });
    $('submit-result').textContent = `job ${r.id} queued`;
    $('submit-result').className = '';
  } catch (e) {
    $('submit-result').textContent = [e.message, ...e.problems].join('\n');
    $('submit-result').className = 'error';
  }
  refresh();
});

$('token').addEventListener('change', () => {
  token = $('token').value;
  localStorage.setItem('obscura-token', token);
  loadCatalogue().catch(() => {});
  refresh();
});

loadCatalogue().catch((e) => { $('submit-result').textContent = e.message; });
refresh();
setInterval(refresh, 1000);
