// Ranking in the comparison document (docs/comparisons.md, "Ranking"): the Pareto set counts a
// candidate faster only beyond the run-to-run spreads and more accurate only beyond the
// reference's noise; the timing spread (min/max) is in the API; a reference too noisy to rank
// the candidates is warned about; candidates with a response mapping link the mapped reference
// they were measured against. Timings and metrics that decide anything are seeded into the
// database (constructed figures), so nothing depends on how fast this machine renders.
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import {test} from 'node:test';

import {SLOW, download, getJSON, pngSize, request, sleep, startDaemon, validate} from './lib.mjs';

const SMALL = {'/image/width': 32, '/image/height': 24};

function sqlWrite(db, text) {
  const r = spawnSync('sqlite3', ['-batch', db, text], {encoding: 'utf8'});
  assert.equal(r.status, 0, `sqlite3: ${r.stderr}`);
}

async function getComparison(d, id) {
  const c = await getJSON(d, `/api/v1/comparisons/${id}`);
  validate('Comparison', c);
  return c;
}

async function waitComparison(d, id) {
  const deadline = Date.now() + 120000 * SLOW;
  for (;;) {
    const c = await getComparison(d, id);
    if (c.state !== 'running') return c;
    if (Date.now() > deadline) throw new Error(`comparison ${id} still running`);
    await sleep(30);
  }
}

/** Seeds candidate idx's timed runs (total_ms per run) and metrics (merged into the stored ones). */
function seed(db, id, idx, totals, metrics) {
  const job = `(SELECT job FROM comparison_candidates WHERE comparison = ${id} AND idx = ${idx})`;
  const cases = totals.map((t, k) => `WHEN ${k + 1} THEN ${t}`).join(' ');
  let text = `UPDATE runs SET total_ms = CASE run ${cases} END WHERE job = ${job};`;
  if (metrics) {
    const sets = Object.entries(metrics).map(([k, v]) => `'$.${k}', ${typeof v === 'boolean' ? `json('${v}')` : v}`).join(', ');
    text += `UPDATE comparison_candidates SET metrics = json_set(metrics, ${sets}) WHERE comparison = ${id} AND idx = ${idx};`;
  }
  sqlWrite(db, text);
}

test('Pareto with margins, timing spreads, the noisy-reference warning and the mapped reference', async () => {
  const d = await startDaemon({});
  let d2 = null;
  try {
    // Two hbao configurations (the roles of hbao on Vulkan and on the CPU of a real sweep) and one
    // ssao, which maps the reference through its response.
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, repeats: 3, reference: {samples: 16},
      candidates: [
        {technique: 'hbao', backend: 'cpu', params: {directions: [8, 4], radius: 100}},
        {technique: 'ssao', backend: 'cpu', params: {samples: 8}},
      ]}});
    assert.equal(r.status, 201, r.text);
    const id = r.json.id;
    let c = await waitComparison(d, id);
    assert.equal(c.state, 'succeeded', JSON.stringify(c).slice(0, 1500));
    assert.equal(c.candidates.length, 3);

    // The spread is the fastest and slowest of the timed runs.
    for (const x of c.candidates) {
      const totals = x.timings_ms.runs.map((t) => t.total);
      assert.equal(totals.length, 3);
      assert.equal(x.timings_ms.min.total, Math.min(...totals));
      assert.equal(x.timings_ms.max.total, Math.max(...totals));
    }
    // ssao is compared with the reference mapped through its response: the link is that image,
    // of the candidate's size; hbao's response is the identity, so its raw reference is the one.
    const ssao = c.candidates.find((x) => x.technique === 'ssao');
    assert.notEqual(ssao.response, 'identity');
    assert.ok(ssao.links['reference_mapped.png'], JSON.stringify(ssao.links));
    assert.equal(ssao.links['reference_mapped.png'], `/api/v1/jobs/${ssao.job_id}/outputs/reference_mapped.png`);
    // A recorded output of the candidate's job (size and SHA-256 checked by download).
    const png = (await download(d, await getJSON(d, `/api/v1/jobs/${ssao.job_id}`), 'reference_mapped.png')).body;
    assert.deepEqual(pngSize(png), {width: 32, height: 24});
    const ref = (await request(d, 'GET', ssao.links['reference.png'])).body;
    assert.ok(!png.equals(ref), 'the mapped reference differs from the raw one');
    for (const x of c.candidates.filter((y) => y.technique === 'hbao')) {
      assert.equal(x.response, 'identity');
      assert.equal(x.links['reference_mapped.png'], undefined);
    }
    await d.stopClean();

    // Constructed figures: candidate 0 ("Vulkan") 27 ms median with RMSE 0.08; candidate 1
    // ("CPU") 2.7x faster, RMSE 2e-9 higher; reference noise 0.004. ssao far off in accuracy.
    seed(d.db, id, 0, [25, 27, 30], {rmse: 0.08, ref_noise: 0.004, at_reference_accuracy: false});
    seed(d.db, id, 1, [9, 10, 11], {rmse: 0.080000002, ref_noise: 0.004, at_reference_accuracy: false});
    seed(d.db, id, 2, [3, 4, 5], {rmse: 0.3, ref_noise: 0.004, at_reference_accuracy: false});
    d2 = await startDaemon({dir: d.dir});
    c = await getComparison(d2, id);
    assert.deepEqual(c.candidates.map((x) => x.pareto), [false, true, true], 'the slower hbao is not starred');
    assert.deepEqual(c.pareto, [2, 1]);
    assert.deepEqual(c.candidates[1].timings_ms.min.total, 9);
    assert.deepEqual(c.candidates[1].timings_ms.max.total, 11);
    assert.equal(c.ranking.ref_noise, 0.004);
    assert.equal(c.ranking.ties_within_noise, 1, 'the two hbao RMSEs lie within the noise');
    assert.equal(c.ranking.at_reference_accuracy, 0);
    assert.equal(c.ranking.noisy_reference, false, 'RMSEs spread 0.08 to 0.3 against noise 0.004');
    assert.equal(c.ranking.warning, null);
    await d2.stopClean();

    // Overlapping spreads: neither hbao is faster beyond them, and equal within the noise: both
    // stay optimal.
    seed(d.db, id, 0, [9.5, 10.5, 12]);
    d2 = await startDaemon({dir: d.dir});
    c = await getComparison(d2, id);
    assert.deepEqual(c.candidates.map((x) => x.pareto), [true, true, true]);
    await d2.stopClean();

    // A noisy reference: hbao at reference accuracy (RMSE below twice the noise): warned, and
    // the noise is named.
    seed(d.db, id, 0, [25, 27, 30], {rmse: 0.05, ref_noise: 0.04, at_reference_accuracy: true});
    d2 = await startDaemon({dir: d.dir});
    c = await getComparison(d2, id);
    assert.equal(c.ranking.noisy_reference, true);
    assert.equal(c.ranking.at_reference_accuracy, 1);
    assert.equal(c.ranking.ref_noise, 0.04);
    assert.match(c.ranking.warning, /too noisy to rank.*1 of 3 are at reference accuracy.*0\.04.*more samples/);
    await d2.stopClean();

    // Noise comparable to the spread of the RMSEs (none at reference accuracy): warned too.
    seed(d.db, id, 0, [25, 27, 30], {rmse: 0.30, ref_noise: 0.1, at_reference_accuracy: false});
    seed(d.db, id, 1, [9, 10, 11], {rmse: 0.25, ref_noise: 0.1, at_reference_accuracy: false});
    seed(d.db, id, 2, [3, 4, 5], {rmse: 0.38, ref_noise: 0.1, at_reference_accuracy: false});
    d2 = await startDaemon({dir: d.dir});
    c = await getComparison(d2, id);
    assert.equal(c.ranking.noisy_reference, true);
    assert.match(c.ranking.warning, /noise 0\.1 is at least half the spread of their RMSEs \(0\.25 to 0\.38\)/);
    // 0.25 and 0.30 tie within 0.1; 0.30 and 0.38 too.
    assert.equal(c.ranking.ties_within_noise, 2);
    await d2.stopClean();
    d2 = null;
  } finally {
    if (d2) await d2.kill9();
    await d.kill9();
  }
});
