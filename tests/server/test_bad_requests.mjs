// The bad-input corpus (tests/server/bad_requests.json): every malformed request gets the right 4xx
// with an Error body that says what is wrong, the daemon stays up, and nothing is written (same
// jobs table, same results directory, no new job id).
//
//   node tests/server/test_bad_requests.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {test} from 'node:test';

import {ROOT, SCENES_DIR, getJSON, listFiles, request, sql, submit, validate, waitJob, withDaemon} from './lib.mjs';

const corpus = JSON.parse(fs.readFileSync(path.join(ROOT, 'tests/server/bad_requests.json'), 'utf8'));

// "@SCENES@" in any string of v becomes the absolute scenes directory.
const scenesIn = (v) => JSON.parse(JSON.stringify(v).replaceAll('@SCENES@', SCENES_DIR));

// Applies {pointer: value | {"$delete": true}} to a copy of base.
function patched(base, patch) {
  const doc = structuredClone(base);
  for (const [ptr, value] of Object.entries(patch)) {
    const keys = ptr.split('/').slice(1).map((k) => k.replace(/~1/g, '/').replace(/~0/g, '~'));
    let o = doc;
    for (const k of keys.slice(0, -1)) o = o[k];
    const last = keys[keys.length - 1];
    if (value && typeof value === 'object' && value.$delete) delete o[last];
    else o[last] = scenesIn(value);
  }
  return doc;
}

function bodyOf(e) {
  if (e.raw !== undefined) return e.raw;
  if (e.raw_base64 !== undefined) return Buffer.from(e.raw_base64, 'base64');
  if (e.raw_gen) return e.raw_gen.prefix + e.raw_gen.repeat.repeat(e.raw_gen.count) + e.raw_gen.suffix;
  if (e.base) return JSON.stringify(patched(corpus.bases[e.base], e.patch || {}));
  return undefined;
}

// What must not change: every column of every job, the output rows, the id sequence and the files.
function snapshot(d) {
  return {
    jobs: sql(d.db, 'SELECT * FROM jobs ORDER BY id'),
    outputs: sql(d.db, 'SELECT * FROM outputs ORDER BY job_id, name'),
    seq: sql(d.db, "SELECT seq FROM sqlite_sequence WHERE name = 'jobs'"),
    files: listFiles(d.dataDir),
  };
}

test('bad input corpus', async () => {
  assert.ok(corpus.requests.length >= 60, `only ${corpus.requests.length} requests`);
  const names = new Set();
  for (const e of corpus.requests) {
    assert.ok(!names.has(e.name), `duplicate name ${e.name}`);
    names.add(e.name);
  }
  await withDaemon({token: corpus.token, args: ['--max-body', '65536', '--max-pixels', '1000000',
                                                '--max-work', '1e8', '--max-triangles', '100000']}, async (d) => {
    // One finished job for the routes that need an id; both base bodies must be valid as they are.
    const id = await submit(d, corpus.bases.file);
    const id2 = await submit(d, corpus.bases.inline);
    for (const j of [id, id2]) assert.equal((await waitJob(d, j)).state, 'succeeded');
    const before = snapshot(d);
    const failures = [];
    for (const e of corpus.requests) {
      const headers = {...(e.headers || {})};
      let auth = true;
      if (e.auth === 'none') auth = false;
      else if (e.auth && e.auth !== 'token') {
        auth = false;
        headers.authorization = e.auth;
      }
      const body = bodyOf(e);
      if (body !== undefined && e.raw === undefined && e.raw_base64 === undefined && !e.raw_gen &&
          !Object.keys(headers).some((k) => k.toLowerCase() === 'content-type')) {
        headers['content-type'] = 'application/json';
      }
      const p = e.path.replaceAll('{id}', String(id));
      let r;
      try {
        r = await request(d, e.method, p, {body, headers, auth, chunked: !!e.chunked});
      } catch (err) {
        failures.push(`${e.name}: ${e.method} ${p}: ${err.message}`);
        continue;
      }
      if (process.env.OBSD_CORPUS_DUMP) console.log(`# ${e.name}: ${r.status} ${r.text.slice(0, 300)}`);
      const problems = [];
      const seq = sql(d.db, "SELECT seq FROM sqlite_sequence WHERE name = 'jobs'");
      if (JSON.stringify(seq) !== JSON.stringify(before.seq)) {
        problems.push(`created job ${seq[0][0]}`);
        before.seq = seq;
      }
      if (r.status !== e.status) problems.push(`status ${r.status}, expected ${e.status}`);
      if (!r.json) {
        problems.push(`not a JSON body (${r.headers['content-type']}): ${r.text.slice(0, 200)}`);
      } else {
        try {
          validate('Error', r.json);
        } catch (err) {
          problems.push(err.message.split('\n')[0]);
        }
        const text = `${r.json.error}\n${(r.json.problems || []).join('\n')}`;
        if (typeof r.json.error !== 'string' || r.json.error.length < 8) problems.push(`error too short: ${JSON.stringify(r.json.error)}`);
        for (const s of e.expect || []) {
          if (!text.toLowerCase().includes(s.toLowerCase())) problems.push(`message lacks "${s}"`);
        }
      }
      if (r.headers['x-content-type-options'] !== 'nosniff') problems.push('no X-Content-Type-Options: nosniff');
      if (!r.headers['content-security-policy']) problems.push('no Content-Security-Policy');
      if (r.headers['access-control-allow-origin'] !== undefined) problems.push('CORS header');
      if (e.status === 401 && !/^Bearer/i.test(r.headers['www-authenticate'] || '')) problems.push('no WWW-Authenticate: Bearer');
      if (e.allow) {
        const allow = (r.headers.allow || '').split(/\s*,\s*/);
        for (const m of e.allow) if (!allow.includes(m)) problems.push(`Allow "${r.headers.allow}" lacks ${m}`);
      }
      if (e.content_range && !(r.headers['content-range'] || '').startsWith(e.content_range)) {
        problems.push(`Content-Range "${r.headers['content-range']}"`);
      }
      if (problems.length) {
        failures.push(`${e.name}: ${e.method} ${p}: ${problems.join('; ')}\n    got ${r.status} ${r.text.slice(0, 400)}`);
      }
    }
    const bad = failures.length;
    console.log(`# ${corpus.requests.length - bad} of ${corpus.requests.length} requests answered as expected`);
    // Still up, and nothing changed.
    const health = await getJSON(d, '/api/v1/health');
    assert.equal(health.status, 'ok');
    const after = snapshot(d);
    for (const k of Object.keys(before)) {
      if (JSON.stringify(after[k]) !== JSON.stringify(before[k])) {
        failures.push(`${k} changed:\n    before ${JSON.stringify(before[k]).slice(0, 1500)}\n    after  ${JSON.stringify(after[k]).slice(0, 1500)}`);
      }
    }
    // Static dashboard files need no token.
    const index = await request(d, 'GET', '/', {auth: false});
    assert.equal(index.status, 200);
    assert.match(index.headers['content-type'], /^text\/html/);
    assert.ok(index.headers['content-security-policy']);
    const list = await getJSON(d, '/api/v1/jobs?limit=500');
    assert.deepEqual(list.jobs.map((j) => j.id).sort((a, b) => a - b), [id, id2]);
    assert.equal(failures.length, 0, `${bad} of ${corpus.requests.length} requests failed, ` +
                 `${failures.length - bad} state checks:\n  ${failures.join('\n  ')}`);
  });
});
