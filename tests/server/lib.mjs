// Shared helpers of the obscurad integration tests (tests/server/test_*.mjs): start a real daemon
// on 127.0.0.1 with an ephemeral port, its own temporary directory and SQLite file; talk to it;
// check responses against schema/openapi.yaml; run the CLI for comparisons.
//
// Every test file is run as
//   node tests/server/test_X.mjs <path-to-obscurad> <path-to-obscura-cli>
// (ctest passes both; OBSCURAD / OBSCURA in the environment work too). Only node built-ins, ajv
// and yaml (to read the OpenAPI document) are used.

import assert from 'node:assert/strict';
import {spawn, spawnSync} from 'node:child_process';
import crypto from 'node:crypto';
import fs from 'node:fs';
import http from 'node:http';
import {createRequire} from 'node:module';
import os from 'node:os';
import path from 'node:path';
import {fileURLToPath} from 'node:url';

export const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
export const SCENES_DIR = path.join(ROOT, 'scenes');
const require = createRequire(path.join(ROOT, 'package.json'));

const args = process.argv.slice(2).filter((a) => !a.startsWith('--test'));
export const OBSCURAD = path.resolve(args[0] || process.env.OBSCURAD || path.join(ROOT, 'build/obscurad'));
export const OBSCURA = path.resolve(args[1] || process.env.OBSCURA || path.join(ROOT, 'build/obscura'));
for (const [what, p] of [['obscurad', OBSCURAD], ['obscura', OBSCURA]]) {
  if (!fs.existsSync(p)) {
    console.error(`usage: node ${path.basename(process.argv[1])} <obscurad> <obscura>: no ${what} at ${p}`);
    process.exit(64);
  }
}
if (spawnSync('sqlite3', ['-version']).status !== 0) {
  console.error('the sqlite3 command-line shell is needed (Debian package sqlite3)');
  process.exit(1);
}
// The sanitizer build is many times slower: timeouts scale with it.
export const SLOW = /asan|sanitize/i.test(OBSCURAD) ? 4 : 1;

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
export const sha256 = (buf) => crypto.createHash('sha256').update(buf).digest('hex');
export const TERMINAL = new Set(['succeeded', 'failed', 'cancelled']);

// ---- the daemon ---------------------------------------------------------------------------------

const live = new Set();
process.on('exit', () => {
  for (const d of live) {
    try {
      d.proc.kill('SIGKILL');
    } catch {}
  }
});

// Log lines that must never appear: database trouble, sanitizer reports.
export const BAD_LOG = /database is locked|SQLITE_BUSY|SQLITE_CORRUPT|disk I\/O error|malformed|sqlite[^\n]*error|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error:/i;

/**
 * Starts obscurad. opts: args (extra options), workers (default 1), token (string: written to a
 * token file and passed as --token-file), dir (reuse this directory: same DB and data dir, for a
 * restart), store (a postgresql:// URL given as --store instead of the directory's SQLite file). Returns {url, port, dir, db, dataDir, resultsDir, token, log(), stop(), kill9(), ...}.
 */
export async function startDaemon(opts = {}) {
  const dir = opts.dir || fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-test-'));
  const db = path.join(dir, 'obscura.db');
  const dataDir = path.join(dir, 'data');
  const argv = ['--listen', '127.0.0.1', '--port', '0', ...(opts.store ? ['--store', opts.store] : ['--db', db]),
                '--data-dir', dataDir,
                '--scenes-dir', opts.scenesDir || SCENES_DIR, '--web-dir', path.join(ROOT, 'web'),
                '--workers', String(opts.workers ?? 1), '--no-vulkan'];
  let token = null;
  if (opts.token !== undefined) {
    token = opts.token;
    const tf = path.join(dir, 'token');
    fs.writeFileSync(tf, `${token}\n`, {mode: 0o600});
    argv.push('--token-file', tf);
  }
  argv.push(...(opts.args || []));
  const logFile = path.join(dir, `obscurad.${Date.now()}.log`);
  const proc = spawn(OBSCURAD, argv, {stdio: ['ignore', 'pipe', 'pipe'], env: process.env});
  let log = '';
  const logStream = fs.createWriteStream(logFile);
  const onData = (b) => {
    log += b.toString();
    logStream.write(b);
  };
  proc.stdout.on('data', onData);
  proc.stderr.on('data', onData);
  const exited = new Promise((resolve) => proc.on('exit', (code, signal) => resolve({code, signal})));
  const d = {proc, dir, db, dataDir, resultsDir: path.join(dataDir, 'results'), token, logFile,
             log: () => log, exited, exit: null};
  exited.then((e) => {
    d.exit = e;
    live.delete(d);
    logStream.end();
  });
  live.add(d);
  const deadline = Date.now() + 30000 * SLOW;
  for (;;) {
    const m = log.match(/listening on http:\/\/(?:127\.0\.0\.1|\[::1\]|localhost):(\d+)/);
    if (m) {
      d.port = Number(m[1]);
      break;
    }
    if (d.exit) throw new Error(`obscurad exited (${JSON.stringify(d.exit)}) before listening:\n${log}`);
    if (Date.now() > deadline) {
      proc.kill('SIGKILL');
      throw new Error(`obscurad did not report its port within ${30 * SLOW} s:\n${log}`);
    }
    await sleep(10);
  }
  d.url = `http://127.0.0.1:${d.port}`;
  d.auth = token === null ? {} : {authorization: `Bearer ${token}`};

  // Stops with SIGTERM (SIGKILL after a grace period); returns {code, signal}.
  d.stop = async () => {
    if (d.exit) return d.exit;
    proc.kill('SIGTERM');
    const t = setTimeout(() => proc.kill('SIGKILL'), 20000 * SLOW);
    const e = await exited;
    clearTimeout(t);
    return e;
  };
  d.kill9 = async () => {
    if (d.exit) return d.exit;
    proc.kill('SIGKILL');
    return exited;
  };
  // Stops it and asserts a clean exit (0 on SIGTERM, also under ASan: a LeakSanitizer report at
  // exit makes it nonzero) with nothing bad in the log.
  d.stopClean = async () => {
    const e = await d.stop();
    assert.equal(e.signal, null, `obscurad died of ${e.signal}\n${tail(log)}`);
    assert.equal(e.code, 0, `obscurad exited ${e.code} on SIGTERM${SLOW > 1 ? ' (sanitizer build: ' +
                 'see the report in the log)' : ''}\n${tail(log)}`);
    assertLogClean(d);
  };
  return d;
}

export function tail(s, n = 4000) {
  return s.length > n ? `...${s.slice(-n)}` : s;
}

export function assertLogClean(d) {
  const m = d.log().match(BAD_LOG);
  assert.ok(!m, `daemon log has "${m && m[0]}":\n${tail(d.log())}`);
}

/**
 * Runs fn(d) with a started daemon and always stops it (SIGKILL when fn failed). With
 * {clean: true} (the default) a successful fn is followed by a clean-shutdown check.
 */
export async function withDaemon(opts, fn) {
  const d = await startDaemon(opts);
  let ok = false;
  try {
    await fn(d);
    ok = true;
  } finally {
    if (ok && opts.clean !== false) {
      await d.stopClean();
      if (!opts.keep) fs.rmSync(d.dir, {recursive: true, force: true});
    } else {
      await d.kill9();
      if (!ok) console.error(`# obscurad log (kept in ${d.dir}):\n${tail(d.log())}`);
    }
  }
}

// ---- HTTP ---------------------------------------------------------------------------------------

/**
 * One request through node:http, so that the path goes out exactly as given (fetch would resolve
 * `..` and re-encode). body: string | Buffer | object (sent as JSON); any body goes with
 * Content-Type: application/json unless headers name one or contentType is false. Returns
 * {status, headers, body (Buffer), text, json (parsed or undefined)}.
 */
export function request(d, method, p, {body, headers = {}, auth = true, chunked = false, contentType = true, timeout = 60000 * SLOW} = {}) {
  return new Promise((resolve, reject) => {
    let data = body;
    const h = {...(auth ? d.auth : {}), ...headers};
    if (data !== undefined && typeof data !== 'string' && !Buffer.isBuffer(data)) data = JSON.stringify(data);
    if (data !== undefined && contentType && !Object.keys(h).some((k) => k.toLowerCase() === 'content-type')) {
      h['content-type'] = 'application/json';
    }
    if (data !== undefined && !chunked) h['content-length'] = Buffer.byteLength(data);
    const req = http.request({host: '127.0.0.1', port: d.port, method, path: p, headers: h, agent: false,
                              timeout}, (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('end', () => {
        const buf = Buffer.concat(chunks);
        const text = buf.toString('utf8');
        let json;
        if (/json/.test(res.headers['content-type'] || '')) {
          try {
            json = JSON.parse(text);
          } catch {}
        }
        resolve({status: res.statusCode, headers: res.headers, body: buf, text, json});
      });
      res.on('error', reject);
    });
    let answered = false;
    req.on('response', () => (answered = true));
    req.on('timeout', () => req.destroy(new Error(`${method} ${p}: timed out`)));
    // A server may answer (413) and close before reading the whole body: the write then fails
    // after the response, which is not an error of the exchange.
    req.on('error', (e) => {
      if (!answered) reject(e);
    });
    if (data !== undefined) req.write(data);
    req.end();
  });
}

export async function getJSON(d, p, expectStatus = 200) {
  const r = await request(d, 'GET', p);
  assert.equal(r.status, expectStatus, `GET ${p}: ${r.status} ${r.text}`);
  assert.ok(r.json !== undefined, `GET ${p}: not JSON: ${r.headers['content-type']} ${r.text}`);
  return r.json;
}

/** POST /api/v1/jobs; asserts 201 and the Submitted shape; returns the id. */
export async function submit(d, body) {
  const r = await request(d, 'POST', '/api/v1/jobs', {body});
  assert.equal(r.status, 201, `submit: ${r.status} ${r.text}`);
  validate('Submitted', r.json);
  assert.equal(r.json.state, 'queued');
  assert.equal(r.headers.location, `/api/v1/jobs/${r.json.id}`);
  return r.json.id;
}

export async function getJob(d, id) {
  const j = await getJSON(d, `/api/v1/jobs/${id}`);
  validate('Job', j);
  return j;
}

/** Polls until pred(job) holds; returns the job. */
export async function waitJob(d, id, pred = (j) => TERMINAL.has(j.state), timeoutMs = 60000 * SLOW) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const j = await getJob(d, id);
    if (pred(j)) return j;
    if (Date.now() > deadline) throw new Error(`job ${id}: condition not met in ${timeoutMs} ms: ${JSON.stringify(j)}`);
    await sleep(15);
  }
}

export async function waitAll(d, ids, timeoutMs = 120000 * SLOW) {
  const out = [];
  for (const id of ids) out.push(await waitJob(d, id, undefined, timeoutMs));
  return out;
}

/** Every job of the listing, following `next` (filters as a query string without limit). */
export async function listAll(d, query = '', limit = 500) {
  const jobs = [];
  let after = null;
  for (let pages = 0; pages < 10000; pages++) {
    const q = [query, `limit=${limit}`, after ? `after=${after}` : ''].filter(Boolean).join('&');
    const page = await getJSON(d, `/api/v1/jobs?${q}`);
    validate('JobList', page);
    jobs.push(...page.jobs);
    if (page.next === null) return jobs;
    after = page.next;
  }
  throw new Error('listing never ends');
}

/** `SELECT ...` through the sqlite3 CLI (read-only); returns the rows as arrays of strings. */
export function sql(dbFile, query) {
  const r = spawnSync('sqlite3', ['-readonly', '-batch', '-separator', '\t', dbFile, query], {encoding: 'utf8'});
  assert.equal(r.status, 0, `sqlite3 ${query}: ${r.stderr}`);
  return r.stdout.split('\n').filter((l) => l !== '').map((l) => l.split('\t'));
}

/** Files under dir, recursively, as "relative/path size" lines (sorted); [] when dir is missing. */
export function listFiles(dir) {
  const out = [];
  const walk = (p, rel) => {
    let ents;
    try {
      ents = fs.readdirSync(p, {withFileTypes: true});
    } catch (e) {
      if (e.code === 'ENOENT') return;
      throw e;
    }
    for (const e of ents) {
      const full = path.join(p, e.name);
      const r = rel ? `${rel}/${e.name}` : e.name;
      if (e.isDirectory()) {
        out.push(`${r}/`);
        walk(full, r);
      } else out.push(`${r} ${fs.lstatSync(full).size}`);
    }
  };
  walk(dir, '');
  return out.sort();
}

// ---- the OpenAPI document -----------------------------------------------------------------------

let ajv = null;
const validators = new Map();
/** Asserts that `value` matches components/schemas/<name> of schema/openapi.yaml. */
export function validate(name, value) {
  if (!ajv) {
    const YAML = require('yaml');
    const Ajv2020 = require('ajv/dist/2020').default;
    const spec = YAML.parse(fs.readFileSync(path.join(ROOT, 'schema', 'openapi.yaml'), 'utf8'));
    ajv = new Ajv2020({strict: false, allErrors: true, validateFormats: false});
    ajv.addSchema({$id: 'openapi', components: spec.components});
  }
  let v = validators.get(name);
  if (!v) {
    v = ajv.getSchema(`openapi#/components/schemas/${name}`);
    assert.ok(v, `no schema ${name} in openapi.yaml`);
    validators.set(name, v);
  }
  if (!v(value)) {
    assert.fail(`${name} does not match openapi.yaml: ${ajv.errorsText(v.errors)}\n${JSON.stringify(value).slice(0, 2000)}`);
  }
}

// ---- images and the CLI -------------------------------------------------------------------------

/** PNG signature and the IHDR size; returns {width, height}. */
export function pngSize(buf) {
  assert.ok(buf.length > 33, 'PNG too short');
  assert.equal(buf.subarray(0, 8).toString('hex'), '89504e470d0a1a0a', 'PNG signature');
  assert.equal(buf.subarray(12, 16).toString('latin1'), 'IHDR', 'PNG IHDR chunk first');
  return {width: buf.readUInt32BE(16), height: buf.readUInt32BE(20)};
}

/** OpenEXR magic and version 2; returns the channel names and data window of the header. */
export function exrHeader(buf) {
  assert.ok(buf.length > 8, 'EXR too short');
  assert.equal(buf.readUInt32LE(0), 20000630, 'EXR magic');
  assert.equal(buf[4], 2, 'EXR version 2');
  let o = 8;
  const attrs = {};
  const cstr = () => {
    const e = buf.indexOf(0, o);
    assert.ok(e > 0, 'EXR header string');
    const s = buf.subarray(o, e).toString('latin1');
    o = e + 1;
    return s;
  };
  for (;;) {
    const name = cstr();
    if (name === '') break;
    const type = cstr();
    const size = buf.readInt32LE(o);
    o += 4;
    attrs[name] = {type, data: buf.subarray(o, o + size)};
    o += size;
    assert.ok(o < buf.length, 'EXR header runs past the file');
  }
  const channels = [];
  if (attrs.channels) {
    const c = attrs.channels.data;
    let p = 0;
    while (p < c.length && c[p] !== 0) {
      const e = c.indexOf(0, p);
      channels.push(c.subarray(p, e).toString('latin1'));
      p = e + 1 + 16;
    }
  }
  const dw = attrs.dataWindow && attrs.dataWindow.data;
  const win = dw ? [dw.readInt32LE(0), dw.readInt32LE(4), dw.readInt32LE(8), dw.readInt32LE(12)] : null;
  return {channels, width: win && win[2] - win[0] + 1, height: win && win[3] - win[1] + 1};
}

/**
 * Renders `scene` (a file) with the CLI into a fresh directory; `sets` maps pointers to values
 * (as the job's `set`), technique/backend as --technique/--backend. Returns the directory.
 */
export function cliRender(scene, outDir, {sets = {}, technique, backend} = {}) {
  const argv = ['render', scene, '-o', outDir, '--quiet'];
  if (technique) argv.push('--technique', technique);
  if (backend) argv.push('--backend', backend);
  for (const [k, v] of Object.entries(sets)) argv.push('--set', `${k}=${JSON.stringify(v)}`);
  const r = spawnSync(OBSCURA, argv, {encoding: 'utf8', timeout: 300000 * SLOW});
  assert.equal(r.status, 0, `obscura ${argv.join(' ')}: exit ${r.status}\n${r.stdout}${r.stderr}`);
  return outDir;
}

/** Downloads an output of a succeeded job and checks it against its Output record. */
export async function download(d, job, name) {
  const o = job.outputs.find((x) => x.name === name);
  assert.ok(o, `job ${job.id} has no output ${name}: ${JSON.stringify(job.outputs)}`);
  assert.equal(o.url, `/api/v1/jobs/${job.id}/outputs/${name}`);
  const r = await request(d, 'GET', o.url);
  assert.equal(r.status, 200, `GET ${o.url}: ${r.status} ${r.text.slice(0, 300)}`);
  assert.equal(r.body.length, o.size, `${o.url}: size`);
  assert.equal(sha256(r.body), o.sha256, `${o.url}: SHA-256`);
  assert.equal(r.headers['content-type'], o.content_type);
  return r;
}
