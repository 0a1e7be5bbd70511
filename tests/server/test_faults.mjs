// Environment faults on real file systems: a results directory that is full or read-only, a
// database disk that fills during a render, a database deleted or replaced while the daemon runs,
// and database pages overwritten. Each fault must pause the lanes (no job fails for it, none stays
// `running` with nothing rendering it), show in GET /api/v1/health and /metrics, refuse new work
// where the database itself is gone, and clear by itself where the disk recovers. A job whose
// outputs alone do not fit the free space is not such a fault: it fails after bounded tries.
//
// Full and read-only disks are small tmpfs mounts (`mount -t tmpfs`, `mount -o remount,ro`), so
// this needs root with CAP_SYS_ADMIN; without it those subtests are skipped with the reason.
//
//   node tests/server/test_faults.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {SLOW, getJSON, listAll, request, sleep, startDaemon, submit, tail, validate, waitAll,
        waitJob} from './lib.mjs';

const SETS = {'/image/width': 48, '/image/height': 48, '/technique/params/samples': 64};
const JOB = {scene_file: 'sphere_on_plane.json', set: SETS};
// About 3 s in the release build (with its standard errors), and about as long in a sanitizer
// build (a quarter of the samples): long enough to fill a disk while it renders.
const LONG = {scene_file: 'sphere_on_plane.json',
              set: {'/image/width': 512, '/image/height': 512, '/technique/params/samples': 128 / SLOW}};
// The fault probes run on the wall clock (1 s, then doubling): a quiet wait spans several of them
// whatever the build.
const PROBES_MS = 2500;

function run(cmd, args) {
  return spawnSync(cmd, args, {encoding: 'utf8'});
}

// Mounts a tmpfs of `size` at dir; returns null, or why it cannot (the subtest is then skipped).
function mountTmpfs(dir, size) {
  fs.mkdirSync(dir, {recursive: true});
  const r = run('mount', ['-t', 'tmpfs', '-o', `size=${size}`, 'tmpfs', dir]);
  return r.status === 0 ? null : `mount -t tmpfs failed (${(r.stderr || '').trim() || r.status}): needs root with CAP_SYS_ADMIN`;
}

function umount(dir) {
  for (let i = 0; i < 20; i++) {
    if (run('umount', [dir]).status === 0) return;
    spawnSync('sleep', ['0.1']);
  }
  run('umount', ['-l', dir]);
}

function remount(dir, mode) {
  const r = run('mount', ['-o', `remount,${mode}`, dir]);
  assert.equal(r.status, 0, `remount ${mode} ${dir}: ${r.stderr}`);
}

// Fills the file system of dir up to the last page; returns the filler's path.
function fill(dir) {
  const f = path.join(dir, '.filler');
  const fd = fs.openSync(f, 'w');
  for (const size of [1 << 20, 1 << 16, 4096, 1]) {
    const buf = Buffer.alloc(size, 0x55);
    try {
      for (;;) fs.writeSync(fd, buf);
    } catch (e) {
      if (e.code !== 'ENOSPC') throw e;
    }
  }
  fs.closeSync(fd);
  return f;
}

function integrity(db) {
  const r = run('sqlite3', [db, 'PRAGMA integrity_check;']);
  assert.equal(r.status, 0, r.stderr);
  return r.stdout.trim();
}

async function health(d) {
  const r = await request(d, 'GET', '/api/v1/health');
  assert.ok(r.json, `health: ${r.status} ${r.text}`);
  validate('Health', r.json);
  return {status: r.status, ...r.json};
}

// Polls health until pred(h) holds; returns it.
async function waitHealth(d, pred, what, ms = 20000 * SLOW) {
  const deadline = Date.now() + ms;
  let h;
  for (;;) {
    h = await health(d);
    if (pred(h)) return h;
    if (Date.now() > deadline) throw new Error(`health never ${what}: ${JSON.stringify(h)}`);
    await sleep(50);
  }
}

const faultOf = (h, kind) => h.faults.find((f) => f.kind === kind);

async function states(d) {
  return (await listAll(d)).map((j) => `${j.id}:${j.state}`);
}

async function assertNoneFailed(d) {
  const jobs = await listAll(d);
  const bad = jobs.filter((j) => j.state === 'failed' || j.state === 'cancelled');
  assert.deepEqual(bad.map((j) => `${j.id} ${j.error}`), [], 'a job failed because of the fault');
}

// Runs fn(dir) with a fresh test directory; the directory (and any mount under it, through
// `mounts`) goes afterwards; a failing fn keeps the daemon log in the error output.
async function inDir(fn) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-faults-'));
  const mounts = [];
  const daemons = [];
  let ok = false;
  try {
    await fn(dir, mounts, daemons);
    ok = true;
  } finally {
    for (const d of daemons) {
      if (!d.exit) await d.kill9();
      if (!ok) console.error(`# obscurad log:\n${tail(d.log())}`);
    }
    for (const m of mounts.reverse()) umount(m);
    if (ok) fs.rmSync(dir, {recursive: true, force: true});
    else console.error(`# kept ${dir}`);
  }
}

async function metric(d, name) {
  const r = await request(d, 'GET', '/metrics');
  assert.equal(r.status, 200);
  const m = r.text.match(new RegExp(`^${name.replace(/[{}"]/g, (c) => `\\${c}`)} (\\S+)$`, 'm'));
  return m ? Number(m[1]) : undefined;
}

// A results directory fault while jobs are queued: the lanes pause (one worker may hold a finished
// render), nothing fails, and once the fault is cleared every job succeeds.
async function resultsFault(t, makeFault, clearFault, code) {
  await inDir(async (dir, mounts, daemons) => {
    const data = path.join(dir, 'data');
    const why = mountTmpfs(data, '16m');
    if (why) return t.skip(why);
    mounts.push(data);
    const d = await startDaemon({dir});
    daemons.push(d);
    assert.equal((await health(d)).status, 'ok');
    makeFault(data);
    const ids = [];
    for (let i = 0; i < 4; i++) ids.push(await submit(d, {...JOB, label: `fault ${i}`}));
    const h = await waitHealth(d, (x) => faultOf(x, 'results'), 'reporting the results fault');
    assert.equal(h.status, 'degraded');
    assert.equal(h.status, 'degraded');
    const f = faultOf(h, 'results');
    assert.equal(f.code, code, JSON.stringify(f));
    assert.equal(f.severity, 'degraded');
    assert.equal(f.path, d.resultsDir);
    assert.ok(f.next_retry && Date.parse(f.next_retry) >= Date.parse(f.since), JSON.stringify(f));
    assert.equal(h.lanes_paused, true);
    assert.equal(await metric(d, 'obscura_fault{kind="results"}'), 1);
    // Several probes' worth of time: still nothing failed, and at most the one job whose render
    // was done when the fault was met is running (held by its worker, never orphaned).
    await sleep(PROBES_MS);
    await assertNoneFailed(d);
    const jobs = await listAll(d);
    const running = jobs.filter((j) => j.state === 'running');
    assert.ok(running.length <= 1, `running: ${await states(d)}`);
    const h2 = await health(d);
    assert.equal(h2.paused, running.length, JSON.stringify(h2));
    const f2 = faultOf(h2, 'results');
    assert.ok(f2.probes >= 1, 'the fault is probed');
    // Back-off doubling from 1 s: after p failed probes the next one is at least
    // 1 + 2 + ... + 2^p s after the fault was raised.
    const waited = Date.parse(f2.next_retry) - Date.parse(f2.since);
    assert.ok(waited >= (2 ** (f2.probes + 1) - 1) * 1000 - 5, `next retry ${waited} ms after ${f2.probes} probes`);
    clearFault(data);
    const done = await waitAll(d, ids);
    for (const j of done) {
      assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.state} ${j.error}`);
      assert.equal(j.attempts, 1, `job ${j.id}: the fault used up an attempt`);
      assert.ok(j.outputs.length >= 4);
    }
    const h3 = await health(d);
    assert.equal(h3.status, 'ok');
    assert.ok(h3.recent_faults.some((x) => x.kind === 'results'), JSON.stringify(h3));
    assert.equal(await metric(d, 'obscura_fault{kind="results"}'), 0);
    assert.equal(await metric(d, 'obscura_faults_total{kind="results"}'), 1);
    await d.stopClean();
    assert.equal(integrity(d.db), 'ok');
  });
}

test('results directory full while jobs are queued', async (t) => {
  let filler;
  await resultsFault(t, (data) => (filler = fill(data)), () => fs.rmSync(filler), 'ENOSPC');
});

test('results directory read-only while jobs are queued', async (t) => {
  await resultsFault(t, (data) => remount(data, 'ro'), (data) => remount(data, 'rw'), 'EROFS');
});

// Outputs that alone do not fit what the disk has free, while smaller files still do: not a fault
// of the environment (the lanes would wait for it to clear, and it never would), so the job keeps
// its render for a few bounded tries and then fails saying why, while the other jobs go on.
test('a job whose outputs do not fit the free space fails with that reason; the others run', async (t) => {
  await inDir(async (dir, mounts, daemons) => {
    const data = path.join(dir, 'data');
    const why = mountTmpfs(data, '1m');
    if (why) return t.skip(why);
    mounts.push(data);
    const d = await startDaemon({dir, workers: 2, args: ['--output-space-retries', '2']});
    daemons.push(d);
    // hbao at 1024 x 1024: its EXR alone is megabytes; the small jobs' files are kilobytes.
    const big = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'hbao', backend: 'cpu'},
                                 set: {'/image/width': 1024, '/image/height': 1024}, label: 'too big'});
    const small = [];
    for (let i = 0; i < 3; i++) small.push(await submit(d, {...JOB, label: `small ${i}`}));
    // Waits of 1 and 2 s, then the verdict: bounded, whatever the disk does meanwhile.
    const b = await waitJob(d, big, undefined, 30000 * SLOW);
    assert.equal(b.state, 'failed', JSON.stringify(b));
    assert.match(b.error, /^its outputs do not fit the free space of the results disk \(ENOSPC, [\d.e+-]+ MB free after 3 tries over \d+ s, while smaller files could still be written\)/);
    assert.ok(!b.error.includes(dir), `the error names the server's directories: ${b.error}`);
    assert.equal(b.attempts, 1);
    assert.deepEqual(b.outputs, []);
    const log = (await request(d, 'GET', `/api/v1/jobs/${big}/log`)).json.lines.join('\n');
    assert.match(log, /try 2 of 3 in 1 s; the other jobs go on/);
    assert.match(log, /try 3 of 3 in 2 s/);
    for (const j of await waitAll(d, small)) assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.error}`);
    // No fault was raised: the lanes never paused for this job.
    const h = await health(d);
    assert.equal(h.status, 'ok', JSON.stringify(h));
    assert.deepEqual(h.faults, []);
    assert.equal(await metric(d, 'obscura_faults_total{kind="results"}'), 0);
    assert.deepEqual(fs.readdirSync(d.resultsDir).filter((f) => f.startsWith('.tmp-')), [], 'staging left behind');
    await d.stopClean();
  });
});

test('database disk fills during a render: the job is not stranded', async (t) => {
  await inDir(async (dir, mounts, daemons) => {
    const dbfs = path.join(dir, 'dbfs');
    const why = mountTmpfs(dbfs, '8m');
    if (why) return t.skip(why);
    mounts.push(dbfs);
    const db = path.join(dbfs, 'obscura.db');
    // A checkpoint after every job truncates the WAL, so the next commit must grow a file.
    const d = await startDaemon({dir, args: ['--db', db, '--checkpoint-jobs', '1']});
    daemons.push(d);
    const first = await submit(d, JOB);
    await waitAll(d, [first]);
    // The checkpoint after it: the WAL is empty, so the next commit must grow it.
    const wal = `${db}-wal`;
    const deadline = Date.now() + 10000 * SLOW;
    while (fs.statSync(wal).size > 0 && Date.now() < deadline) await sleep(20);
    assert.equal(fs.statSync(wal).size, 0, 'no checkpoint after the first job');
    const id = await submit(d, LONG);
    const queued = await submit(d, JOB);
    await waitJob(d, id, (j) => j.state === 'running' && j.progress > 0);
    // The daemon is stopped while the disk fills, so the render cannot end and commit before the
    // disk is full, however fast this build renders.
    d.proc.kill('SIGSTOP');
    let filler;
    try {
      filler = fill(dbfs);
    } finally {
      d.proc.kill('SIGCONT');
    }
    // The render ends, its outputs are published, the commit meets the full disk: the worker
    // holds the job (health counts it paused) and the fault shows.
    // The render itself takes seconds, many more on a loaded machine: wait for its end generously.
    const h = await waitHealth(d, (x) => faultOf(x, 'database') && x.paused === 1, 'reporting the database fault',
                               120000 * SLOW);
    assert.equal(h.status, 'degraded');
    assert.match(faultOf(h, 'database').message, /full/i);
    const j = (await listAll(d)).find((x) => x.id === id);
    // Still `running` in the database, but held by its worker: health counts it as paused. A retry
    // of the commit can find room before this read (the failed attempt's log frames are reused),
    // and then the outcome is recorded: never failed, never stranded.
    assert.ok(['running', 'succeeded'].includes(j.state), JSON.stringify(j));
    assert.match(d.log(), new RegExp(`job ${id}: cannot record the outcome yet`));
    await sleep(1500);
    await assertNoneFailed(d);
    fs.rmSync(filler);
    const [jl, jq] = await waitAll(d, [id, queued]);
    assert.equal(jl.state, 'succeeded', JSON.stringify(jl));
    assert.equal(jl.attempts, 1);
    assert.equal(jq.state, 'succeeded', JSON.stringify(jq));
    await waitHealth(d, (x) => x.status === 'ok', 'ok again');
    await d.stopClean();
    assert.equal(integrity(db), 'ok');
  });
});

// Deleted with its -wal and -shm, or alone (the old log and index then still lie at their names
// beside the written-back copy, and must not be read into it).
for (const [what, suffixes] of [['with its log', ['', '-wal', '-shm']], ['alone', ['']]]) {
test(`database deleted ${what} while running: written back, every accepted job survives a restart`, async () => {
  await inDir(async (dir, mounts, daemons) => {
    let d = await startDaemon({dir, workers: 1});
    daemons.push(d);
    const ids = [await submit(d, LONG)];
    for (let i = 0; i < 3; i++) ids.push(await submit(d, JOB));
    await waitJob(d, ids[0], (j) => j.state === 'running');
    for (const s of suffixes) fs.rmSync(d.db + s, {force: true});
    const t0 = Date.now();
    const h = await waitHealth(d, (x) => (x.faults.concat(x.recent_faults)).some((f) => f.kind === 'database_lost'),
                               'reporting the lost database', 10000 * SLOW);
    console.log(`# deletion noticed in ${Date.now() - t0} ms: ${h.status}`);
    await waitHealth(d, (x) => x.status === 'ok', 'ok again');
    assert.ok(fs.existsSync(d.db), 'the database was not written back');
    assert.match(d.log(), /wrote the open database back to/);
    assert.ok(await metric(d, 'obscura_faults_total{kind="database_lost"}') >= 1);
    // Accepting again (on the restored file), and the jobs run to the end.
    await waitHealth(d, (x) => x.status === 'ok', 'ok again');
    ids.push(await submit(d, JOB));
    const done = await waitAll(d, ids);
    for (const j of done) assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.error}`);
    await d.stop();
    assert.equal(integrity(d.db), 'ok');
    d = await startDaemon({dir});
    daemons.push(d);
    const after = await listAll(d);
    assert.deepEqual(after.map((j) => j.id).sort((a, b) => a - b), ids, 'an accepted job was lost');
    assert.ok(after.every((j) => j.state === 'succeeded'), await states(d));
    await d.stopClean();
  });
});
}

test('database replaced while running: work refused, own copy written aside', async () => {
  await inDir(async (dir, mounts, daemons) => {
    let d = await startDaemon({dir});
    daemons.push(d);
    const ids = [];
    for (let i = 0; i < 3; i++) ids.push(await submit(d, JOB));
    await waitAll(d, ids);
    for (const s of ['', '-wal', '-shm']) fs.rmSync(d.db + s, {force: true});
    fs.writeFileSync(d.db, 'not the database\n');
    // The fault shows at once (work is refused first); its action names the copy once written.
    const h = await waitHealth(d, (x) => x.status === 'error' && faultOf(x, 'database_lost') &&
                               /recovered-/.test(faultOf(x, 'database_lost').action || ''),
                               'error with the copy named', 10000 * SLOW);
    assert.equal(h.status, 'error');
    const f = faultOf(h, 'database_lost');
    assert.ok(f, JSON.stringify(h));
    assert.match(f.action, /recovered-/);
    const r = await request(d, 'POST', '/api/v1/jobs', {body: JOB});
    assert.equal(r.status, 503, r.text);
    assert.match(r.json.error, /deleted or replaced/);
    const rc = await request(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'sphere_on_plane.json', set: SETS,
      candidates: [{technique: 'rt_ao'}]}});
    assert.equal(rc.status, 503, rc.text);
    await d.stop();
    const copies = fs.readdirSync(dir).filter((n) => n.startsWith('obscura.db.recovered-'));
    assert.equal(copies.length, 1, fs.readdirSync(dir).join(' '));
    // What the action says: put the copy in place and start again.
    fs.renameSync(path.join(dir, copies[0]), d.db);
    assert.equal(integrity(d.db), 'ok');
    d = await startDaemon({dir});
    daemons.push(d);
    const after = await listAll(d);
    assert.deepEqual(after.map((j) => j.id).sort((a, b) => a - b), ids);
    assert.equal((await health(d)).status, 'ok');
    await d.stopClean();
  });
});

test('database pages overwritten: quick_check notices, work refused', async () => {
  await inDir(async (dir, mounts, daemons) => {
    const d = await startDaemon({dir, args: ['--db-check-seconds', '1', '--checkpoint-jobs', '1']});
    daemons.push(d);
    const ids = [];
    for (let i = 0; i < 6; i++) ids.push(await submit(d, {...JOB, label: 'x'.repeat(200)}));
    await waitAll(d, ids);
    // Every page in the main file (the checkpoint after the last job emptied the WAL).
    const deadline = Date.now() + 10000 * SLOW;
    while (fs.existsSync(`${d.db}-wal`) && fs.statSync(`${d.db}-wal`).size > 0 && Date.now() < deadline) await sleep(50);
    const pages = fs.statSync(d.db).size / 4096;
    assert.ok(pages >= 6, `only ${pages} pages`);
    const from = Math.floor(pages / 3);
    const r = run('dd', ['if=/dev/urandom', `of=${d.db}`, 'bs=4096', `seek=${from}`, `count=${Math.max(2, Math.floor(pages / 3))}`,
                         'conv=notrunc']);
    assert.equal(r.status, 0, r.stderr);
    const h = await waitHealth(d, (x) => x.status === 'error', 'error', 15000 * SLOW);
    const f = faultOf(h, 'database_corrupt');
    assert.ok(f, JSON.stringify(h));
    assert.ok(f.message.length > 20, f.message);
    assert.equal(h.status, 'error');
    const p = await request(d, 'POST', '/api/v1/jobs', {body: JOB});
    assert.equal(p.status, 503, p.text);
    assert.match(p.json.error, /quick_check/);
    assert.equal(await metric(d, 'obscura_fault{kind="database_corrupt"}'), 1);
    await d.kill9();
  });
});

test('start on read-only disks: a results fault from the start, a database that cannot open is named', async (t) => {
  await inDir(async (dir, mounts, daemons) => {
    const data = path.join(dir, 'data');
    const why = mountTmpfs(data, '8m');
    if (why) return t.skip(why);
    mounts.push(data);
    fs.mkdirSync(path.join(data, 'results'));
    remount(data, 'ro');
    const d = await startDaemon({dir});
    daemons.push(d);
    const h = await health(d);
    assert.equal(h.status, 'degraded', JSON.stringify(h));
    assert.equal(faultOf(h, 'results').code, 'EROFS');
    const id = await submit(d, JOB);
    await sleep(1500);
    assert.equal((await getJSON(d, `/api/v1/jobs/${id}`)).state, 'queued', 'claimed while the results directory is read-only');
    remount(data, 'rw');
    const [j] = await waitAll(d, [id]);
    assert.equal(j.state, 'succeeded', JSON.stringify(j));
    await d.stopClean();
    // The database on a read-only file system: the daemon does not start, and says which file.
    remount(data, 'ro');
    const db = path.join(data, 'obscura.db');
    await assert.rejects(startDaemon({dir, args: ['--db', db]}), (e) => {
      assert.match(e.message, /exited/);
      assert.ok(e.message.includes(db), e.message);
      return true;
    });
    remount(data, 'rw');
  });
});
