// Entry point of the dashboard: hash routing to the page modules (#/view/ID: the image viewer), the header's health line and
// token box. Each page's mount(container, params) returns a cleanup that stops its polling.
import {api, debug, el, login, onApiStatus, poll, setToken, token} from './api.js';
import {mountJobs, mountJob} from './jobs.js';
import {mountComparisons, mountComparison} from './comparisons.js';
import {mountSubmit} from './submit.js';
import {mountViewer} from './viewer.js';

const routes = [
  [/^#\/jobs\/(\d+)$/, mountJob, 'jobs'],
  [/^#\/jobs$/, mountJobs, 'jobs'],
  [/^#\/comparisons\/(\d+)$/, mountComparison, 'comparisons'],
  [/^#\/comparisons$/, mountComparisons, 'comparisons'],
  [/^#\/submit$/, mountSubmit, 'submit'],
  [/^#\/view\/(\d+)$/, mountViewer, 'jobs'],
];

const view = document.getElementById('view');
let cleanup = null;

// The skip link moves the focus to the page, not to another route ("#view" is no route).
document.querySelector('a.skip').addEventListener('click', (ev) => {
  ev.preventDefault();
  view.tabIndex = -1;
  view.focus();
});

function route() {
  const [path, query] = (location.hash || '#/jobs').split('?');
  const match = routes.find(([re]) => re.test(path));
  if (!match) {
    location.replace('#/jobs');
    return;
  }
  const [re, mount, section] = match;
  if (cleanup) cleanup();
  cleanup = null;
  view.replaceChildren();
  for (const a of document.querySelectorAll('nav a')) {
    if (a.dataset.page === section) a.setAttribute('aria-current', 'page');
    else a.removeAttribute('aria-current');
  }
  debug.page = path;
  const params = new URLSearchParams(query || '');
  cleanup = mount(view, path.match(re).slice(1), params) || null;
  // Screen readers and keyboard users land on the new page's heading, not on the old link.
  const h1 = view.querySelector('h1');
  if (h1) {
    h1.tabIndex = -1;
    h1.focus({preventScroll: true});
  }
}

window.addEventListener('hashchange', route);

// ---- header -------------------------------------------------------------------------------------

const health = document.getElementById('health');
const tokenBox = document.getElementById('token-box');
document.getElementById('token').value = token;
onApiStatus((status) => {
  if (status === 401) tokenBox.hidden = false;
});
tokenBox.addEventListener('submit', async (ev) => {
  ev.preventDefault();
  setToken(document.getElementById('token').value.trim());
  await login();
  route();
});

// Every page shows the server's active faults (a full or read-only disk, a lost or corrupt
// database) above its content: what failed, where, since when, the next retry and what to do; and
// the server-wide limits that refused requests in the last minute (health's capacity.refusing).
const banner = document.getElementById('fault-banner');
function showFaults(faults, refusing = []) {
  const lines = faults.map((f) => {
    const when = f.next_retry ? ` · next retry ${new Date(f.next_retry).toLocaleTimeString()}` : '';
    return el('p', {className: f.severity === 'error' ? 'fault error' : 'fault'},
      el('strong', {}, f.severity === 'error' ? 'Not accepting work: ' : 'Paused: '),
      `${f.what} (${f.code ? f.code + ', ' : ''}${f.path}) since ${new Date(f.since).toLocaleTimeString()}${when}. `,
      el('span', {className: 'fault-message'}, f.message), ' ',
      el('span', {className: 'fault-action'}, f.action));
  });
  if (refusing.length) {
    lines.push(el('p', {className: 'fault'}, el('strong', {}, 'Refusing requests: '),
      `no room under ${refusing.join(', ')} in the last minute; submissions may get 429 or 503 ` +
      '(GET /api/v1/health lists every limit\'s refusals).'));
  }
  banner.replaceChildren(...lines);
  banner.hidden = lines.length === 0;
}

// The counts follow the queue: every 2 s while something is queued or running, at most 5 s apart
// when idle, and at once after this page changed something (obscura:changed, from api()).
let uptime = Infinity;
debug.health = {polls: 0, wakes: 0};
const healthPoll = poll(async () => {
  try {
    const h = await api('/api/v1/health', {allow: [503]});
    debug.health.polls++;
    // A restarted daemon has forgotten the session: log in again for the images.
    if (h.uptime_s < uptime && uptime !== Infinity) login();
    uptime = h.uptime_s;
    health.textContent = `server ${h.status} · ${h.queue_depth} queued · ${h.running} running` +
      (h.vulkan_available ? ' · Vulkan' : '');
    showFaults(h.faults || [], (h.capacity && h.capacity.refusing) || []);
    return h.queue_depth + h.running > 0 || (h.faults || []).length > 0;
  } catch (e) {
    health.textContent = `server: ${e.message}`;
    return false;
  }
}, {fast: 2000, slow: 5000});
window.addEventListener('obscura:changed', () => {
  debug.health.wakes++;
  healthPoll.wake();
});
// The job list saw a job start or end (joblist.js): the counts follow.
window.addEventListener('obscura:jobs-moved', () => healthPoll.wake());

// Images on the first page need the session cookie before they load.
login().then(route);
