// Three obscurad sharing one PostgreSQL store (docs/cluster.md), all real: a throwaway PostgreSQL
// on loopback (tests/pg/pg.sh, its own server, since one case restarts it) and three daemons on
// loopback ports, each with its own data directory, node name and one CPU lane, leases of 3 s.
// The cases: a comparison's 60 jobs run once each, shared between nodes; kill -9 of a node
// mid-render (its job re-runs elsewhere after the lease and the back-off); SIGSTOP past the lease
// then SIGCONT (the late result is refused, the job stays the other node's); a cancel through one
// node of a job another renders; one node serving another's outputs; PostgreSQL restarted
// mid-sweep; priorities, per-node exclusion and the work caps across nodes. What the store holds
// is read with psql beside the API.
//
//   node tests/server/test_cluster.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import {after, before, test} from 'node:test';

import {ROOT, download, getJSON, getJob, listAll, request, sleep, startDaemon, submit, tail, validate,
        waitJob} from './lib.mjs';

const PG_SH = path.join(ROOT, 'tests', 'pg', 'pg.sh');
const PG_BIN = process.env.OBSCURA_PG_BIN || '/usr/lib/postgresql/15/bin';
const LEASE_S = 3;
// Per client (all requests come from 127.0.0.1): above what any case but the caps' queues.
const MAX_QUEUED_WORK = 1.3e9;

const scene = (w, samples) => ({scene_file: 'sphere_on_plane.json',
  set: {'/image/width': w, '/image/height': w, '/technique/params/samples': samples}});
const TINY = scene(16, 4);
// About 2 s alone on one lane of a 2-core machine; long enough to act on while it runs.
const SLOW = scene(256, 256);
// About 8 s alone: blockers that stay running until every node has claimed one, however late a
// loaded machine lets a node wake.
const BLOCKER = scene(256, 1024);
// Tens of seconds: only ever cancelled.
const LONG = scene(320, 4096);

let pgDir = null;
let url = null;
const nodes = {};  // name -> daemon (startDaemon's object), replaced when a node restarts
const NAMES = ['node-a', 'node-b', 'node-c'];

function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.once('error', reject);
    s.listen(0, '127.0.0.1', () => {
      const {port} = s.address();
      s.close(() => resolve(port));
    });
  });
}

/** psql against the store; returns the rows as arrays of strings. */
function psql(query) {
  const r = spawnSync('psql', ['-X', '-A', '-t', '-F', '\t', '-v', 'ON_ERROR_STOP=1', '-d', url, '-c', query],
                      {encoding: 'utf8'});
  assert.equal(r.status, 0, `psql ${query}: ${r.stderr}`);
  return r.stdout.split('\n').filter((l) => l !== '').map((l) => l.split('\t'));
}

/** tests/pg/pg.sh start|restart|stop DIR ...; returns its output. */
function pgSh(...argv) {
  const r = spawnSync('sh', [PG_SH, ...argv], {encoding: 'utf8', env: {...process.env, OBSCURA_PG_BIN: PG_BIN}});
  assert.equal(r.status, 0, `pg.sh ${argv.join(' ')}: ${r.stdout}${r.stderr}`);
  return r.stdout;
}

// No render-time estimate: the caps' case submits a job only to weigh on the queue (it is
// cancelled, never rendered), and an estimate learned from runs timed on a loaded machine would
// refuse it before the caps are reached.
const nodeArgs = (name) => ['--node-name', name, '--lease-seconds', String(LEASE_S),
                            '--max-queued-work', String(MAX_QUEUED_WORK), '--no-estimate-render-time'];

async function startNode(name, dir) {
  nodes[name] = await startDaemon({dir, workers: 1, store: url, args: nodeArgs(name)});
  return nodes[name];
}

/** A node that is running and not stopped, other than those named. */
function live(...not) {
  const n = NAMES.find((k) => !not.includes(k) && nodes[k] && !nodes[k].exit && !nodes[k].paused);
  assert.ok(n, 'no live node');
  return nodes[n];
}

async function waitFor(what, fn, ms = 60000) {
  const deadline = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > deadline) throw new Error(`${what}: not within ${ms} ms`);
    await sleep(50);
  }
}

async function waitLog(d, re, ms = 30000) {
  await waitFor(`log of ${d.nodeName} to match ${re}:\n${tail(d.log())}`, () => re.test(d.log()), ms);
}

async function cancelJob(d, id) {
  const r = await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
  assert.ok(r.status === 202 || r.status === 200, `cancel ${id}: ${r.status} ${r.text}`);
}

/** Submits `bodies` through node d and waits until every one is running; returns the jobs. */
async function runningAll(d, bodies) {
  const ids = [];
  for (const b of bodies) ids.push(await submit(d, b));
  const jobs = [];
  for (const id of ids) jobs.push(await waitJob(d, id, (j) => j.state === 'running'));
  return jobs;
}

/** Runs of a job in the store (one row per timed render). */
const runsOf = (id) => Number(psql(`SELECT count(*) FROM runs WHERE job = ${id}`)[0][0]);

before(async () => {
  assert.ok(fs.existsSync(path.join(PG_BIN, 'initdb')), `no PostgreSQL at ${PG_BIN} (Debian postgresql-15)`);
  const base = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-cluster-pg-'));
  fs.chmodSync(base, 0o755);  // pg.sh runs the server as postgres when we are root
  pgDir = path.join(base, 'pg');
  url = pgSh('start', pgDir, String(await freePort())).trim().split('\n').pop();
  assert.match(url, /^postgresql:\/\/.*\/obscura$/);
  // Started one after the other: the first applies the schema under its advisory lock.
  for (const n of NAMES) (await startNode(n)).nodeName = n;
});

after(async () => {
  const failed = [];
  for (const n of NAMES) {
    const d = nodes[n];
    if (!d) continue;
    if (d.paused) d.proc.kill('SIGCONT');
    try {
      await d.stopClean();
      fs.rmSync(d.dir, {recursive: true, force: true});
    } catch (e) {
      failed.push(`${n}: ${e.message}`);
      console.error(`# ${n}'s log (kept in ${d.dir}):\n${tail(d.log())}`);
    }
  }
  if (pgDir) {
    pgSh('stop', pgDir);
    fs.rmSync(path.dirname(pgDir), {recursive: true, force: true});
  }
  assert.deepEqual(failed, [], 'every node stops cleanly');
});

let sweep = null;  // case a's jobs, which case e serves across nodes

test('a comparison posted to one node runs its 60 jobs exactly once, shared between nodes', async () => {
  const a = nodes['node-a'];
  const body = {scene_file: 'sphere_on_plane.json', set: {'/image/width': 24, '/image/height': 24},
                label: 'cluster sweep', repeats: 1, reference: {samples: 16},
                candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: Array.from({length: 59}, (_, i) => i + 1)}}]};
  const r = await request(a, 'POST', '/api/v1/comparisons', {body});
  assert.equal(r.status, 201, r.text);
  validate('ComparisonCreated', r.json);
  assert.deepEqual([r.json.candidates, r.json.references], [59, 1]);
  const cid = r.json.id;
  // Every node lists the comparison at once (one store).
  for (const n of NAMES) {
    const c = await getJSON(nodes[n], `/api/v1/comparisons/${cid}`);
    assert.equal(c.candidates.length, 59, `${n} sees the comparison`);
  }
  const c = await waitFor(`comparison ${cid} finished`, async () => {
    const x = await getJSON(nodes['node-b'], `/api/v1/comparisons/${cid}`);
    return x.state !== 'running' && x;
  });
  validate('Comparison', c);
  assert.equal(c.state, 'succeeded', JSON.stringify(c.candidates.map((x) => [x.state, x.error])));
  assert.ok(c.candidates.every((x) => x.metrics), 'every candidate has its metrics');

  const rows = psql(`SELECT id, state, attempts, node, repeats FROM jobs WHERE comparison = ${cid} ORDER BY id`);
  assert.equal(rows.length, 60, 'the comparison stored 60 jobs');
  assert.deepEqual(rows.filter((x) => x[1] !== 'succeeded' || x[2] !== '1'), [], 'every job succeeded at its first attempt');
  const perNode = {};
  for (const x of rows) perNode[x[3]] = (perNode[x[3]] || 0) + 1;
  // Node A hears of the jobs in-process, the others through the store's wake-up. Sixty jobs of a
  // few tens of milliseconds can all be taken before a node whose worker the loaded machine
  // schedules late gets a turn, so the spread asked here is at least one node beyond the one the
  // comparison was posted to; that every node claims while the others are busy is the cancel
  // case's (three long jobs at once on three one-lane nodes).
  const busy = NAMES.filter((n) => perNode[n]);
  assert.ok(busy.length >= 2 && busy.some((n) => n !== 'node-a'),
            `jobs per node: ${JSON.stringify(perNode)}; the idle nodes' logs:\n` +
            NAMES.filter((n) => !perNode[n]).map((n) => `${n}:\n${nodes[n].log().slice(-3000)}`).join('\n'));
  assert.deepEqual(Object.keys(perNode).filter((n) => !NAMES.includes(n)), [], 'every job names its node');
  // Run once: each job has exactly its timed runs stored, no attempt's runs twice.
  const off = psql(`SELECT j.id, j.repeats, count(r.job) FROM jobs j LEFT JOIN runs r ON r.job = j.id
                    WHERE j.comparison = ${cid} GROUP BY j.id, j.repeats HAVING count(r.job) <> j.repeats`);
  assert.deepEqual(off, [], 'jobs whose stored runs differ from their repeats');
  // The API says the same through any node, with the node that ran each job.
  const mine = (await listAll(nodes['node-c'])).filter((j) => j.comparison_id === cid);
  assert.equal(mine.length, 60, 'node C lists the comparison\'s jobs');
  for (const j of mine) assert.equal(j.node, rows.find((x) => Number(x[0]) === j.id)[3], `job ${j.id}: node as stored`);
  sweep = {cid, rows};
  console.log(`# 60 jobs per node: ${JSON.stringify(perNode)}`);
});

test('a node serves the outputs of jobs another node rendered, byte for byte', async () => {
  assert.ok(sweep, 'needs the sweep of the first case');
  // Each node that rendered a job of the sweep, its outputs served by the next node along.
  const ran = NAMES.filter((n) => sweep.rows.some((x) => x[3] === n));
  for (const from of ran) {
    const via = NAMES[(NAMES.indexOf(from) + 1) % NAMES.length];
    const id = Number(sweep.rows.find((x) => x[3] === from)[0]);
    const job = await getJob(nodes[from], id);
    const own = await download(nodes[from], job, 'ao.png');
    const other = await download(nodes[via], await getJob(nodes[via], id), 'ao.png');
    assert.ok(own.body.equals(other.body), `job ${id} (rendered by ${from}): ao.png from ${via} differs`);
    const exr = await download(nodes[via], job, 'ao.exr');
    assert.ok(exr.body.length > 0);
  }
  // A difference map, on a third node, of outputs two other nodes rendered: both come through the
  // store (the sweep's first case asks for two nodes at least).
  const [na, nb] = ran;
  const third = NAMES.find((n) => n !== na && n !== nb);
  const ja = Number(sweep.rows.find((x) => x[3] === na)[0]);
  const jb = Number(sweep.rows.find((x) => x[3] === nb)[0]);
  const diff = await request(nodes[third], 'GET', `/api/v1/diff?a=${ja}/ao.exr&b=${jb}/ao.exr&channel=ao`);
  assert.equal(diff.status, 200, `diff on ${third} of jobs of ${na} and ${nb}: ${diff.status} ${diff.text}`);
});

test('kill -9 of a node mid-render: the job re-runs elsewhere after the lease and its back-off', async () => {
  const a = nodes['node-a'];
  const [job] = await runningAll(a, [SLOW]);
  const victim = job.node;
  assert.ok(NAMES.includes(victim), `running job's node: ${job.node}`);
  const d = nodes[victim];
  const dir = d.dir;
  await d.kill9();
  const other = live(victim);
  // The reaper of a surviving node requeues it once the lease expired, with run_after ahead.
  const requeued = await waitFor('requeued after the lease', () => {
    const x = psql(`SELECT state, attempts, worker IS NULL, run_after > now(),
                           (extract(epoch FROM run_after) * 1000)::bigint FROM jobs WHERE id = ${job.id}`)[0];
    return x[0] !== 'running' && x;
  }, 30000);
  assert.deepEqual(requeued.slice(0, 4), ['queued', '1', 't', 't'], 'queued, no worker, a back-off still ahead');
  assert.deepEqual(psql(`SELECT node, failures FROM job_node_failures WHERE job = ${job.id}`), [[victim, '1']]);
  const done = await waitJob(other, job.id, undefined, 60000);
  assert.equal(done.state, 'succeeded', done.error);
  assert.notEqual(done.node, victim, 're-run on another node');
  assert.equal(done.attempts, 2);
  // Not claimed again before its back-off ended.
  const started = Number(psql(`SELECT started_ms FROM jobs WHERE id = ${job.id}`)[0][0]);
  assert.ok(started >= Number(requeued[4]), `claimed at ${started}, before run_after ${requeued[4]}`);
  assert.equal(runsOf(job.id), 1, 'one attempt\'s runs stored');
  await download(other, done, 'ao.png');
  // Back with the same name: nothing of its previous boot is running any more.
  (await startNode(victim, dir)).nodeName = victim;
  const h = await getJSON(nodes[victim], '/api/v1/health');
  assert.equal(h.db, 'ok');
  assert.equal((await getJob(nodes[victim], job.id)).state, 'succeeded');
});

test('SIGSTOP past the lease, then SIGCONT: the late result is refused, the job stays the other node\'s', async () => {
  const a = nodes['node-a'];
  const [job] = await runningAll(a, [SLOW]);
  const paused = job.node;
  const d = nodes[paused];
  const logFrom = d.log().length;
  d.proc.kill('SIGSTOP');
  d.paused = true;
  let done;
  try {
    done = await waitJob(live(paused), job.id, (j) => j.state === 'succeeded', 60000);
  } finally {
    d.proc.kill('SIGCONT');
    d.paused = false;
  }
  assert.notEqual(done.node, paused);
  assert.equal(done.attempts, 2);
  // The resumed node learns it lost the job and drops its result: at its first heartbeat (the
  // usual way, the render being still under way) or when the store refuses the finish.
  const gaveUp = new RegExp(`job ${job.id}: (late result refused|lease lost)[^\n]*`);
  await waitFor(`${paused} refuses its late result`, () => gaveUp.test(d.log().slice(logFrom)), 30000);
  console.log(`# ${paused}: ${d.log().slice(logFrom).match(gaveUp)[0]}`);
  const [state, node, attempts] = psql(`SELECT state, node, attempts FROM jobs WHERE id = ${job.id}`)[0];
  assert.deepEqual([state, node, attempts], ['succeeded', done.node, '2'], 'the store keeps the other node\'s result');
  assert.equal(runsOf(job.id), 1, 'one attempt\'s runs stored');
  const after = await getJob(d, job.id);
  assert.equal(after.node, done.node);
  assert.deepEqual(after.outputs.map((o) => o.sha256), done.outputs.map((o) => o.sha256));
  assert.equal((await getJSON(d, '/api/v1/health')).db, 'ok', `${paused} is healthy after SIGCONT`);
});

test('three long jobs run one per node, and a cancel through node A stops the one another node renders', async () => {
  const a = nodes['node-a'];
  const jobs = await runningAll(a, [LONG, LONG, LONG]);
  // Three at once on three one-lane nodes: every node claimed one while the others were busy.
  assert.deepEqual(jobs.map((j) => j.node).sort(), NAMES, 'one long job on each node');
  const target = jobs.find((j) => j.node !== 'node-a');
  assert.ok(target, `one of three runs elsewhere than node-a: ${jobs.map((j) => j.node)}`);
  await cancelJob(a, target.id);
  // Well before the render could end by itself.
  const j = await waitJob(a, target.id, undefined, 20000);
  assert.equal(j.state, 'cancelled', `${j.state}: ${j.error}`);
  assert.equal(j.node, target.node);
  for (const x of jobs) if (x !== target) await cancelJob(a, x.id);
  for (const x of jobs) assert.equal((await waitJob(a, x.id, undefined, 20000)).state, 'cancelled');
  await waitLog(nodes[target.node], new RegExp(`job ${target.id}\\b[^\\n]*cancel`, 'i'));
});

test('PostgreSQL restarted mid-sweep: every node reconnects and the sweep completes', async () => {
  const b = nodes['node-b'];
  const body = {scene_file: 'sphere_on_plane.json', set: {'/image/width': 64, '/image/height': 64},
                label: 'restart sweep', repeats: 1, reference: {samples: 64},
                candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: Array.from({length: 23}, (_, i) => 8 * (i + 1))}}]};
  const r = await request(b, 'POST', '/api/v1/comparisons', {body});
  assert.equal(r.status, 201, r.text);
  const cid = r.json.id;
  await waitFor('a few jobs done', () =>
    Number(psql(`SELECT count(*) FROM jobs WHERE comparison = ${cid} AND state = 'succeeded'`)[0][0]) >= 3);
  pgSh('restart', pgDir);
  const c = await waitFor(`comparison ${cid} finished`, async () => {
    const x = await getJSON(nodes['node-c'], `/api/v1/comparisons/${cid}`);
    return x.state !== 'running' && x;
  }, 120000);
  const rows = psql(`SELECT id, state, error FROM jobs WHERE comparison = ${cid}`);
  assert.equal(rows.length, 24);
  assert.deepEqual(rows.filter((x) => x[1] !== 'succeeded'), [], 'every job of the sweep succeeded');
  assert.equal(c.state, 'succeeded');
  // Each node talks to the restarted server: its health, a job submitted through it, and its lane
  // claims again (three jobs at once on three one-lane nodes run one on each).
  const ids = [];
  for (const n of NAMES) {
    const d = nodes[n];
    assert.equal((await getJSON(d, '/api/v1/health')).db, 'ok', `${n}'s health after the restart`);
    ids.push(await submit(d, SLOW));
  }
  const running = [];
  for (const id of ids) running.push(await waitJob(b, id, (j) => j.state !== 'queued'));
  assert.deepEqual(running.map((j) => j.node).sort(), NAMES, 'every node claims after the restart');
  for (const id of ids) assert.equal((await waitJob(b, id)).state, 'succeeded');
});

test('priorities, per-node exclusion and the work caps hold across nodes', async () => {
  const a = nodes['node-a'], b = nodes['node-b'], c = nodes['node-c'];
  // Every lane busy: what is queued next waits for the claims to choose.
  const blockers = await runningAll(a, [BLOCKER, BLOCKER, BLOCKER]);
  assert.deepEqual(new Set(blockers.map((j) => j.node)).size, 3,
                   `one blocker per node: ${blockers.map((j) => j.node)}`);

  // The work caps count every node's submissions: the blockers went through A, B refuses a job
  // that alone fits under --max-queued-work.
  const big = scene(1000, 1260);
  const workOf = (b) => b.set['/image/width'] * b.set['/image/height'] * b.set['/technique/params/samples'];
  assert.ok(workOf(big) < MAX_QUEUED_WORK && workOf(big) + 3 * workOf(BLOCKER) > MAX_QUEUED_WORK);
  const refused = await request(b, 'POST', '/api/v1/jobs', {body: big});
  assert.equal(refused.status, 429, refused.text);
  validate('Error', refused.json);
  assert.ok(refused.json.problems.some((p) => p.includes('max-queued-work')), refused.text);

  // Priorities: three low jobs, then a high one, through B and C; the first free lane takes it.
  const low = [];
  for (let i = 0; i < 3; i++) low.push(await submit(i % 2 ? c : b, {...TINY, priority: 10}));
  const high = await submit(c, {...TINY, priority: 90});
  // Exclusion: nodes A and B failed `only` three times each, so only C may claim it; `none` is
  // excluded from all three and stays queued while later, lower jobs run.
  const only = await submit(a, {...TINY, priority: 5});
  const none = await submit(a, {...TINY, priority: 5});
  psql(`INSERT INTO job_node_failures (job, node, failures) VALUES
        (${only}, 'node-a', 3), (${only}, 'node-b', 3),
        (${none}, 'node-a', 3), (${none}, 'node-b', 3), (${none}, 'node-c', 3)`);
  const last = await submit(b, {...TINY, priority: 0});
  assert.ok(psql(`SELECT count(*) FROM jobs WHERE id IN (${low}, ${high}, ${only}, ${none}, ${last}) AND state = 'queued'`)[0][0] === '7',
            'all queued behind the blockers');

  for (const x of blockers) assert.equal((await waitJob(a, x.id)).state, 'succeeded');
  const hj = await waitJob(a, high);
  const lj = [];
  for (const id of low) lj.push(await waitJob(a, id));
  for (const l of lj) {
    assert.equal(l.state, 'succeeded');
    assert.ok(Date.parse(hj.started_at) <= Date.parse(l.started_at),
              `high priority started ${hj.started_at}, after low job ${l.id} at ${l.started_at}`);
  }
  const oj = await waitJob(a, only);
  assert.equal(oj.state, 'succeeded');
  assert.equal(oj.node, 'node-c', 'only the node not excluded ran it');
  assert.equal((await waitJob(a, last)).state, 'succeeded');
  const nj = await getJob(a, none);
  assert.equal(nj.state, 'queued', 'a job every node is excluded from is never claimed');
  assert.equal(nj.attempts, 0);
  await cancelJob(a, none);
  assert.equal((await waitJob(a, none)).state, 'cancelled');

  // Nothing active any more: the same job is accepted through B now, and cancelled.
  const ok = await request(b, 'POST', '/api/v1/jobs', {body: big});
  assert.equal(ok.status, 201, ok.text);
  await cancelJob(b, ok.json.id);
  assert.equal((await waitJob(b, ok.json.id)).state, 'cancelled');
});
