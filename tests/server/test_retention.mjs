// Retention (--keep-jobs): the pass a daemon runs at start deletes the finished jobs beyond the
// newest N with their results directories, keeps a comparison whole until every one of its jobs is
// past the limit, and the counts by state (kept by triggers) follow the deletions.
//
//   node tests/server/test_retention.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {test} from 'node:test';

import {getJSON, listAll, request, sql, startDaemon, submit, waitAll} from './lib.mjs';

const SMALL = {'/image/width': 24, '/image/height': 16};
const small = () => ({scene_file: 'sphere_on_plane.json', set: {...SMALL, '/technique/params/samples': 8}});

async function waitComparison(d, id) {
  for (;;) {
    const c = await getJSON(d, `/api/v1/comparisons/${id}`);
    if (c.state !== 'running') return c;
    await new Promise((r) => setTimeout(r, 30));
  }
}

const exists = (d, id) => fs.existsSync(path.join(d.resultsDir, String(id)));

// The job counts /metrics reports (from job_counts) against a count of the rows themselves.
async function assertCounts(d) {
  const r = await request(d, 'GET', '/metrics');
  assert.equal(r.status, 200);
  for (const state of ['queued', 'running', 'succeeded', 'failed', 'cancelled']) {
    const m = r.text.match(new RegExp(`obscura_jobs\\{state="${state}"\\} (\\d+)`));
    assert.ok(m, `/metrics lacks obscura_jobs{state="${state}"}`);
    const rows = Number(sql(d.db, `SELECT count(*) FROM jobs WHERE state = '${state}'`)[0][0]);
    assert.equal(Number(m[1]), rows, `jobs ${state}`);
  }
}

// A daemon on `dir` with retention, stopped cleanly after fn.
async function restart(dir, keep, fn) {
  const d = await startDaemon({dir, args: ['--keep-jobs', String(keep)]});
  try {
    // The start-up pass runs on its own thread: wait for its log line.
    for (let i = 0; !/retention: removed/.test(d.log()); i++) {
      assert.ok(i < 2000, `no retention pass in the log:\n${d.log()}`);
      await new Promise((r) => setTimeout(r, 10));
    }
    await fn(d);
  } finally {
    await d.stopClean();
  }
}

test('keep-jobs keeps the newest jobs and their files, and comparisons whole', async () => {
  let d = await startDaemon({});
  const dir = d.dir;
  let jobs, cmp, cmpJobs, last;
  try {
    jobs = [];
    for (let i = 0; i < 5; i++) jobs.push(await submit(d, small()));
    await waitAll(d, jobs);
    for (const id of jobs) assert.ok(exists(d, id), `results/${id} before retention`);
    await assertCounts(d);
  } finally {
    await d.stopClean();
  }

  // Five finished jobs, keep 3: the two oldest go with their files, the newest three stay whole.
  await restart(dir, 3, async (d) => {
    const left = (await listAll(d)).map((j) => j.id);
    assert.deepEqual(left, jobs.slice(2).reverse());
    for (const id of jobs.slice(0, 2)) {
      assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 404);
      assert.ok(!exists(d, id), `results/${id} should be gone`);
    }
    for (const id of jobs.slice(2)) {
      const j = await getJSON(d, `/api/v1/jobs/${id}`);
      assert.equal(j.state, 'succeeded');
      assert.ok(j.outputs.length > 0);
      for (const o of j.outputs) {
        const r = await request(d, 'GET', `/api/v1/jobs/${id}/outputs/${o.name}`);
        assert.equal(r.status, 200, `${id}/${o.name}`);
      }
    }
    await assertCounts(d);
    // A comparison of three jobs, then one more job: with 3 kept, the comparison's oldest job is
    // past the limit but its others are not, so the comparison stays whole.
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, reference: {samples: 16},
      candidates: [{technique: 'hbao', backend: 'cpu', params: {steps: [2, 4]}}]}});
    assert.equal(r.status, 201, r.text);
    cmp = r.json.id;
    const c = await waitComparison(d, cmp);
    cmpJobs = [...c.references.map((x) => x.job_id), ...c.candidates.map((x) => x.job_id)];
    assert.equal(cmpJobs.length, 3);
    last = await submit(d, small());
    await waitAll(d, [last]);
  });

  await restart(dir, 3, async (d) => {
    const left = (await listAll(d)).map((j) => j.id).sort((a, b) => a - b);
    assert.deepEqual(left, [...cmpJobs, last].sort((a, b) => a - b));
    assert.equal((await request(d, 'GET', `/api/v1/comparisons/${cmp}`)).status, 200);
    for (const id of cmpJobs) assert.ok(exists(d, id), `results/${id} of the kept comparison`);
    for (const id of jobs) assert.ok(!exists(d, id), `results/${id} should be gone`);
    await assertCounts(d);
  });

  // Keep 1: every job of the comparison is past the limit now, so it goes whole.
  await restart(dir, 1, async (d) => {
    assert.deepEqual((await listAll(d)).map((j) => j.id), [last]);
    assert.equal((await request(d, 'GET', `/api/v1/comparisons/${cmp}`)).status, 404);
    assert.equal(Number(sql(d.db, 'SELECT count(*) FROM comparison_candidates')[0][0]), 0);
    for (const id of cmpJobs) assert.ok(!exists(d, id), `results/${id} should be gone`);
    assert.ok(exists(d, last));
    for (const t of ['outputs', 'runs']) {
      const n = sql(d.db, `SELECT count(*) FROM ${t} WHERE ${t === 'outputs' ? 'job_id' : 'job'} <> ${last}`);
      assert.equal(Number(n[0][0]), 0, `${t} rows of pruned jobs`);
    }
    await assertCounts(d);
  });
  fs.rmSync(dir, {recursive: true, force: true});
});
