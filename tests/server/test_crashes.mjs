// kill -9 at eight distinct moments of the daemon's life, timed from its log and its files:
// jobs queued, a job just claimed, mid-render, between publishing the outputs and committing
// them, while a comparison's metrics are computed, during a comparison insert, around a WAL
// checkpoint, and during a graceful shutdown. After every kill the database as the crash left it
// passes PRAGMA integrity_check, the restarted daemon lists every job that got a 201, and in the
// end every accepted job has succeeded (none lost, none stranded `running`).
//
//   node tests/server/test_crashes.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawn, spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {SLOW, TERMINAL, getJSON, listAll, request, sleep, startDaemon, submit, tail, waitAll,
        waitJob} from './lib.mjs';

const SMALL = {'/image/width': 48, '/image/height': 48, '/technique/params/samples': 64};
const JOB = {scene_file: 'sphere_on_plane.json', set: SMALL};
// About 1 s in the release build, and about as long under the sanitizers with a quarter of the
// samples (SLOW): long enough to be caught running at every moment below, and each is rendered
// again after the kill that interrupted it.
const MEDIUM = {scene_file: 'sphere_on_plane.json',
                set: {'/image/width': 320, '/image/height': 320, '/technique/params/samples': 256 / SLOW}};
const COMPARISON = {scene_file: 'cornell_box.json', set: {'/image/width': 160, '/image/height': 120},
                    reference: {samples: 32},
                    candidates: [{technique: 'ssao', backend: 'cpu', params: {samples: [8, 16]}}]};

function integrity(db) {
  const r = spawnSync('sqlite3', [db, 'PRAGMA integrity_check; PRAGMA foreign_key_check;'], {encoding: 'utf8'});
  assert.equal(r.status, 0, r.stderr);
  return r.stdout.trim();
}

// integrity_check of a copy of the database and WAL as the crash left them (opening the original
// would replay the WAL before the restarted daemon's own recovery).
function integrityOfCopy(db) {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-crashcopy-'));
  try {
    for (const s of ['', '-wal']) if (fs.existsSync(db + s)) fs.copyFileSync(db + s, path.join(tmp, `x.db${s}`));
    return integrity(path.join(tmp, 'x.db'));
  } finally {
    fs.rmSync(tmp, {recursive: true, force: true});
  }
}

// Polls the daemon's log, from offset `from`, for `re`; returns the offset after the match.
async function waitLog(d, re, from = 0, ms = 60000 * SLOW) {
  const deadline = Date.now() + ms;
  for (;;) {
    const m = d.log().slice(from).match(re);
    if (m) return from + m.index + m[0].length;
    if (d.exit) throw new Error(`obscurad exited before logging ${re}:\n${tail(d.log())}`);
    if (Date.now() > deadline) throw new Error(`never logged ${re}:\n${tail(d.log())}`);
    await sleep(2);
  }
}

test('kill -9 at eight moments: no accepted job lost or stranded, database intact', async () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-crashes-'));
  const args = ['--checkpoint-jobs', '1'];
  let d = await startDaemon({dir, args});
  const accepted = [];
  const moments = [];
  let ok = false;
  let locker = null;
  const crash = async (moment) => {
    await d.kill9();
    moments.push(moment);
    assert.equal(integrityOfCopy(d.db), 'ok', `database after the kill ${moment}`);
    d = await startDaemon({dir, args});
    const ids = new Set((await listAll(d)).map((j) => j.id));
    const lost = accepted.filter((id) => !ids.has(id));
    assert.deepEqual(lost, [], `accepted jobs lost after the kill ${moment}`);
    console.log(`# kill -9 ${moment}: ${accepted.length} accepted jobs all there`);
  };
  const add = async (body) => {
    const id = await submit(d, body);
    accepted.push(id);
    return id;
  };
  try {
    // 1. Jobs queued behind a running one.
    await add(MEDIUM);
    for (let i = 0; i < 3; i++) await add(JOB);
    await crash('with jobs queued');

    // 2. Just claimed: at the log line of the claim.
    let at = d.log().length;
    const c = await add(JOB);
    await waitLog(d, new RegExp(`job ${c}: queued -> running`), at);
    await crash('at a claim');

    // 3. Mid-render.
    const m = await add(MEDIUM);
    await waitJob(d, m, (j) => j.state === 'running' && j.progress > 0.2, 60000 * SLOW);
    await crash('mid-render');
    await waitAll(d, accepted);

    // 4. Between publish and commit: a write lock held from outside makes the commit wait
    // (SQLITE_BUSY after the busy timeout), with the outputs already renamed into place.
    const p = await add(MEDIUM);
    await waitJob(d, p, (j) => j.state === 'running' && j.progress > 0);
    locker = spawn('sqlite3', [d.db], {stdio: ['pipe', 'ignore', 'ignore']});
    locker.stdin.write('BEGIN IMMEDIATE; UPDATE schema_migrations SET applied_ms = applied_ms;\n');
    const published = path.join(d.resultsDir, String(p));
    const deadline = Date.now() + 60000 * SLOW;
    while (!fs.existsSync(published) && Date.now() < deadline) await sleep(2);
    assert.ok(fs.existsSync(published), 'the outputs were never published');
    assert.equal((await getJSON(d, `/api/v1/jobs/${p}`)).state, 'running');
    await d.kill9();
    locker.stdin.end('ROLLBACK;\n');
    await new Promise((r) => locker.on('exit', r));
    locker = null;
    await crash('between publish and commit');
    await waitAll(d, accepted);

    // 5. While a comparison's metrics are computed: right after its last job succeeded.
    at = d.log().length;
    const r5 = await request(d, 'POST', '/api/v1/comparisons', {body: COMPARISON});
    assert.equal(r5.status, 201, r5.text);
    const cmp = await getJSON(d, `/api/v1/comparisons/${r5.json.id}`);
    const cmpJobs = [...new Set(cmp.candidates.flatMap((x) => [x.job_id, x.reference_job_id]))];
    accepted.push(...cmpJobs);
    const last = Math.max(...cmpJobs);
    await waitLog(d, new RegExp(`job ${last}: running -> succeeded`), at);
    await crash('during metrics');

    // 6. During a comparison insert: the request is in flight, no answer awaited.
    const inflight = request(d, 'POST', '/api/v1/comparisons', {body: COMPARISON}).catch(() => null);
    await sleep(3);
    await crash('during a comparison insert');
    const r6 = await inflight;
    if (r6 && r6.status === 201) accepted.push(...(await getJSON(d, `/api/v1/comparisons/${r6.json.id}`))
      .candidates.flatMap((x) => [x.job_id, x.reference_job_id]));
    // A comparison that made it is whole: every candidate row has its jobs.
    for (const row of spawnSync('sqlite3', [d.db, 'SELECT count(*) FROM comparison_candidates cc LEFT JOIN jobs j ON j.id = cc.job WHERE j.id IS NULL;'],
      {encoding: 'utf8'}).stdout.trim().split('\n')) assert.equal(row, '0');

    // 7. Around a checkpoint: one follows every finished job (--checkpoint-jobs 1) within 250 ms.
    at = d.log().length;
    const k = await add(JOB);
    await waitLog(d, new RegExp(`job ${k}: running -> succeeded`), at);
    await sleep(100);
    await crash('around a checkpoint');

    // 8. During a graceful shutdown: SIGTERM while a job renders, kill -9 once it began stopping.
    const s = await add(MEDIUM);
    await waitJob(d, s, (j) => j.state === 'running');
    at = d.log().length;
    d.proc.kill('SIGTERM');
    await waitLog(d, /stopping/, at);
    await crash('during shutdown');

    const jobs = await waitAll(d, [...new Set(accepted)]);
    for (const j of jobs) assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.state} ${j.error}`);
    const all = await listAll(d);
    assert.deepEqual(all.filter((j) => !TERMINAL.has(j.state)).map((j) => j.id), [], 'stranded jobs');
    // Every comparison candidate gets its metrics (recomputed at start after the kill).
    const cmpDone = await getJSON(d, `/api/v1/comparisons/${r5.json.id}`);
    for (const x of cmpDone.candidates) assert.ok(x.metrics, `candidate ${x.index} has no metrics`);
    await d.stopClean();
    assert.equal(integrity(d.db), 'ok');
    assert.equal(moments.length, 8, moments.join(', '));
    ok = true;
  } finally {
    if (locker) locker.kill('SIGKILL');
    if (!ok) {
      await d.kill9();
      console.error(`# obscurad log (kept in ${dir}):\n${tail(d.log())}`);
    } else {
      fs.rmSync(dir, {recursive: true, force: true});
    }
  }
});
