// Shared helpers of the dashboard: the API client (bearer token from localStorage, and the
// session cookie login() gets for images and downloads), a small DOM builder, formatting, the registry cache, and the polling loop every live page uses.

export let token = localStorage.getItem('obscura-token') || '';
export function setToken(t) {
  token = t;
  localStorage.setItem('obscura-token', t);
}

/** An API error: HTTP status, the server's message and its `problems` (JSON pointers inside). */
export class ApiError extends Error {
  constructor(status, message, problems) {
    super(message);
    this.status = status;
    this.problems = problems || [];
  }
}

const listeners = new Set();
/** fn(status) is called after every API answer: the header shows 401s and lost connections. */
export function onApiStatus(fn) {
  listeners.add(fn);
}

export async function api(path, options = {}) {
  const headers = Object.assign({}, options.headers);
  if (token) headers.Authorization = 'Bearer ' + token;
  if (options.json !== undefined) {
    headers['Content-Type'] = 'application/json';
    options = Object.assign({}, options, {body: JSON.stringify(options.json)});
  }
  let res;
  try {
    const {raw, json, allow, ...init} = options; // obscura's own options are not fetch's
    res = await fetch(path, Object.assign({}, init, {headers}));
  } catch (e) {
    for (const fn of listeners) fn(0);
    throw new ApiError(0, `cannot reach the server (${e.message})`);
  }
  for (const fn of listeners) fn(res.status);
  // A request that changed something (a submission, a cancel): the header's counts are stale.
  const method = (options.method || 'GET').toUpperCase();
  if (res.ok && method !== 'GET' && method !== 'HEAD') window.dispatchEvent(new Event('obscura:changed'));
  // options.raw: a successful body is returned as text (CSV); errors are JSON either way.
  if (options.raw && res.ok) return res.text();
  const body = res.status === 204 ? null : await res.json().catch(() => null);
  // options.allow: statuses whose body is an answer, not an error (health's 503).
  if (!res.ok && !(options.allow && options.allow.includes(res.status) && body)) throw new ApiError(res.status, (body && body.error) || res.statusText, body && body.problems);
  return body;
}

let sessionTimer = null;
/**
 * With a token: POST /api/v1/session, whose HttpOnly cookie stands in for the bearer header on the
 * GETs an <img> or a download link makes (they cannot send the header). Renewed at half its life;
 * a failure leaves the API calls working (they carry the header) and the token box shown on 401.
 */
export async function login() {
  clearTimeout(sessionTimer);
  if (!token) return null;
  try {
    const s = await api('/api/v1/session', {method: 'POST'});
    if (s && s.expires_in) sessionTimer = setTimeout(login, s.expires_in * 500);
    debug.session = s;
    return s;
  } catch {
    return null;
  }
}

/**
 * el('tr', {className: 'x', onclick: f, 'aria-label': 'y'}, child, 'text', ...): properties are
 * assigned, names with a dash (aria-*, data-*) and `for` become attributes; null children are
 * skipped.
 */
export function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(props || {})) {
    if (v === undefined || v === null || v === false) continue;
    // Attributes whose DOM property is spelled otherwise ("tabindex" is tabIndex) are set as
    // attributes: assigned as properties they would be silently ignored.
    if (k.includes('-') || k === 'for' || k === 'role' || k === 'tabindex') e.setAttribute(k, v === true ? '' : v);
    else e[k] = v;
  }
  for (const c of children.flat()) if (c !== null && c !== undefined && c !== false) e.append(c);
  return e;
}

export const fmtMs = (v) => (v === null || v === undefined ? '–' : v >= 100 ? v.toFixed(0) : v >= 10 ? v.toFixed(1) : v.toFixed(2));
export const fmtNum = (v, digits = 4) => (v === null || v === undefined ? '–' : Number(v).toPrecision(digits));
export const fmtTime = (iso) => (iso ? new Date(iso).toLocaleString() : '–');
export const fmtBytes = (n) => (n < 1024 ? `${n} B` : n < 1 << 20 ? `${(n / 1024).toFixed(1)} KiB` : `${(n / (1 << 20)).toFixed(1)} MiB`);
export const ACTIVE = new Set(['queued', 'running']);

/** Text of a state that does not rely on colour: a symbol and the word. */
const STATE_MARK = {queued: '◷', running: '▶', succeeded: '✓', failed: '✗', cancelled: '⊘'};
export function stateBadge(state) {
  return el('span', {className: `state state-${state}`}, `${STATE_MARK[state] || '·'} ${state}`);
}

/**
 * A value as people read it, the one formatter of parameter values: numbers with at most 6
 * significant digits and no binary noise (0.360306, not 0.36030600000000002), strings bare, lists
 * as [a, b], anything else as JSON.
 */
export function fmtValue(v) {
  if (typeof v === 'number') return Number.isInteger(v) ? String(v) : String(Number(v.toPrecision(6)));
  if (typeof v === 'string') return v;
  if (Array.isArray(v)) return `[${v.map(fmtValue).join(', ')}]`;
  return JSON.stringify(v);
}

/** "k=v k=v" of a parameter object (values through fmtValue). */
export function paramText(params) {
  return Object.entries(params || {}).map(([k, v]) => `${k}=${fmtValue(v)}`).join(' ');
}

let registry = null;
/** GET /api/v1/techniques, once per page load (the registry only changes with the daemon). */
export async function techniques() {
  if (!registry) registry = api('/api/v1/techniques').catch((e) => {
    registry = null;
    throw e;
  });
  return registry;
}

/**
 * Calls fn() now and again after `fast` ms while it returns true (something is live), backing off
 * (doubling up to `slow`) while it returns false; pauses while the tab is hidden. Returns stop().
 */
export function poll(fn, {fast = 1000, slow = 8000} = {}) {
  let stopped = false, timer = null, delay = fast, gen = 0;
  // gen: a wake() during a request starts a new chain; the old one ends when its request returns.
  const tick = async (g) => {
    if (stopped || g !== gen) return;
    if (document.hidden) {
      timer = setTimeout(() => tick(g), fast);
      return;
    }
    let live = false;
    try {
      live = await fn();
    } catch {
      live = false;
    }
    if (stopped || g !== gen) return;
    delay = live ? fast : Math.min(delay * 2, slow);
    timer = setTimeout(() => tick(g), delay);
  };
  tick(gen);
  return {
    stop: () => {
      stopped = true;
      clearTimeout(timer);
    },
    // Poll again now and at full speed (after an action that changes what is shown).
    wake: () => {
      if (stopped) return;
      clearTimeout(timer);
      delay = fast;
      tick(++gen);
    },
  };
}

/** Shared debug hook for tests and curious people: window.__obscura. */
export const debug = (window.__obscura = window.__obscura || {});
