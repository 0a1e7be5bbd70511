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

/** RFC 4180 rows (quoted fields may hold commas). */
function parseCsv(text) {
  const rows = [];
  for (const line of text.trim().split('\r\n')) {
    const row = [];
    for (let i = 0; i <= line.length;) {
      let v = '';
      if (line[i] === '"') {
        for (i++; i < line.length; i++) {
          if (line[i] === '"' && line[i + 1] === '"') v += line[i++];
          else if (line[i] === '"') break;
          else v += line[i];
        }
        i++;
      } else {
        const e = line.indexOf(',', i);
        v = line.slice(i, e < 0 ? line.length : e);
        i = e < 0 ? line.length : e;
      }
      row.push(v);
      i++;
    }
    rows.push(row);
  }
  return rows;
}

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
    // Ranked within each reference's group: hbao's two against one reference, ssao against its
    // own (sqrt falloff, mapped through its response).
    assert.equal(c.comparable, false);
    const [hb, ss] = [c.groups.find((g) => g.candidates.includes(0)), c.groups.find((g) => g.candidates.includes(2))];
    assert.deepEqual(hb.candidates, [0, 1]);
    assert.deepEqual(hb.pareto, [1]);
    assert.deepEqual(ss.pareto, [2]);
    assert.equal(hb.ranking.ref_noise, 0.004);
    assert.equal(hb.ranking.ties_within_noise, 1, 'the two hbao RMSEs lie within the noise');
    assert.equal(hb.ranking.at_reference_accuracy, 0);
    // The two hbao RMSEs differ by 2e-9 against noise 0.004, a twentieth of their RMSE 0.08: a
    // tie (above), not a reference too noisy to rank (its noise moves both RMSEs by 0.1 %).
    assert.equal(hb.ranking.noisy_reference, false);
    assert.equal(hb.ranking.warning, null);
    assert.equal(ss.ranking.noisy_reference, false, 'one candidate, RMSE 0.3 against noise 0.004');
    assert.equal(c.ranking.ref_noise, 0.004);
    assert.equal(c.ranking.noisy_reference, false);
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
    assert.match(c.ranking.warning, /^R\d+: the reference is too noisy to rank.*1 of 2 are at reference accuracy.*0\.04.*more samples/);
    await d2.stopClean();

    // Noise comparable to the spread of the RMSEs (none at reference accuracy): warned too.
    seed(d.db, id, 0, [25, 27, 30], {rmse: 0.30, ref_noise: 0.1, at_reference_accuracy: false});
    seed(d.db, id, 1, [9, 10, 11], {rmse: 0.25, ref_noise: 0.1, at_reference_accuracy: false});
    seed(d.db, id, 2, [3, 4, 5], {rmse: 0.38, ref_noise: 0.1, at_reference_accuracy: false});
    d2 = await startDaemon({dir: d.dir});
    c = await getComparison(d2, id);
    assert.equal(c.ranking.noisy_reference, true);
    // Within hbao's group: 0.25 and 0.30 tie within 0.1; ssao's 0.38 is in a group of its own.
    assert.match(c.ranking.warning, /noise 0\.1 is at least half the spread of their RMSEs \(0\.25 to 0\.3\)/);
    assert.equal(c.ranking.ties_within_noise, 1);
    await d2.stopClean();
    d2 = null;
  } finally {
    if (d2) await d2.kill9();
    await d.kill9();
  }
});

// References named by what defines them (docs/comparisons.md, "References"): each reference's
// label, id and definition; each candidate's reference; the Pareto set and ranking within each
// reference's group and the note that errors against different references are not comparable;
// the mapped reference as floats (A - B over it is the error the RMSE sums); the common
// reference every candidate is also measured against; another output (obscurance's W) against
// the reference its technique declares for it; all of it in the CSV; common_reference refused
// with pointers into the request.
test('references labelled and grouped, the mapped reference EXR, the common reference, other outputs', async () => {
  const d = await startDaemon({});
  try {
    const bad = async (common, pointer) => {
      const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
        scene_file: 'cornell_box.json', set: SMALL, common_reference: common,
        candidates: [{technique: 'rt_ao', params: {samples: 4}}]}});
      assert.equal(r.status, 422, r.text);
      assert.ok(r.json.problems.some((p) => p.startsWith(`request: ${pointer}:`)), JSON.stringify(r.json.problems));
    };
    await bad({technique: 'ssao'}, '/common_reference/technique');
    await bad({technique: 'rt_ao', params: {falloff: 'nope'}}, '/common_reference/params/falloff');
    await bad({technique: 'rt_ao', params: {samples: 4}}, '/common_reference/params/samples');
    await bad({technique: 'rt_ao', colour: 1}, '/common_reference/colour');
    assert.equal((await getJSON(d, '/api/v1/comparisons')).comparisons.length, 0, 'nothing stored');

    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, repeats: 1, reference: {samples: 16},
      common_reference: {technique: 'rt_ao', params: {falloff: 'binary', weighting: 'cosine'}, samples: 32},
      candidates: [
        {technique: 'ssao', backend: 'cpu', params: {samples: 8}},
        {technique: 'hbao', backend: 'cpu', params: {directions: 4}},
        {technique: 'rt_ao', backend: 'cpu', params: {samples: [4, 64]}},
        {technique: 'obscurance', backend: 'cpu', params: {samples: 4, light_samples: 1, color_bleeding: false}},
      ]}});
    assert.equal(r.status, 201, r.text);
    const c = await waitComparison(d, r.json.id);
    assert.equal(c.state, 'succeeded', JSON.stringify(c).slice(0, 3000));
    const byTech = Object.fromEntries(c.candidates.map((x) => [x.technique, x]));

    // Every reference: an id, its definition and a label made from it; distinct references have
    // distinct labels, and every candidate names one of them.
    const ids = c.references.map((x) => x.id);
    assert.deepEqual(ids, ids.map((_, k) => `R${k + 1}`));
    assert.equal(new Set(c.references.map((x) => x.label)).size, c.references.length, c.references.map((x) => x.label).join(' | '));
    for (const ref of c.references) {
      assert.ok(ref.label.startsWith(`${ref.technique}: `), ref.label);
      for (const [k, v] of Object.entries(ref.definition)) {
        assert.equal(v, ref.params[k]);
        assert.ok(ref.label.includes(`${k} `), `${ref.label} names ${k}`);
      }
      assert.equal(ref.label.includes('mapped through'), ref.response !== 'identity');
    }
    const ssaoRef = c.references.find((x) => x.id === byTech.ssao.reference.id);
    assert.equal(ssaoRef.definition.falloff, 'sqrt');
    assert.equal(ssaoRef.definition.weighting, 'uniform');
    assert.match(ssaoRef.label, new RegExp(`mapped through ${byTech.ssao.response}$`));
    for (const x of c.candidates) {
      const ref = c.references.find((y) => y.id === x.reference.id);
      assert.equal(x.reference.label, ref.label);
      assert.equal(x.reference.job_id, x.reference_job_id);
      assert.equal(x.reference.response, x.response);
    }

    // Ranked within each reference's group: ssao, hbao and rt_ao have three different references.
    assert.equal(c.comparable, false);
    assert.match(c.note, /not comparable/);
    assert.equal(c.groups.length, new Set(c.candidates.map((x) => x.reference.id)).size);
    const union = [];
    for (const g of c.groups) {
      for (const i of g.candidates) assert.equal(c.candidates[i].reference.id, g.reference);
      assert.ok(g.pareto.length >= 1, 'each group has an optimal candidate');
      union.push(...g.pareto);
      assert.equal(typeof g.ranking.noisy_reference, 'boolean');
    }
    assert.deepEqual([...c.pareto].sort(), union.sort());
    // A group of one candidate: it is optimal.
    for (const g of c.groups.filter((x) => x.candidates.length === 1)) assert.equal(c.candidates[g.candidates[0]].pareto, true);

    // The common reference: every candidate measured against it too, without a response mapping.
    const common = c.references.find((x) => x.id === c.common.reference.id);
    assert.equal(common.params.samples, 32);
    assert.equal(common.definition.falloff, 'binary');
    assert.equal(common.response, 'identity');
    assert.ok(common.roles.includes('common'));
    for (const x of c.candidates) {
      assert.equal(x.common.reference.id, common.id, x.technique);
      assert.ok(Number.isFinite(x.common.metrics.rmse), JSON.stringify(x.common));
    }
    assert.equal(byTech.obscurance.common.metrics.output, 'obscurance', 'W against rt_ao');
    assert.ok(c.common.pareto.length >= 1);
    assert.equal(c.candidates.filter((x) => x.common.pareto).length, c.common.pareto.length);

    // Another output: obscurance's W without bleeding against rt_ao with obscurance's falloff.
    assert.equal(byTech.obscurance.outputs.length, 1);
    const w = byTech.obscurance.outputs[0];
    assert.equal(w.output, 'obscurance');
    assert.equal(w.reference_output, 'ao');
    assert.ok(Number.isFinite(w.metrics.rmse));
    assert.equal(c.references.find((x) => x.id === w.reference.id).technique, 'rt_ao');
    for (const x of c.candidates.filter((y) => y.technique === 'ssao' || y.technique === 'hbao')) assert.deepEqual(x.outputs, []);
    // rt_ao's bent normal against its reference's (the pair rt_ao's descriptor declares): the
    // mean angle between them, smaller with 16 times the samples.
    const angle = (samples) => {
      const x = c.candidates.find((y) => y.technique === 'rt_ao' && y.params.samples === samples);
      assert.equal(x.outputs.length, 1, JSON.stringify(x.outputs));
      const bn = x.outputs[0];
      assert.deepEqual([bn.output, bn.reference_output, bn.reference.id, bn.reference_job_id],
                       ['bent_normal', 'bent_normal', x.reference.id, x.reference_job_id]);
      assert.ok(bn.metrics.angle_deg > 0 && bn.metrics.angle_deg < 90, JSON.stringify(bn.metrics));
      return bn.metrics.angle_deg;
    };
    assert.ok(angle(64) < angle(4) / 2, `${angle(64)} deg at 64 samples against ${angle(4)} at 4`);

    // The mapped reference as floats: the RMSE of the candidate's ao against it over the covered
    // pixels is the candidate's RMSE.
    const {decodeExr} = await import('../../web/js/exr.js');
    const ssao = byTech.ssao;
    assert.equal(ssao.links['reference_mapped.exr'], `/api/v1/jobs/${ssao.job_id}/outputs/reference_mapped.exr`);
    const job = await getJSON(d, `/api/v1/jobs/${ssao.job_id}`);
    const exr = async (name) => decodeExr(new Uint8Array((await download(d, job, name)).body).buffer);
    const [cand, mapped] = [await exr('ao.exr'), await exr('reference_mapped.exr')];
    const ch = (img, n) => img.channels.find((x) => x.name === n).data;
    const [a, b, alpha] = [ch(cand, 'ao'), ch(mapped, 'ao'), ch(mapped, 'alpha')];
    let sq = 0, n = 0;
    for (let i = 0; i < a.length; i++) if (alpha[i] > 0) { sq += (a[i] - b[i]) ** 2; n++; }
    assert.ok(Math.abs(Math.sqrt(sq / n) - ssao.metrics.rmse) < 1e-5, `${Math.sqrt(sq / n)} vs ${ssao.metrics.rmse}`);

    // The CSV: the reference of each row, the common figures, and a row for obscurance's W.
    const csv = parseCsv((await request(d, 'GET', c.links.csv)).text);
    const head = csv[0], col = (k) => head.indexOf(k);
    for (const k of ['reference', 'reference_label', 'common_rmse', 'common_pareto']) assert.ok(col(k) > 0, k);
    assert.equal(csv.length, 1 + c.candidates.length + c.candidates.reduce((a, x) => a + x.outputs.length, 0));
    const rowsOf = (i) => csv.slice(1).filter((x) => Number(x[0]) === i);
    for (const x of c.candidates) {
      const own = rowsOf(x.index)[0];
      assert.equal(own[col('reference')], x.reference.id);
      assert.equal(Number(own[col('common_rmse')]), x.common.metrics.rmse);
    }
    const wRow = rowsOf(byTech.obscurance.index)[1];
    assert.equal(wRow[col('output')], 'obscurance');
    assert.equal(wRow[col('reference')], w.reference.id);
    assert.equal(Number(wRow[col('rmse')]), w.metrics.rmse);
    await d.stopClean();
  } finally {
    await d.kill9();
  }
});
