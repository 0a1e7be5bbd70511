// Crash recovery: 20 jobs, `kill -9` while several run (twice), restart on the same database and
// data directory; every job ends succeeded with outputs whose size and SHA-256 match what the API
// and the database report (and the CLI's rendering of the same document), nothing half-written is
// left, and PRAGMA integrity_check is ok. Then a graceful stop (SIGTERM) while a job runs: it goes
// back to the queue without using up an attempt.
//
//   node tests/server/test_recovery.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {SCENES_DIR, SLOW, assertLogClean, cliRender, download, exrHeader, getJSON, listAll, pngSize, sha256,
        sleep, sql, startDaemon, submit, tail, waitAll} from './lib.mjs';

const N = 20;
const SETS = {'/image/width': 64, '/image/height': 64, '/technique/params/samples': 256};
const JOB = {scene_file: 'sphere_on_plane.json', set: SETS};
// What obs_result_write gives an rt_ao render.
const OUTPUTS = ['ao.exr', 'ao.png', 'bent_normal.png', 'depth.png', 'summary.json'];

// Polls the listing until at least `running` jobs run (and `done` finished); returns the listing.
async function waitRunning(d, running, done = 0) {
  const deadline = Date.now() + 60000 * SLOW;
  for (;;) {
    const jobs = await listAll(d);
    const n = jobs.filter((j) => j.state === 'running').length;
    const f = jobs.filter((j) => j.state === 'succeeded').length;
    if (n >= running && f >= done) return jobs;
    if (Date.now() > deadline) throw new Error(`never ${running} running and ${done} done: ${jobs.map((j) => j.state)}`);
    await sleep(5);
  }
}

function integrity(db) {
  const r = spawnSync('sqlite3', [db, 'PRAGMA integrity_check; PRAGMA foreign_key_check;'], {encoding: 'utf8'});
  assert.equal(r.status, 0, r.stderr);
  return r.stdout.trim();
}

// Checks the database as the crash left it, on a copy (opening it would recover the WAL in place).
// Runs fn on a copy of the database as a crash left it (database and WAL), so that reading it
// (which replays the WAL) leaves the original for the restarted daemon to recover.
function withCopy(d, fn) {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-dbcopy-'));
  try {
    for (const suffix of ['', '-wal']) {
      if (fs.existsSync(d.db + suffix)) fs.copyFileSync(d.db + suffix, path.join(tmp, `obscura.db${suffix}`));
    }
    return fn(path.join(tmp, 'obscura.db'));
  } finally {
    fs.rmSync(tmp, {recursive: true, force: true});
  }
}

function integrityOfCopy(d) {
  return withCopy(d, integrity);
}

// Ids of the jobs the database holds as running: those a crash interrupted.
function runningInCopy(d) {
  return withCopy(d, (db) => {
    const r = spawnSync('sqlite3', [db, "SELECT id FROM jobs WHERE state = 'running';"], {encoding: 'utf8'});
    assert.equal(r.status, 0, r.stderr);
    return r.stdout.split('\n').filter((l) => l !== '').map(Number);
  });
}

// After a test that restarts its daemon in one directory: the directory goes when the test
// passed; otherwise the daemon is killed and its log printed, and the directory is kept.
async function cleanUp(d, ok) {
  if (!ok) {
    await d.kill9();
    console.error(`# obscurad log (kept in ${d.dir}):\n${tail(d.log())}`);
  } else {
    fs.rmSync(d.dir, {recursive: true, force: true});
  }
}

test('crash recovery', async () => {
  let d = await startDaemon({workers: 2});
  const dir = d.dir;
  let ok = false;
  try {
    const ids = [];
    for (let i = 0; i < N; i++) ids.push(await submit(d, {...JOB, label: `job ${i}`}));
    const runningAt = [];
    for (let round = 0; round < 2; round++) {
      // Kill while both workers render (after at least one job finished in the first round).
      const jobs = await waitRunning(d, 2, round === 0 ? 1 : 0);
      await d.kill9();
      // What the database says after the kill, not the poll before it: a job seen running may
      // have finished in between.
      runningAt.push(runningInCopy(d));
      assert.ok(runningAt[round].length >= 1, 'the kill interrupted no render: nothing to recover');
      console.log(`# kill -9 #${round + 1}: running ${runningAt[round]}, done ${jobs.filter((j) => j.state === 'succeeded').length}`);
      assert.equal(integrityOfCopy(d), 'ok', 'database as the crash left it');
      d = await startDaemon({workers: 2, dir});
      const after = await listAll(d);
      assert.deepEqual(after.map((j) => j.id).sort((a, b) => a - b), ids, 'a job that got 201 was lost');
    }
    const jobs = await waitAll(d, ids);
    const cliDir = cliRender(path.join(SCENES_DIR, JOB.scene_file), path.join(dir, 'cli'), {sets: SETS});
    const cliExr = fs.readFileSync(path.join(cliDir, 'ao.exr'));
    const cliPng = fs.readFileSync(path.join(cliDir, 'ao.png'));
    const rows = new Map(sql(d.db, 'SELECT job_id, name, size, sha256 FROM outputs').map((r) => [`${r[0]}/${r[1]}`, r]));
    for (const j of jobs) {
      assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.state} ${j.error}`);
      const crashed = runningAt.filter((r) => r.includes(j.id)).length;
      assert.ok(j.attempts >= 1 + crashed && j.attempts <= 3, `job ${j.id}: ${j.attempts} attempts, running at ${crashed} crashes`);
      assert.deepEqual(j.outputs.map((o) => o.name).sort(), OUTPUTS);
      for (const o of j.outputs) {
        const r = await download(d, j, o.name);
        const onDisk = fs.readFileSync(path.join(d.resultsDir, String(j.id), o.name));
        assert.ok(onDisk.equals(r.body), `job ${j.id} ${o.name}: file differs from the download`);
        assert.deepEqual(rows.get(`${j.id}/${o.name}`), [String(j.id), o.name, String(o.size), o.sha256]);
        if (o.name === 'ao.exr') {
          assert.deepEqual(exrHeader(r.body).width, 64);
          assert.ok(r.body.equals(cliExr), `job ${j.id}: ao.exr differs from the CLI's`);
        }
        if (o.name === 'ao.png') {
          assert.deepEqual(pngSize(r.body), {width: 64, height: 64});
          assert.ok(r.body.equals(cliPng), `job ${j.id}: ao.png differs from the CLI's`);
        }
        if (o.name === 'summary.json') assert.equal(JSON.parse(r.text).width, 64);
      }
    }
    assert.equal(rows.size, OUTPUTS.length * N);
    // Exactly the outputs: no staging files, no directories of half-written attempts.
    // (logs/ holds the jobs' own logs: one per job.)
    const files = fs.readdirSync(d.dataDir).filter((f) => f !== 'results' && f !== 'logs');
    assert.deepEqual(files, [], 'data directory holds more than results/ and logs/');
    const expected = ids.flatMap((id) => [`${id}/`, ...OUTPUTS.map((n) =>
      `${id}/${n} ${jobs.find((j) => j.id === id).outputs.find((o) => o.name === n).size}`)]).sort();
    const listing = fs.readdirSync(d.resultsDir, {recursive: true}).map((f) => {
      const st = fs.statSync(path.join(d.resultsDir, f));
      return st.isDirectory() ? `${f}/` : `${f} ${st.size}`;
    }).sort();
    assert.deepEqual(listing, expected);

    // Graceful stop while a job runs: it is requeued, its attempt not counted, and completes (as
    // long under the sanitizers as in the release build, with a quarter of the samples: SLOW).
    const g = await submit(d, {...JOB, set: {...SETS, '/image/width': 256, '/image/height': 256,
                                             '/technique/params/samples': 256 / SLOW}});
    const g2 = await submit(d, JOB);
    await waitRunning(d, 1);
    const t0 = Date.now();
    const e = await d.stop();
    assert.deepEqual(e, {code: 0, signal: null}, `SIGTERM exit\n${tail(d.log())}`);
    assert.ok(Date.now() - t0 < 5000 * SLOW, `SIGTERM took ${Date.now() - t0} ms`);
    assertLogClean(d);
    assert.equal(integrity(d.db), 'ok');
    d = await startDaemon({workers: 2, dir});
    const [jg, jg2] = await waitAll(d, [g, g2]);
    assert.equal(jg.state, 'succeeded');
    assert.equal(jg2.state, 'succeeded');
    assert.equal(jg.attempts, 1, 'a graceful stop used up an attempt');
    assert.equal((await getJSON(d, '/api/v1/health')).status, 'ok');
    await d.stopClean();
    assert.equal(integrity(d.db), 'ok');
    ok = true;
  } finally {
    await cleanUp(d, ok);
  }
});

test('a job whose render crashed the daemon 3 times fails', async () => {
  let d = await startDaemon({});
  const dir = d.dir;
  let ok = false;
  try {
    const long = {scene_file: 'sphere_on_plane.json', set: {...SETS, '/image/width': 512, '/image/height': 512}};
    const id = await submit(d, long);
    for (let attempt = 1; attempt <= 3; attempt++) {
      const jobs = await waitRunning(d, 1);
      assert.equal(jobs.find((j) => j.id === id).attempts, attempt);
      await d.kill9();
      d = await startDaemon({dir});
    }
    const [j] = await listAll(d);
    assert.equal(j.state, 'failed', JSON.stringify(j));
    assert.equal(j.attempts, 3);
    assert.ok(j.error && j.error.length > 10, `error: ${j.error}`);
    assert.ok(j.finished_at);
    assert.deepEqual(j.outputs, []);
    assert.deepEqual(fs.readdirSync(d.resultsDir), []);
    // The daemon goes on: a new job runs.
    const next = await submit(d, JOB);
    const [jn] = await waitAll(d, [next]);
    assert.equal(jn.state, 'succeeded');
    await d.stopClean();
    assert.equal(integrity(d.db), 'ok');
    ok = true;
  } finally {
    await cleanUp(d, ok);
  }
});
