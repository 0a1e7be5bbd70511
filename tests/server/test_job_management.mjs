// Job management through the API: comparison_id on the jobs of a comparison, a comparison deleted
// as a whole (its jobs and their output directories; 409 while one runs), and retrying a failed or
// cancelled job (the same job back in the queue, 409 for other states), and the document a clone
// starts from, and each job's log.
//
//   node tests/server/test_job_management.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {test} from 'node:test';

import {OBSCURA, SCENES_DIR, getJSON, getJob, request, submit, validate, waitJob, withDaemon} from './lib.mjs';

const SMALL = {'/image/width': 24, '/image/height': 16};
const small = (extra = {}) => ({scene_file: 'sphere_on_plane.json', set: {...SMALL, '/technique/params/samples': 8}, ...extra});
// Runs long enough to be cancelled while running; every test cancels it.
const BLOCKER = {scene_file: 'cornell_box.json', set: {...SMALL, '/technique/params/samples': 65536}, priority: 100};

async function waitComparison(d, id) {
  for (;;) {
    const c = await getJSON(d, `/api/v1/comparisons/${id}`);
    if (c.state !== 'running') return c;
    await new Promise((r) => setTimeout(r, 30));
  }
}

test('comparison_id on jobs and deleting a comparison as a whole', async () => {
  await withDaemon({}, async (d) => {
    const plain = await submit(d, small());
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, reference: {samples: 16},
      candidates: [{technique: 'hbao', backend: 'cpu', params: {steps: [2, 4]}}]}});
    assert.equal(r.status, 201, r.text);
    const cid = r.json.id;
    let c = await getJSON(d, `/api/v1/comparisons/${cid}`);
    const jobIds = [...c.references.map((x) => x.job_id), ...c.candidates.map((x) => x.job_id)];
    assert.equal(jobIds.length, 3);
    // The refusal while it runs is the next test's, which holds the jobs back with a blocker: here
    // they may all finish before a request could see them running.
    c = await waitComparison(d, cid);
    await waitJob(d, plain);
    for (const id of jobIds) {
      const j = await getJob(d, id);
      validate('Job', j);
      assert.equal(j.comparison_id, cid);
      assert.equal(j.links.comparison, `/api/v1/comparisons/${cid}`);
    }
    const pj = await getJob(d, plain);
    assert.equal(pj.comparison_id, null);
    assert.equal(pj.links.comparison, undefined);
    const list = await getJSON(d, '/api/v1/jobs?limit=10');
    validate('JobList', list);
    assert.deepEqual(list.jobs.map((j) => j.comparison_id), [cid, cid, cid, null]);
    // One job of it alone still cannot be deleted.
    assert.equal((await request(d, 'DELETE', `/api/v1/jobs/${jobIds[1]}`)).status, 409);
    for (const id of jobIds) assert.ok(fs.existsSync(path.join(d.dataDir, 'results', String(id))), `results/${id}`);
    const del = await request(d, 'DELETE', `/api/v1/comparisons/${cid}`);
    assert.equal(del.status, 204, del.text);
    assert.equal((await request(d, 'GET', `/api/v1/comparisons/${cid}`)).status, 404);
    for (const id of jobIds) {
      assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 404);
      assert.ok(!fs.existsSync(path.join(d.dataDir, 'results', String(id))), `results/${id} removed`);
    }
    assert.equal((await getJob(d, plain)).state, 'succeeded');
    assert.equal((await request(d, 'DELETE', `/api/v1/comparisons/${cid}`)).status, 404);
    assert.equal((await request(d, 'DELETE', `/api/v1/comparisons/${cid}.csv`)).status, 405);
  });
});

test('a running comparison refuses deletion', async () => {
  await withDaemon({}, async (d) => {
    const blocker = await submit(d, BLOCKER);
    await waitJob(d, blocker, (j) => j.state === 'running');
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, reference: {samples: 16},
      candidates: [{technique: 'hbao', backend: 'cpu'}]}});
    assert.equal(r.status, 201, r.text);
    const busy = await request(d, 'DELETE', `/api/v1/comparisons/${r.json.id}`);
    assert.equal(busy.status, 409, busy.text);
    validate('Error', busy.json);
    assert.equal((await getJSON(d, `/api/v1/comparisons/${r.json.id}`)).id, r.json.id);
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${blocker}/cancel`)).status, 202);
  });
});

test('retry puts a cancelled or failed job back in the queue', async () => {
  await withDaemon({}, async (d) => {
    const blocker = await submit(d, BLOCKER);
    await waitJob(d, blocker, (j) => j.state === 'running');
    const id = await submit(d, small({label: 'again'}));
    // Queued: not retryable.
    let r = await request(d, 'POST', `/api/v1/jobs/${id}/retry`);
    assert.equal(r.status, 409, r.text);
    validate('Error', r.json);
    assert.match(r.json.error, /queued/);
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${id}/cancel`)).status, 202);
    assert.equal((await getJob(d, id)).state, 'cancelled');
    r = await request(d, 'POST', `/api/v1/jobs/${id}/retry`);
    assert.equal(r.status, 202, r.text);
    validate('Job', r.json);
    assert.equal(r.json.id, id);
    assert.equal(r.json.state, 'queued');
    assert.equal(r.json.error, null);
    assert.equal(r.json.cancel_requested, false);
    assert.equal(r.json.finished_at, null);
    assert.equal(r.json.label, 'again');
    assert.equal(r.json.links.retry, `/api/v1/jobs/${id}/retry`);
    // The blocker, cancelled while running, is retryable too; cancel it again to let id run.
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${blocker}/cancel`)).status, 202);
    const done = await waitJob(d, id);
    assert.equal(done.state, 'succeeded');
    assert.ok(done.outputs.length > 0);
    // One job says where it ran (the machine of its timed render); the list does not.
    const one = await getJSON(d, `/api/v1/jobs/${id}`);
    validate('Job', one);
    assert.ok(one.machine && one.machine.cores >= 1, JSON.stringify(one.machine));
    assert.equal(one.machine.vulkan_device, null);
    assert.deepEqual([one.device.backend, one.device.kind], ['cpu', 'cpu']);
    assert.equal(one.device.label, `cpu · ${one.machine.cpu_model} (${one.machine.cores} threads)`);
    assert.equal(one.choice, null, 'no time budget, no choice');
    // Every millisecond is a stage: load, the render's own and write sum to the total (the
    // accounting, not the timings' values).
    const st = Object.values(one.timings_ms.stages);
    assert.ok(st.every((v) => v >= 0), JSON.stringify(one.timings_ms));
    assert.ok(Math.abs(st.reduce((a, b) => a + b, 0) - one.timings_ms.total) <= 1e-6 * (1 + one.timings_ms.total),
              JSON.stringify(one.timings_ms));
    assert.equal((await getJSON(d, '/api/v1/jobs')).jobs[0].machine, undefined);
    const bj = await waitJob(d, blocker);
    assert.equal(bj.state, 'cancelled');
    // The document a clone starts from: the bundled scene with the set and technique applied.
    const doc = await getJSON(d, `/api/v1/jobs/${id}/document`);
    assert.equal(doc.scene, 'sphere_on_plane.json');
    assert.equal(doc.label, 'again');
    assert.equal(doc.priority, 50);
    assert.equal(doc.document.image.width, 24);
    assert.equal(doc.document.technique.params.samples, 8);
    assert.ok(Array.isArray(doc.document.objects));
    assert.equal((await request(d, 'GET', '/api/v1/jobs/999999/document')).status, 404);
    // Succeeded: 409; unknown: 404; GET: 405.
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${id}/retry`)).status, 409);
    assert.equal((await request(d, 'POST', '/api/v1/jobs/999999/retry')).status, 404);
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}/retry`)).status, 405);
  });
});

test('a failed job is retried with the same document', async () => {
  await withDaemon({args: ['--max-render-seconds', '1', '--no-estimate-render-time']}, async (d) => {
    const id = await submit(d, BLOCKER);
    const failed = await waitJob(d, id);
    assert.equal(failed.state, 'failed');
    assert.match(failed.error, /time limit/);
    const r = await request(d, 'POST', `/api/v1/jobs/${id}/retry`);
    assert.equal(r.status, 202, r.text);
    assert.ok(['queued', 'running'].includes(r.json.state), r.json.state);
    const again = await waitJob(d, id, (j) => j.state !== 'queued');
    assert.ok(again.attempts >= 2, `attempts ${again.attempts}`);
    await waitJob(d, id);
    // The job's log tells the whole story, oldest first.
    const log = await getJSON(d, `/api/v1/jobs/${id}/log`);
    assert.equal(log.job, id);
    const text = log.lines.join('\n');
    for (const re of [/submitted -> queued \(cornell_box\.json, rt_ao/, /queued -> running \(cpu lane, attempt 1\)/,
                      /render time limit of 1 s exceeded/, /running -> failed \(render time limit of 1 s exceeded\)/,
                      /retried by request -> queued/, /queued -> running \(cpu lane, attempt 2\)/]) {
      assert.match(text, re);
    }
    assert.ok(text.indexOf('attempt 1') < text.indexOf('retried') && text.indexOf('retried') < text.indexOf('attempt 2'));
    for (const l of log.lines) assert.match(l, /^\d{4}-\d\d-\d\dT/);
    // A warning of the renderer and the success line of another job.
    const wide = await submit(d, small({set: {...SMALL, '/camera/fov_y': 175}, technique: {name: 'ssao', backend: 'cpu'}}));
    const wj = await waitJob(d, wide);
    assert.equal(wj.state, 'succeeded');
    const wl = (await getJSON(d, `/api/v1/jobs/${wide}/log`)).lines.join('\n');
    assert.match(wl, /warning: camera fov_y 175 degrees/);
    assert.match(wl, /running -> succeeded \(ssao\/cpu 24x16 on \d+ CPU threads?, /);
    // Deleted with the job.
    assert.equal((await request(d, 'DELETE', `/api/v1/jobs/${wide}`)).status, 204);
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${wide}/log`)).status, 404);
    assert.ok(!fs.existsSync(path.join(d.dataDir, 'logs', `${wide}.log`)));
    assert.ok(fs.existsSync(path.join(d.dataDir, 'logs', `${id}.log`)));
  });
});

test('the name of an inline scene: scene_name from the request or the CLI', async () => {
  await withDaemon({}, async (d) => {
    const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, 'sphere_on_plane.json'), 'utf8'));
    doc.image.width = 24;
    doc.image.height = 16;
    const named = await submit(d, {...doc, scene_name: 'my_scene.json', label: 'named'});
    const unnamed = await submit(d, doc);
    const bundled = await submit(d, small());
    let j = await getJob(d, named);
    validate('Job', j);
    assert.deepEqual([j.scene, j.scene_name], ['inline', 'my_scene.json']);
    j = await getJob(d, unnamed);
    assert.deepEqual([j.scene, j.scene_name], ['inline', null]);
    j = await getJob(d, bundled);
    assert.deepEqual([j.scene, j.scene_name], ['sphere_on_plane.json', 'sphere_on_plane.json']);
    assert.equal((await waitJob(d, named)).state, 'succeeded', 'scene_name is not part of the rendered document');
    assert.equal((await getJSON(d, `/api/v1/jobs/${named}/document`)).scene_name, 'my_scene.json');
    // Only for inline documents, 1 to 256 bytes.
    for (const [body, re] of [[small({scene_name: 'x.json'}), /\/scene_name/], [{...doc, scene_name: ''}, /\/scene_name: must be 1 to 256/],
                              [{...doc, scene_name: 'x'.repeat(257)}, /\/scene_name: must be 1 to 256/]]) {
      const r = await request(d, 'POST', '/api/v1/jobs', {body});
      assert.equal(r.status, 422, r.text);
      assert.match(r.json.problems.join('\n'), re);
    }
    // The CLI names the job after its scene file.
    const cli = spawnSync(OBSCURA, ['submit', path.join(SCENES_DIR, 'sphere_on_plane.json'), '--server', d.url,
                                    '--set', '/image/width=24', '--set', '/image/height=16'], {encoding: 'utf8'});
    assert.equal(cli.status, 0, cli.stderr);
    const list = await getJSON(d, '/api/v1/jobs?limit=1');
    assert.deepEqual([list.jobs[0].scene, list.jobs[0].scene_name], ['inline', 'sphere_on_plane.json']);
  });
});
