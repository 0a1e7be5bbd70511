// The daemon as a node of a store, on its SQLite file: the options that name the store and the
// node (--store or --db, never both; --node-name; --lease-seconds), the job's `node`, the node
// loop's heartbeats while a long render runs, and what the node does when the store says another
// writer changed a running job: a cancel requested in the store (what any other node's cancel
// writes) stops the render within a heartbeat; a job the store no longer gives this node (what
// the reaper of another node does to an expired lease) stops with its outputs dropped and runs
// again; a completion the store refuses (the job is no longer this worker's) leaves no outputs.
// The store's side of those changes is written here with the sqlite3 shell, as another node
// would write it.
//
//   node tests/server/test_cluster_node.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawn, spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {OBSCURAD, ROOT, SCENES_DIR, SLOW, getJSON, getJob, listFiles, request, sleep, sql, submit,
        validate, waitJob, withDaemon} from './lib.mjs';

// A render of a few seconds: long enough for several heartbeats of a 2 s lease (one each 0.67 s).
// The sanitizer build renders slower, so it renders fewer samples for about the same time.
const LONG = {scene_file: 'sphere_on_plane.json',
              set: {'/image/width': 256, '/image/height': 256, '/technique/params/samples': 1024 / SLOW}};

// A write to the daemon's database, as another node's statement would land in a shared store.
function sqlWrite(db, query) {
  const r = spawnSync('sqlite3', ['-batch', '-cmd', '.timeout 10000', db, query], {encoding: 'utf8'});
  assert.equal(r.status, 0, `sqlite3 ${query}: ${r.stderr}`);
  return r.stdout.trim();
}

async function jobLog(d, id) {
  return (await getJSON(d, `/api/v1/jobs/${id}/log`)).lines.join('\n');
}

async function waitLog(d, id, re, timeoutMs = 60000 * SLOW) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const log = await jobLog(d, id);
    if (re.test(log)) return log;
    if (Date.now() > deadline) throw new Error(`job ${id}: log never matched ${re}:\n${log}`);
    await sleep(20);
  }
}

// Runs obscurad with `args` until it exits (bad options) or says it listens; returns {code, out}.
function runOptions(args, timeoutMs = 20000 * SLOW) {
  return new Promise((resolve) => {
    const p = spawn(OBSCURAD, args, {stdio: ['ignore', 'pipe', 'pipe']});
    let out = '';
    const t = setTimeout(() => p.kill('SIGKILL'), timeoutMs);
    const onData = (b) => {
      out += b.toString();
      if (/listening on/.test(out)) p.kill('SIGTERM');
    };
    p.stdout.on('data', onData);
    p.stderr.on('data', onData);
    p.on('exit', (code, signal) => {
      clearTimeout(t);
      resolve({code, signal, out});
    });
  });
}

test('the store options: --store or --db (not both), --lease-seconds range, --store FILE as --db', async () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-cluster-opt-'));
  try {
    const base = ['--listen', '127.0.0.1', '--port', '0', '--data-dir', path.join(dir, 'data'),
                  '--scenes-dir', SCENES_DIR, '--web-dir', path.join(ROOT, 'web'), '--no-vulkan'];
    const both = await runOptions([...base, '--store', path.join(dir, 'a.db'), '--db', path.join(dir, 'b.db')]);
    assert.equal(both.code, 2, both.out);
    assert.match(both.out, /--store .*a\.db and --db .*b\.db/);
    assert.ok(!fs.existsSync(path.join(dir, 'a.db')) && !fs.existsSync(path.join(dir, 'b.db')),
              'a refused start must create no database');
    // A URL's password never reaches the message.
    const url = await runOptions([...base, '--store', 'postgresql://obscura:s3cret@127.0.0.1:1/x',
                                  '--db', path.join(dir, 'b.db')]);
    assert.equal(url.code, 2, url.out);
    assert.match(url.out, /postgresql:\/\/obscura:\*\*\*@127\.0\.0\.1:1\/x/);
    assert.doesNotMatch(url.out, /s3cret/);
    for (const bad of ['1', '3601', '2.5', 'x']) {
      const r = await runOptions([...base, '--lease-seconds', bad]);
      assert.equal(r.code, 2, r.out);
      assert.match(r.out, /lease-seconds must be an integer from 2 to 3600/);
    }
    // --store with a SQLite path is --db by another name: the file is created and used.
    const db = path.join(dir, 'store.db');
    const ok = await runOptions([...base, '--store', db, '--node-name', 'alpha']);
    assert.equal(ok.signal, null, ok.out);
    assert.equal(ok.code, 0, ok.out);
    assert.match(ok.out, /node alpha \(boot [0-9a-f]{16}\), lease 30 s; store SQLite/);
    assert.ok(fs.existsSync(db), 'the SQLite file named by --store');
  } finally {
    fs.rmSync(dir, {recursive: true, force: true});
  }
});

test('a job names its node (default HOSTNAME:PORT) and a comparison run its host', async () => {
  await withDaemon({}, async (d) => {
    const id = await submit(d, {scene_file: 'sphere_on_plane.json', set: {'/image/width': 32, '/image/height': 32}});
    const queued = await getJob(d, id);
    const job = await waitJob(d, id);
    assert.equal(job.state, 'succeeded', JSON.stringify(job));
    assert.equal(job.node, `${os.hostname()}:${d.port}`);
    assert.ok(queued.node === null || queued.node === job.node, `queued node ${queued.node}`);
    assert.deepEqual(sql(d.db, `SELECT node, worker FROM jobs WHERE id = ${id}`), [[job.node, '']]);
    const list = await getJSON(d, '/api/v1/jobs');
    assert.equal(list.jobs.find((j) => j.id === id).node, job.node);
  });
  await withDaemon({args: ['--node-name', 'render-7']}, async (d) => {
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'sphere_on_plane.json', set: {'/image/width': 16, '/image/height': 16}, repeats: 1,
      reference: {samples: 16}, candidates: [{technique: 'rt_ao', params: {samples: 4}}]}});
    assert.equal(r.status, 201, r.text);
    const deadline = Date.now() + 120000 * SLOW;
    let c;
    for (;;) {
      c = await getJSON(d, `/api/v1/comparisons/${r.json.id}`);
      if (c.state !== 'running') break;
      assert.ok(Date.now() < deadline, JSON.stringify(c));
      await sleep(50);
    }
    validate('Comparison', c);
    const runs = c.candidates.flatMap((k) => k.timings_ms.runs);
    assert.ok(runs.length >= 1, JSON.stringify(c.candidates));
    for (const run of runs) assert.equal(run.host, 'render-7');
    const job = await getJob(d, c.candidates[0].job_id);
    assert.equal(job.node, 'render-7');
  });
});

test('with a 2 s lease the node heartbeats a long render, which succeeds', async () => {
  await withDaemon({args: ['--lease-seconds', '2']}, async (d) => {
    const id = await submit(d, LONG);
    const job = await waitJob(d, id);
    assert.equal(job.state, 'succeeded', JSON.stringify(job));
    assert.equal(job.attempts, 1);
    const log = await jobLog(d, id);
    // Beats 1, 2, 4, 8 ... are logged: at least the first two came while it rendered.
    assert.match(log, /heartbeat 1: lease of attempt 1 held/);
    assert.match(log, /heartbeat 2: lease of attempt 1 held/);
    assert.doesNotMatch(log, /lease lost|late result/);
    // The lease the store holds is over once the job finished.
    assert.deepEqual(sql(d.db, `SELECT worker, lease_expires_ms FROM jobs WHERE id = ${id}`), [['', '']]);
  });
});

test('a cancel requested in the store stops the render within a heartbeat', async () => {
  await withDaemon({args: ['--lease-seconds', '2']}, async (d) => {
    const id = await submit(d, {...LONG, set: {...LONG.set, '/technique/params/samples': 8192}});
    await waitLog(d, id, /heartbeat 1:/);
    sqlWrite(d.db, `UPDATE jobs SET cancel_requested = 1 WHERE id = ${id}`);
    const job = await waitJob(d, id);
    assert.equal(job.state, 'cancelled', JSON.stringify(job));
    assert.ok(job.progress < 1, `stopped before the end: ${job.progress}`);
    assert.match(await jobLog(d, id), /cancel requested through another node/);
    assert.deepEqual(listFiles(d.resultsDir), [], 'nothing published or staged');
  });
});

test('a job the store no longer gives this node stops, drops its outputs and runs again', async () => {
  await withDaemon({args: ['--lease-seconds', '2']}, async (d) => {
    const id = await submit(d, LONG);
    await waitLog(d, id, /heartbeat 1:/);
    // What a reaper does to an expired lease: back to the queue, no worker.
    sqlWrite(d.db, `UPDATE jobs SET state = 'queued', worker = NULL, lease_expires_ms = NULL WHERE id = ${id}`);
    const log = await waitLog(d, id, /lease lost \(attempt 1\)/);
    assert.doesNotMatch(log, /running -> (cancelled|failed)/);
    const job = await waitJob(d, id, (j) => j.state === 'succeeded' || j.state === 'failed' || j.state === 'cancelled');
    assert.equal(job.state, 'succeeded', JSON.stringify(job));
    assert.equal(job.attempts, 2, 'the second claim rendered it');
    const files = listFiles(d.resultsDir);
    assert.ok(files.every((f) => f.startsWith(`${id}/`)), `only the job's results: ${files}`);
    assert.match(d.log(), new RegExp(`job ${id}: lease lost`));
  });
});

test('a completion the store refuses is dropped, never retried', async () => {
  // A lease too long for any heartbeat in this test: only the completion's guard can see it.
  await withDaemon({args: ['--lease-seconds', '3600']}, async (d) => {
    const id = await submit(d, LONG);
    await waitJob(d, id, (j) => j.state === 'running');
    // Another node's worker holds the attempt now (its claim after this node's lease lapsed).
    sqlWrite(d.db, `UPDATE jobs SET worker = 'elsewhere/0123456789abcdef' WHERE id = ${id}`);
    const log = await waitLog(d, id, /late result refused \(attempt 1 no longer held\)/);
    // The daemon's own log gets the line too, through its stderr pipe, which can trail the job log.
    const line = new RegExp(`job ${id}: late result refused \\(attempt 1 no longer held\\)`);
    for (let i = 0; i < 250 * SLOW && !line.test(d.log()); i++) await sleep(20);
    assert.match(d.log(), line);
    assert.equal(log.match(/late result refused/g).length, 1);
    const job = await getJob(d, id);
    assert.equal(job.state, 'running', 'the store keeps the other worker\'s attempt');
    assert.deepEqual(sql(d.db, `SELECT worker, attempts FROM jobs WHERE id = ${id}`),
                     [['elsewhere/0123456789abcdef', '1']]);
    assert.equal((await sql(d.db, `SELECT count(*) FROM outputs WHERE job_id = ${id}`))[0][0], '0');
    assert.deepEqual(listFiles(d.resultsDir), [], 'the refused attempt left no outputs');
    // The other node "finishes" it, so the daemon stops cleanly with nothing of its own running.
    sqlWrite(d.db, `UPDATE jobs SET state = 'failed', error = 'test', worker = NULL WHERE id = ${id}`);
  });
});

test('--results-dir: outputs are written and served there, marked with their attempt', async () => {
  const results = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-cluster-results-'));
  try {
    await withDaemon({args: ['--results-dir', results, '--node-name', 'shared-1']}, async (d) => {
      const id = await submit(d, {scene_file: 'sphere_on_plane.json', set: {'/image/width': 32, '/image/height': 32}});
      const job = await waitJob(d, id);
      assert.equal(job.state, 'succeeded', JSON.stringify(job));
      assert.deepEqual(listFiles(d.resultsDir), [], 'nothing under DATA-DIR/results');
      const mark = fs.readFileSync(path.join(results, String(id), '.attempt'), 'utf8');
      assert.match(mark, /^shared-1\/[0-9a-f]{16} 1\n$/);
      assert.ok(job.outputs.length >= 3, JSON.stringify(job.outputs));
      for (const o of job.outputs) {
        const r = await request(d, 'GET', `/api/v1/jobs/${id}/outputs/${o.name}`);
        assert.equal(r.status, 200, o.name);
        assert.equal(r.body.length, o.size);
        assert.deepEqual(r.body, fs.readFileSync(path.join(results, String(id), o.name)));
      }
      assert.ok(!job.outputs.some((o) => o.name === '.attempt'), 'the mark is no output');
    });
  } finally {
    fs.rmSync(results, {recursive: true, force: true});
  }
});
