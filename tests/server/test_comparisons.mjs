// Speed/accuracy comparisons against real daemons (docs/comparisons.md): sweep expansion (the
// product of the lists), 422s with pointers for bad grids and nothing stored, a comparison run to
// completion with metrics, error images, the Pareto set and the CSV, stored runs, metrics
// recomputed at start, learned "auto" from seeded timings, and the time-budget choice. Images are
// 32x24 and references 64 samples so the whole file runs in seconds; nothing depends on timing
// (timings that decide anything are seeded into the database).
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import {test} from 'node:test';

import {OBSCURA, ROOT, SLOW, exrHeader, getJSON, getJob, pngSize, request, sql, startDaemon, submit,
        validate, waitJob, withDaemon, download, sleep} from './lib.mjs';

const SMALL = {'/image/width': 32, '/image/height': 24};

// The grid of the main comparison: 3 x 2 hbao, 2 x 2 ssao, 2 rt_ao = 12 candidates.
const GRID = {
  scene_file: 'cornell_box.json',
  set: SMALL,
  label: 'test sweep',
  repeats: 2,
  reference: {samples: 64},
  candidates: [
    {technique: 'hbao', backend: 'cpu', params: {directions: [4, 8, 16], steps: [2, 4], radius: 100}},
    {technique: 'ssao', backend: ['cpu'], params: {samples: [8, 16], normal_oriented: [false, true]}},
    {technique: 'rt_ao', params: {samples: [4, 64], max_distance: 200}},
  ],
};

/** Writes to the daemon's database with the sqlite3 shell (the daemon must be stopped). */
function sqlWrite(db, text) {
  const r = spawnSync('sqlite3', ['-batch', db, text], {encoding: 'utf8'});
  assert.equal(r.status, 0, `sqlite3: ${r.stderr}`);
}

async function postComparison(d, body, expect = 201) {
  const r = await request(d, 'POST', '/api/v1/comparisons', {body});
  assert.equal(r.status, expect, `POST /api/v1/comparisons: ${r.status} ${r.text}`);
  if (expect === 201) {
    validate('ComparisonCreated', r.json);
    assert.equal(r.headers.location, `/api/v1/comparisons/${r.json.id}`);
  } else {
    validate('Error', r.json);
  }
  return r.json;
}

async function getComparison(d, id) {
  const c = await getJSON(d, `/api/v1/comparisons/${id}`);
  validate('Comparison', c);
  return c;
}

async function waitComparison(d, id, timeoutMs = 120000 * SLOW) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const c = await getComparison(d, id);
    if (c.state !== 'running') return c;
    if (Date.now() > deadline) throw new Error(`comparison ${id} still running: ${JSON.stringify(c).slice(0, 2000)}`);
    await sleep(30);
  }
}

/**
 * The Pareto set by its definition, from the returned table (docs/comparisons.md, "Ranking"):
 * within each reference's group (errors against different references do not compare), faster
 * only beyond both timing spreads, more accurate only beyond the larger reference noise; the
 * groups' sets together by ascending time.
 */
function paretoOf(cands) {
  const groups = [...new Set(cands.map((c) => c.reference.id))];
  const all = groups.flatMap((g) => paretoIn(cands.filter((c) => c.reference.id === g)));
  const time = (i) => cands.find((c) => c.index === i).timings_ms.median.total;
  return all.sort((a, b) => time(a) - time(b) || a - b);
}

function paretoIn(cands) {
  const pts = cands.map((c) => ({
    i: c.index,
    t: c.metrics && c.timings_ms.median ? c.timings_ms.median.total : null,
    lo: c.timings_ms.min ? c.timings_ms.min.total : null,
    hi: c.timings_ms.max ? c.timings_ms.max.total : null,
    tol: c.metrics && c.metrics.ref_noise > 0 ? c.metrics.ref_noise : 0,
    e: c.metrics ? (c.metrics.at_reference_accuracy ? -Infinity : c.metrics.rmse) : null,
  })).filter((p) => typeof p.t === 'number' && (p.e === -Infinity || typeof p.e === 'number'));
  const dominates = (q, p) => {
    const tol = Math.max(p.tol, q.tol);
    const faster = q.hi < p.lo, slower = q.lo > p.hi;
    return !slower && !(q.e > p.e + tol) && (faster || q.e < p.e - tol);
  };
  const opt = pts.filter((p) => !pts.some((q) => q !== p && dominates(q, p)));
  return opt.sort((a, b) => a.t - b.t || a.i - b.i).map((p) => p.i);
}

/** RFC 4180 CSV into rows of fields. */
function parseCsv(text) {
  const rows = [];
  let row = [], f = '', q = false;
  for (let i = 0; i < text.length; i++) {
    const ch = text[i];
    if (q) {
      if (ch === '"' && text[i + 1] === '"') (f += '"', i++);
      else if (ch === '"') q = false;
      else f += ch;
    } else if (ch === '"') q = true;
    else if (ch === ',') (row.push(f), (f = ''));
    else if (ch === '\r' && text[i + 1] === '\n') (row.push(f), rows.push(row), (row = []), (f = ''), i++);
    else f += ch;
  }
  assert.equal(f, '', 'CSV ends with CRLF');
  return rows;
}

const csvNum = (s) => (s === '' ? null : Number(s));

// Numbers rounded to 9 significant digits: a 201 body and a GET answer print reals with different
// precision (17 and 12 digits).
const rounded = (v) => JSON.parse(JSON.stringify(v, (k, x) => (typeof x === 'number' ? Number(x.toPrecision(9)) : x)));

test('a sweep expands to the product of its lists, runs to completion with metrics, Pareto set and CSV', async () => {
  await withDaemon({}, async (d) => {
    const created = await postComparison(d, GRID);
    assert.equal(created.state, 'running');
    assert.equal(created.candidates, 3 * 2 + 2 * 2 + 2);
    // hbao: one definition (R fixed); ssao: one per sample count (normal_oriented only changes
    // the response); rt_ao: one (same definition, reference samples and seed).
    assert.equal(created.references, 1 + 2 + 1);
    const id = created.id;

    // The expansion is the product, backends outermost, then the parameters in request order.
    let c = await getComparison(d, id);
    const got = c.candidates.map((x) => [x.technique, x.backend, x.params.directions ?? x.params.samples,
                                         x.params.steps ?? x.params.normal_oriented ?? null]);
    const want = [];
    for (const dir of [4, 8, 16]) for (const st of [2, 4]) want.push(['hbao', 'cpu', dir, st]);
    for (const s of [8, 16]) for (const no of [false, true]) want.push(['ssao', 'cpu', s, no]);
    for (const s of [4, 64]) want.push(['rt_ao', 'cpu', s, null]);
    assert.deepEqual(got, want);
    assert.deepEqual(c.candidates.map((x) => x.index), [...want.keys()]);
    for (const x of c.candidates) {
      if (x.technique === 'hbao') assert.equal(x.params.radius, 100, 'scalars are kept');
      if (x.technique === 'rt_ao') assert.equal(x.params.max_distance, 200);
      assert.equal(x.params.seed, 1, 'defaults are filled in');
    }
    assert.deepEqual(c.candidates.map((x) => x.response),
                     [...Array(6).fill('identity'), 'ssao_sphere', 'ssao_hemi', 'ssao_sphere', 'ssao_hemi', 'identity', 'identity']);
    // Four reference jobs; a reference is a job mapped through a response, and ssao's two jobs are
    // each mapped through both of its responses (whole sphere and normal-oriented): six references.
    assert.equal(new Set(c.references.map((r) => r.job_id)).size, 4);
    assert.deepEqual(c.references.map((r) => r.response).sort(),
                     ['identity', 'identity', 'ssao_hemi', 'ssao_hemi', 'ssao_sphere', 'ssao_sphere']);
    for (const r of c.references) {
      assert.equal(r.technique, 'rt_ao');
      assert.equal(r.params.samples, 64);
      assert.equal(r.params.seed, 7919);
      assert.equal(r.params.weighting, c.candidates.find((x) => x.reference_job_id === r.job_id).technique === 'rt_ao' ? 'cosine' : 'uniform');
    }
    const hbaoRef = c.references.find((r) => r.job_id === c.candidates[0].reference_job_id);
    assert.deepEqual([hbaoRef.params.falloff, hbaoRef.params.max_distance.toFixed(6)], ['binary', (200 / 3).toFixed(6)]);
    const ssaoRefs = new Set(c.candidates.filter((x) => x.technique === 'ssao').map((x) => x.reference_job_id));
    assert.equal(ssaoRefs.size, 2);
    for (const rid of ssaoRefs) assert.equal(c.references.find((r) => r.job_id === rid).params.falloff, 'sqrt');
    const rtRef = c.references.find((r) => r.job_id === c.candidates[10].reference_job_id);
    assert.deepEqual([rtRef.params.falloff, rtRef.params.max_distance, rtRef.params.weighting], ['binary', 200, 'cosine']);
    // Rows in the database: one comparison, 12 candidates and a row for each rt_ao candidate's bent
    // normal (against its reference's), 16 jobs.
    assert.deepEqual(sql(d.db, "SELECT role, count(*) FROM comparison_candidates GROUP BY 1 ORDER BY 1"), [['output', '2'], ['own', '12']]);
    assert.deepEqual(sql(d.db, 'SELECT count(*) FROM jobs'), [['16']]);
    assert.deepEqual(sql(d.db, "SELECT repeats, warmup, count(*) FROM jobs WHERE technique != 'rt_ao' OR id IN (SELECT job FROM comparison_candidates) GROUP BY 1, 2"), [['2', '1', '12']]);

    c = await waitComparison(d, id);
    assert.equal(c.state, 'succeeded', JSON.stringify(c.candidates.map((x) => [x.state, x.error])));
    for (const x of c.candidates) {
      assert.equal(x.state, 'succeeded');
      assert.ok(x.metrics, `candidate ${x.index} has metrics`);
      for (const k of ['rmse', 'bias', 'max_abs', 'psnr', 'ssim', 'flip', 'ref_noise']) assert.equal(typeof x.metrics[k], 'number', `${x.index} ${k}`);
      assert.ok(x.metrics.flip > 0 && x.metrics.flip < 1, `FLIP ${x.metrics.flip}`);
      assert.ok(x.metrics.ssim > -1 && x.metrics.ssim < 1, `SSIM ${x.metrics.ssim}`);
      assert.equal(x.metrics.pixels > 0, true);
      assert.equal(x.metrics.at_reference_accuracy, x.metrics.rmse < 2 * x.metrics.ref_noise);
      assert.equal(x.timings_ms.runs.length, 2, 'repeats timed runs');
      for (const k of ['build', 'render', 'post', 'total']) assert.equal(typeof x.timings_ms.median[k], 'number');
      for (const r of x.timings_ms.runs) assert.ok(Math.abs(r.total - (r.build + r.render + r.post)) < 1e-6);
      assert.equal(x.machine.cores > 0, true);
      assert.equal(x.machine.vulkan_device, null, '--no-vulkan: no device recorded');
      assert.equal(x.links['reference.png'], `/api/v1/jobs/${x.reference_job_id}/outputs/ao.png`);
      // The error images are outputs of the candidate job, hashed like the others.
      const job = await getJob(d, x.job_id);
      const errPng = (await download(d, job, 'error.png')).body;
      assert.deepEqual(pngSize(errPng), {width: 32, height: 24});
      assert.deepEqual(exrHeader((await download(d, job, 'error.exr')).body).channels, ['error']);
      assert.equal(x.links['error.png'], `/api/v1/jobs/${x.job_id}/outputs/error.png`);
      // FLIP's map beside them: the magma picture and the float map.
      assert.deepEqual(pngSize((await download(d, job, 'flip.png')).body), {width: 32, height: 24});
      assert.deepEqual(exrHeader((await download(d, job, 'flip.exr')).body).channels, ['flip']);
      assert.equal(x.links['flip.png'], `/api/v1/jobs/${x.job_id}/outputs/flip.png`);
      assert.equal(x.links['flip.exr'], `/api/v1/jobs/${x.job_id}/outputs/flip.exr`);
    }
    // rt_ao with the reference's own samples is at reference accuracy: the noise floor.
    assert.equal(c.candidates[11].metrics.at_reference_accuracy, true, JSON.stringify(c.candidates[11].metrics));
    for (const r of c.references) {
      assert.equal(r.state, 'succeeded');
      assert.equal(typeof r.ao_stderr_mean, 'number');
      assert.equal(r.timings_ms.runs.length, 1, 'a reference renders once');
    }
    // Pareto: as recomputed from the table; the flags agree with the list.
    assert.deepEqual(c.pareto, paretoOf(c.candidates));
    assert.ok(c.pareto.length >= 1);
    assert.deepEqual(c.candidates.filter((x) => x.pareto).map((x) => x.index).sort((a, b) => a - b),
                     [...c.pareto].sort((a, b) => a - b));
    // Stored runs: repeats per candidate, one per reference, every one with the machine.
    assert.deepEqual(sql(d.db, `SELECT count(*) FROM runs WHERE job IN (SELECT job FROM comparison_candidates WHERE comparison = ${id})`), [['24']]);
    assert.deepEqual(sql(d.db, `SELECT count(*) FROM runs WHERE job IN (SELECT reference_job FROM comparison_candidates WHERE comparison = ${id})`), [['4']]);
    assert.deepEqual(sql(d.db, 'SELECT count(*) FROM runs WHERE machine IS NULL'), [['0']]);
    assert.deepEqual(sql(d.db, 'SELECT count(*) FROM machines'), [['1']]);

    // The CSV: header and one row per candidate, values equal to the JSON.
    const r = await request(d, 'GET', `/api/v1/comparisons/${id}.csv`);
    assert.equal(r.status, 200);
    assert.match(r.headers['content-type'], /^text\/csv/);
    const rows = parseCsv(r.text);
    // The metric columns are the metric table's (GET /api/v1/metrics), in its order.
    const table = (await getJSON(d, '/api/v1/metrics')).metrics;
    assert.ok(['rmse', 'psnr', 'ssim', 'flip', 'rmse_r', 'rel_mse'].every((n) => table.some((m) => m.name === n)));
    assert.equal(rows[0].join(','), ['index,job_id,technique,backend,params,state,total_ms,build_ms,render_ms,post_ms,runs',
      ...table.map((m) => m.name), 'at_reference_accuracy,pareto,cpu_model,cores,vulkan_device,output,total_ms_min,total_ms_max',
      'reference,reference_label,common_rmse,common_bias,common_psnr,common_ssim,common_flip,common_pareto,device'].join(','));
    // A row per candidate, each followed by a row per other output (rt_ao's bent normal).
    assert.equal(rows.length, 1 + c.candidates.length + c.candidates.filter((x) => x.technique === 'rt_ao').length);
    const own = rows.slice(1).filter((r, k, all) => k === 0 || r[0] !== all[k - 1][0]);
    for (const [k, x] of c.candidates.entries()) {
      const f = Object.fromEntries(rows[0].map((h, i) => [h, own[k][i]]));
      assert.equal(Number(f.index), x.index);
      assert.equal(Number(f.job_id), x.job_id);
      assert.deepEqual([csvNum(f.total_ms_min), csvNum(f.total_ms_max)], [x.timings_ms.min.total, x.timings_ms.max.total]);
      assert.equal(f.technique, x.technique);
      assert.equal(f.backend, x.backend);
      const params = Object.fromEntries(f.params.split(';').map((kv) => {
        const [key, v] = kv.split('=');
        return [key, typeof x.params[key] === 'string' ? v : JSON.parse(v)];
      }));
      assert.deepEqual(params, x.params);
      assert.equal(f.state, x.state);
      for (const s of ['total', 'build', 'render', 'post']) assert.equal(csvNum(f[`${s}_ms`]), x.timings_ms.median[s]);
      assert.equal(Number(f.runs), x.timings_ms.runs.length);
      for (const m of ['rmse', 'bias', 'max_abs', 'psnr', 'ssim', 'flip', 'ref_noise']) assert.equal(csvNum(f[m]), x.metrics[m], m);
      assert.equal(f.at_reference_accuracy, String(x.metrics.at_reference_accuracy));
      assert.equal(f.pareto, String(x.pareto));
      assert.deepEqual([f.reference, f.reference_label, f.common_rmse], [x.reference.id, x.reference.label, '']);
      assert.equal(f.cpu_model, x.machine.cpu_model);
      assert.equal(Number(f.cores), x.machine.cores);
      assert.equal(f.vulkan_device, '');
      assert.equal(f.device, x.device.label);
      // AO candidates: the compared output is named, the RGB columns stay empty.
      assert.deepEqual([f.output, f.rmse_r, f.rmse_luminance, f.rel_mse], ['ao', '', '', '']);
    }

    // The list.
    const list = await getJSON(d, '/api/v1/comparisons');
    validate('ComparisonList', list);
    assert.deepEqual(list.comparisons.map((x) => [x.id, x.label, x.scene, x.state, x.candidates, x.done]),
                     [[id, 'test sweep', 'cornell_box.json', 'succeeded', 12, 12]]);
    assert.equal(list.next, null);
    assert.equal((await request(d, 'GET', '/api/v1/comparisons?limit=0')).status, 400);
    assert.equal((await request(d, 'GET', '/api/v1/comparisons?color=red')).status, 400);
    assert.equal((await request(d, 'GET', `/api/v1/comparisons/${id + 1}`)).status, 404);
    assert.equal((await request(d, 'GET', '/api/v1/comparisons/01')).status, 404);
    assert.equal((await request(d, 'PUT', `/api/v1/comparisons/${id}`)).status, 405);

    // Jobs of a comparison cannot be deleted on their own.
    const del = await request(d, 'DELETE', `/api/v1/jobs/${c.candidates[0].job_id}`);
    assert.equal(del.status, 409);
    assert.match(del.json.error, new RegExp(`belongs to comparison ${id}`));
    assert.equal((await request(d, 'DELETE', `/api/v1/jobs/${c.references[0].job_id}`)).status, 409);

    // Recovery: metrics lost before a restart (a crash between a job's commit and its metrics)
    // are computed again at start, equal to the first ones (renders are deterministic).
    await d.stopClean();
    const before = c.candidates[3];
    sqlWrite(d.db, `UPDATE comparison_candidates SET metrics = NULL WHERE idx = 3;
                    DELETE FROM outputs WHERE job_id = ${before.job_id} AND name LIKE 'error.%';`);
    const d2 = await startDaemon({dir: d.dir});
    try {
      const again = await getComparison(d2, id);
      assert.equal(again.state, 'succeeded');
      assert.deepEqual(again.candidates[3].metrics, before.metrics);
      assert.ok(again.candidates[3].links['error.png']);
      assert.deepEqual(again.pareto, c.pareto);
      await d2.stopClean();
    } finally {
      await d2.kill9();
    }
  });
});

test('bad grids are 422 with a pointer for every problem, and store nothing', async () => {
  await withDaemon({}, async (d) => {
    const base = {scene_file: 'cornell_box.json', set: SMALL};
    const cases = [
      [{...base, candidates: [{technique: 'hbao', backend: 'cpu', params: {directionz: [4, 8]}}]},
       'request: /candidates/0/params/directionz'],
      [{...base, candidates: [{technique: 'hbao', backend: 'cpu', params: {directions: [4, 64]}}]},
       'request: /candidates/0/params/directions/1: must be <= 32'],
      [{...base, candidates: [{technique: 'hbao', backend: ['cpu', 'metal']}]},
       'request: /candidates/0/backend/1: must be "cpu" or "vulkan"'],
      [{...base, candidates: [{technique: 'hbao', backend: 'vulkan'}]},
       'request: /candidates/0/backend: '],
      [{...base, candidates: [{technique: 'hbao', backend: [], params: {}}]},
       'request: /candidates/0/backend: must list 1 or 2 backends'],
      [{...base, candidates: [{technique: 'hbao', params: {steps: []}}]},
       'request: /candidates/0/params/steps: an empty list'],
      [{...base, candidates: [{technique: 'hbao', params: {directions: [...Array(32).keys()].map((i) => i + 1), steps: [1, 2, 3, 4, 5, 6, 7, 8, 9]}}]},
       'request: /candidates: expands to 288 candidates; at most 256'],
      [{...base, candidates: [{technique: 'nope'}]}, 'request: /candidates/0/technique: not a technique'],
      [{...base, candidates: []}, 'request: /candidates: must list at least one candidate'],
      [{...base}, 'request: /candidates'],
      [{set: SMALL, candidates: [{technique: 'hbao'}]}, 'request: /: needs scene_file'],
      [{...base, colour: 1, candidates: [{technique: 'hbao'}]}, 'request: /colour'],
      [{...base, repeats: 0, candidates: [{technique: 'hbao'}]}, 'request: /repeats: must be >= 1'],
      [{...base, budget_ms: 0, candidates: [{technique: 'hbao'}]}, 'request: /budget_ms: must be > 0'],
      [{...base, budget_ms: 'fast', candidates: [{technique: 'hbao'}]}, 'request: /budget_ms'],
      [{...base, reference: {samples: 1024, sampler: 'halton'}, candidates: [{technique: 'hbao'}]}, 'request: /reference/sampler'],
      // max_distance null given: the Cornell box's own is 200.
      [{...base, candidates: [{technique: 'rt_ao', params: {falloff: ['binary', 'sqrt'], max_distance: null}}]},
       'request: /candidates/0/params/max_distance: falloff "sqrt" needs a finite max_distance'],
      [{...base, set: {'/image/width': 0}, candidates: [{technique: 'hbao'}]}, 'cornell_box.json: /image/width: must be >= 1'],
      [{...base, candidates: [{technique: 'hbao', params: {directions: [4, 8]}}, {technique: 'ssao', params: {samples: [8, 12]}}]},
       'request: /candidates/1/params/samples/1'],
    ];
    for (const [body, needle] of cases) {
      const e = await postComparison(d, body, 422);
      assert.ok(e.problems.some((p) => p.includes(needle)), `${JSON.stringify(body)}: no problem with "${needle}" in ${JSON.stringify(e.problems)}`);
    }
    // Every problem of a request at once, each named once (a bad value in many combinations).
    const two = await postComparison(d, {...base, candidates: [
      {technique: 'hbao', params: {directions: [4, 64], steps: [1, 2, 3]}},
      {technique: 'ssao', params: {samples: [8, 12]}}]}, 422);
    assert.deepEqual(two.problems.filter((p) => /^request: \/candidates/.test(p)).map((p) => p.split(':').slice(0, 2).join(':')),
                     ['request: /candidates/0/params/directions/1', 'request: /candidates/1/params/samples/1']);
    assert.equal((await request(d, 'POST', '/api/v1/comparisons', {body: '{"scene_file": '})).status, 400);
    assert.equal((await request(d, 'POST', '/api/v1/comparisons', {body: 'x=1', headers: {'content-type': 'application/x-www-form-urlencoded'}})).status, 415);
    // Nothing was stored.
    assert.deepEqual(sql(d.db, 'SELECT (SELECT count(*) FROM comparisons), (SELECT count(*) FROM jobs), (SELECT count(*) FROM comparison_candidates)'), [['0', '0', '0']]);
  });
});

test('a failed reference fails its candidates and the comparison', async () => {
  await withDaemon({}, async (d) => {
    // A long job keeps the only worker busy, so the comparison's jobs are still queued when one
    // of them is cancelled; then the blocker is cancelled too. Nothing here waits on a clock.
    const blocker = await submit(d, {scene_file: 'cornell_box.json', set: {...SMALL, '/technique/params/samples': 65536}, priority: 100});
    await waitJob(d, blocker, (j) => j.state === 'running');
    const {id} = await postComparison(d, {scene_file: 'cornell_box.json', set: SMALL, reference: {samples: 16},
                                          candidates: [{technique: 'hbao', backend: 'cpu', params: {steps: [2, 4]}}]});
    let c = await getComparison(d, id);
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${c.references[0].job_id}/cancel`)).status, 202);
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${blocker}/cancel`)).status, 202);
    c = await waitComparison(d, id);
    assert.equal(c.state, 'failed');
    assert.equal(c.references[0].state, 'cancelled');
    for (const x of c.candidates) {
      assert.equal(x.state, 'succeeded');
      assert.equal(x.metrics, null);
    }
    assert.deepEqual(c.pareto, []);
    const list = await getJSON(d, '/api/v1/comparisons');
    assert.deepEqual(list.comparisons.map((x) => [x.state, x.done]), [['failed', 2]]);
  });
});

// A succeeded job with runs, as a past render would have left it (for learned "auto"), on a seeded
// machine of this daemon's host kind (its CPU model and threads; `host: 'other'`: another kind, whose
// runs must never count here), with a Vulkan device of `kind` (gpu, software) for Vulkan runs: not
// this daemon's own row, whose runs the render-time estimate would read.
function seedRuns(db, technique, backend, work, totals, kind = 'software', host = 'this') {
  const device = backend === 'vulkan' ? `seeded ${kind} device` : 'seeded cpu host';
  const facts = host === 'this' ? 'cpu_model, cores' : "'another host kind', 64";
  sqlWrite(db, `INSERT OR IGNORE INTO machines (cpu_model, cores, vulkan_device, vulkan_kind)
                SELECT ${facts}, '${device}', ${backend === 'vulkan' ? `'${kind}'` : 'NULL'}
                FROM machines ORDER BY id LIMIT 1;`);
  const machine = `(SELECT max(id) FROM machines WHERE vulkan_device = '${device}' AND
                    (cores = 64) = ${host === 'this' ? 'false' : 'true'})`;
  const rows = totals.map((t, i) => `((SELECT max(id) FROM jobs), ${i + 1}, 0, ${t}, 0, ${t}, ${machine})`).join(', ');
  sqlWrite(db, `INSERT INTO jobs (state, scene, doc, technique, backend_requested, lane, backend, width, height, spp, created_ms, work)
                VALUES ('succeeded', 'cornell_box.json', '{}', '${technique}', '${backend}', '${backend}', '${backend}', 32, 24, 1, 0, ${work});
                INSERT INTO runs (job, run, build_ms, render_ms, post_ms, total_ms, machine) VALUES ${rows};`);
}

const HBAO_AUTO = {scene_file: 'cornell_box.json', technique: {name: 'hbao', backend: 'auto', params: {directions: 8, steps: 8}}, set: SMALL};
const HBAO_WORK = 32 * 24 * 1 * 8 * 8;

async function autoReason(d) {
  const id = await submit(d, HBAO_AUTO);
  const j = await waitJob(d, id);
  assert.equal(j.state, 'succeeded', j.error);
  assert.equal(j.backend.requested, 'auto');
  return j;
}

test('learned auto: the backend with the lower median at similar work, else the static rule', async () => {
  // --no-vulkan: the static rule gives the CPU; measured timings are read and reported.
  const d = await startDaemon({});
  try {
    let j = await autoReason(d);
    assert.equal(j.backend.actual, 'cpu');
    assert.match(j.backend.reason, /^static rule/);
    await d.stopClean();
    // Far from this work, vulkan looks faster; at this work, only cpu has runs yet.
    seedRuns(d.db, 'hbao', 'vulkan', HBAO_WORK * 10, [1, 1, 1]);
    seedRuns(d.db, 'hbao', 'cpu', HBAO_WORK * 10, [9, 9, 9]);
    let d2 = await startDaemon({dir: d.dir});
    j = await autoReason(d2);
    assert.match(j.backend.reason, /^static rule \(no stored runs of hbao on both backends at similar work\)/);
    await d2.stopClean();
    seedRuns(d.db, 'hbao', 'vulkan', HBAO_WORK * 1.5, [2, 3, 100]);
    seedRuns(d.db, 'hbao', 'cpu', HBAO_WORK / 1.5, [5, 6, 7]);
    d2 = await startDaemon({dir: d.dir});
    j = await autoReason(d2);
    // Without a Vulkan lane no device kind is known here: Vulkan timings predict nothing.
    assert.equal(j.backend.actual, 'cpu');
    assert.match(j.backend.reason, /^static rule \(no stored runs of hbao on both backends/);
    // An explicit backend is never second-guessed.
    const e = await waitJob(d2, await submit(d2, {...HBAO_AUTO, technique: {...HBAO_AUTO.technique, backend: 'cpu'}}));
    assert.equal(e.backend.reason, 'requested');
    await d2.stopClean();
  } finally {
    await d.kill9();
  }

  // With a Vulkan lane (lavapipe) the measured faster backend is the one that runs.
  // (--no-vulkan, lib.mjs's default, does not probe for a device: --vulkan does.)
  const probe = await startDaemon({args: ['--vulkan']});
  const health = await getJSON(probe, '/api/v1/health');
  await probe.stopClean();
  if (!health.vulkan_device) {
    console.log('# no Vulkan device: learned auto with a Vulkan lane not tested');
    return;
  }
  console.log('# learned auto with a Vulkan lane');
  const v = await startDaemon({args: ['--vulkan']});
  try {
    let j = await autoReason(v);
    assert.equal(j.backend.actual, 'vulkan', 'static rule with a device');
    await v.stopClean();
    // This job's own run counts too; seed enough cpu-faster runs to outvote it.
    seedRuns(v.db, 'hbao', 'cpu', HBAO_WORK, [0.001, 0.001, 0.001, 0.001, 0.001]);
    seedRuns(v.db, 'hbao', 'vulkan', HBAO_WORK, [1e6, 1e6, 1e6, 1e6, 1e6]);
    // A GPU's far faster runs never stand for this software device's, nor another host kind's
    // runs on a device of this kind (a store that several nodes share holds both).
    seedRuns(v.db, 'hbao', 'vulkan', HBAO_WORK, [1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6], 'gpu');
    seedRuns(v.db, 'hbao', 'vulkan', HBAO_WORK, [1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6], health.devices.vulkan.kind, 'other');
    const v2 = await startDaemon({dir: v.dir, args: ['--vulkan']});
    const devices = (await getJSON(v2, '/api/v1/health')).devices;
    assert.equal(devices.vulkan.kind, health.devices.vulkan.kind);
    assert.match(devices.vulkan.label, /^vulkan · .+ \((software|GPU|other)\)$/);
    j = await autoReason(v2);
    assert.equal(j.backend.actual, 'cpu');
    assert.match(j.backend.reason, /^measured: cpu is faster/);
    assert.match(j.backend.reason, devices.vulkan.kind === 'gpu' ? /vulkan/ : /vulkan [\d.e+]+ ms \(\d+ runs\)/);
    assert.doesNotMatch(j.backend.reason, /vulkan 1e-06 ms/);
    await v2.stopClean();
  } finally {
    await v.kill9();
  }
});

test('time budget: the most accurate measured configuration within the budget (with margins), 422 when none fits', async () => {
  const d = await startDaemon({});
  try {
    // Nothing measured yet.
    let e = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', set: SMALL, technique: 'auto', time_budget_ms: 200}});
    assert.equal(e.status, 422, e.text);
    assert.ok(e.json.problems.some((p) => p.startsWith('request: /time_budget_ms: nothing has been measured')), e.text);
    e = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', technique: 'auto'}});
    assert.equal(e.status, 422);
    assert.ok(e.json.problems.some((p) => p.startsWith('request: /time_budget_ms')), e.text);
    e = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', time_budget_ms: 5}});
    assert.equal(e.status, 422);
    assert.ok(e.json.problems.some((p) => p.startsWith('request: /time_budget_ms: only allowed')), e.text);

    const {id} = await postComparison(d, {...GRID, repeats: 1});
    let c = await waitComparison(d, id);
    assert.equal(c.state, 'succeeded');
    await d.stopClean();
    // Timings decide the choice, so they are seeded: candidate k takes 10 (k + 1) ms.
    sqlWrite(d.db, `UPDATE runs SET total_ms = 10 * (1 + (SELECT idx FROM comparison_candidates WHERE job = runs.job))
                    WHERE job IN (SELECT job FROM comparison_candidates);`);
    const d2 = await startDaemon({dir: d.dir});
    try {
      c = await getComparison(d2, id);
      // The documented rule: of the configurations that fit, the Pareto set with margins (faster
      // only beyond the timing spreads, more accurate only beyond the reference's noise); of its
      // lowest RMSE and those within that RMSE's noise of it, the fastest.
      // RMSEs are ranked on one scale only: the reference on which the most techniques (then the
      // most configurations, then the first candidate's) were measured; the others are left out.
      const byRef = new Map();
      for (const x of c.candidates) byRef.set(x.reference.id, [...(byRef.get(x.reference.id) || []), x]);
      const scale = [...byRef.values()].reduce((m, g) => {
        const techs = (xs) => new Set(xs.map((x) => x.technique)).size;
        return techs(g) > techs(m) || (techs(g) === techs(m) && g.length > m.length) ? g : m;
      });
      const expect = (budget) => {
        const fit = scale.filter((x) => x.timings_ms.median.total <= budget && x.metrics.rmse !== null);
        const err = (x) => (x.metrics.at_reference_accuracy ? -Infinity : x.metrics.rmse);
        const tol = (x) => x.metrics.ref_noise || 0;
        const t = (x) => x.timings_ms.median.total;
        const lo = (x) => Math.min(t(x), x.timings_ms.min.total), hi = (x) => Math.max(t(x), x.timings_ms.max.total);
        const faster = (a, b) => hi(a) < lo(b);
        const better = (a, b) => (err(a) === -Infinity ? err(b) !== -Infinity : err(a) < err(b) - Math.max(tol(a), tol(b)));
        const dominates = (a, b) => !faster(b, a) && !better(b, a) && (faster(a, b) || better(a, b));
        const opt = fit.filter((x) => !fit.some((y) => y !== x && dominates(y, x)));
        const best = opt.reduce((m, x) => (err(x) < err(m) ? x : m), opt[0]);
        const near = opt.filter((x) => err(x) <= err(best) + tol(best));
        return near.sort((a, b) => t(a) - t(b))[0];
      };
      for (const budget of [10, 35, 75, 115, 1000]) {
        const want = expect(budget);
        const r = await request(d2, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', set: SMALL, technique: 'auto', time_budget_ms: budget}});
        assert.equal(r.status, 201, r.text);
        validate('Submitted', r.json);
        const ch = r.json.choice;
        assert.deepEqual(rounded([ch.technique, ch.backend, ch.params, ch.expected_ms, ch.comparison_id, ch.expected_rmse]),
                         rounded([want.technique, want.backend, want.params, want.timings_ms.median.total, id, want.metrics.rmse]),
                         `budget ${budget}`);
        assert.match(ch.reason, /of this scene/);
        // The reasoning kept with the job: what was considered, each alternative with why it lost.
        assert.equal(ch.budget_ms, budget);
        assert.equal(ch.considered, scale.length);
        assert.equal(ch.other_references, c.candidates.length - scale.length);
        assert.equal(ch.reference_label, scale[0].reference.label);
        assert.ok(ch.reason.includes(`all measured against ${scale[0].reference.label}`), ch.reason);
        assert.equal(ch.alternatives.length, Math.min(12, scale.length - 1));
        for (const a of ch.alternatives) assert.ok(scale.some((x) => x.index === a.candidate), 'an alternative of the same scale');
        for (const a of ch.alternatives) {
          assert.equal(a.fits, a.expected_ms <= budget);
          if (!a.fits) assert.equal(a.why_not, 'over the budget');
        }
        const j = await waitJob(d2, r.json.id);
        assert.equal(j.state, 'succeeded', j.error);
        validate('Job', j);
        assert.deepEqual(rounded(j.choice.alternatives), rounded(ch.alternatives));
        assert.ok(j.choice.actual_ms > 0, 'the actual time once it ran');
        assert.match(j.device.label, /^cpu · .+ \(\d+ threads\)$/);
        assert.equal(j.technique, want.technique);
        assert.equal(j.backend.reason, ch.reason);
        assert.equal(j.backend.actual, want.backend);
      }
      // The comparison's answer, per reference (candidates of different references are not
      // ranked together), by the same rule as the budget choice; a budget in the query.
      const refs = new Set(c.candidates.map((x) => x.reference.id));
      assert.deepEqual(new Set(c.answer.groups.map((g) => g.reference)), refs);
      assert.deepEqual(c.answer.groups.map((g) => g.reference), c.groups.map((g) => g.reference), 'the groups of the ranking');
      assert.equal(c.answer.budget_ms, null);
      const a = await getJSON(d2, `/api/v1/comparisons/${id}?budget_ms=35`);
      validate('Comparison', a);
      assert.equal(a.answer.budget_ms, 35);
      for (const g of a.answer.groups) {
        const mine = c.candidates.filter((x) => x.reference.id === g.reference);
        assert.equal(g.candidates, mine.length);
        const fit = mine.filter((x) => x.timings_ms.median.total <= 35);
        if (!fit.length) assert.equal(g.best_under_budget, null);
        else assert.ok(fit.some((x) => x.index === g.best_under_budget.index), JSON.stringify(g));
        assert.ok(mine.some((x) => x.index === g.best.index));
      }
      assert.equal((await request(d2, 'GET', `/api/v1/comparisons/${id}?budget_ms=-1`)).status, 400);
      const listed = (await getJSON(d2, '/api/v1/comparisons')).comparisons.find((x) => x.id === id);
      assert.deepEqual(listed.answer, c.answer);
      const csv = (await request(d2, 'GET', `/api/v1/comparisons/${id}.csv`)).text.trim().split('\r\n');
      assert.equal(csv[0].split(',').at(-1), 'device');
      assert.match(csv[1], /,cpu · [^,]+ \(\d+ threads\)$/);
      // The CLI asks the same question: --budget sends technique auto with time_budget_ms.
      const cli = spawnSync(OBSCURA, ['submit', 'scenes/cornell_box.json', '--set', '/image/width=32', '--set', '/image/height=24',
                                      '--budget', '1000', '--server', d2.url], {encoding: 'utf8', cwd: ROOT});
      assert.equal(cli.status, 0, cli.stderr);
      assert.match(cli.stdout, /^job \d+ queued: .*\nauto picked \w+ on (cpu|vulkan): expected [\d.e+-]+ ms, RMSE [\d.e+-]+ \(comparison \d+\); /);
      await waitJob(d2, Number(cli.stdout.match(/^job (\d+)/)[1]));
      const bad = spawnSync(OBSCURA, ['submit', 'scenes/cornell_box.json', '--budget', '0', '--server', d2.url], {encoding: 'utf8', cwd: ROOT});
      assert.equal(bad.status, 2);
      assert.match(bad.stderr, /--budget must be a time in milliseconds above 0/);
      // Under the fastest configuration: 422 naming the fastest time.
      e = await request(d2, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', set: SMALL, technique: 'auto', time_budget_ms: 9.5}});
      assert.equal(e.status, 422, e.text);
      assert.ok(e.json.problems.some((p) => /fits 9.5 ms: the fastest takes 10 ms/.test(p)), e.text);
      // Another scene of the same size borrows these measurements; a much larger image does not.
      const other = await request(d2, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: SMALL, technique: 'auto', time_budget_ms: 1000}});
      assert.equal(other.status, 201, other.text);
      assert.match(other.json.choice.reason, /of scenes of a similar size/);
      await waitJob(d2, other.json.id);
      e = await request(d2, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', set: {'/image/width': 320, '/image/height': 240}, technique: 'auto', time_budget_ms: 1000}});
      assert.equal(e.status, 422, e.text);
      assert.ok(e.json.problems.some((p) => /nothing has been measured/.test(p)), e.text);
      await d2.stopClean();
    } finally {
      await d2.kill9();
    }
  } finally {
    await d.kill9();
  }
});

test('timed renders run alone: a candidate waits while another render runs; cancel ends the wait', async () => {
  // Two CPU workers, so without the render gate a candidate would render beside the blocker.
  await withDaemon({workers: 2}, async (d) => {
    const blocker = await submit(d, {
      scene_file: 'sphere_on_plane.json', label: 'blocker',
      technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 256}},
      set: {'/image/width': 1024, '/image/height': 1024}});
    // Rendering, not only claimed: a claimed job still loading its scene holds no render, so a
    // candidate could pass the gate before it.
    await waitJob(d, blocker, (j) => j.state === 'running' && j.progress > 0);
    const one = {scene_file: 'cornell_box.json', set: SMALL, repeats: 1, reference: {samples: 16},
                 candidates: [{technique: 'ssao', backend: 'cpu', params: {samples: 8}}]};
    // Claimed by the second worker, the candidate then waits at the gate (the reference, a
    // shared render, may run first).
    const atGate = async (cmp) => {
      const cand = (await getComparison(d, cmp)).candidates[0].job_id;
      const deadline = Date.now() + 60000 * SLOW;
      while (!d.log().includes(`job ${cand}: timed renders wait until no other render runs`)) {
        assert.ok(Date.now() < deadline, `the candidate never reached the gate:\n${d.log().slice(-3000)}`);
        await sleep(20);
      }
      return cand;
    };
    // A candidate cancelled while it waits ends at once, although the blocker still renders.
    const first = await postComparison(d, one);
    const c1 = await atGate(first.id);
    const w = await getJob(d, c1);
    assert.equal(w.state, 'running');
    assert.equal(w.progress, 0, 'no render progress while another render runs');
    let r = await request(d, 'POST', `/api/v1/jobs/${c1}/cancel`);
    assert.equal(r.status, 202, r.text);
    assert.equal((await waitJob(d, c1)).state, 'cancelled');
    assert.equal((await getJob(d, blocker)).state, 'running', 'the blocker still renders');
    // A second comparison's candidate waits too and completes once the blocker is gone.
    const second = await postComparison(d, one);
    await atGate(second.id);
    assert.equal((await getJob(d, blocker)).state, 'running', 'the blocker still renders');
    r = await request(d, 'POST', `/api/v1/jobs/${blocker}/cancel`);
    assert.equal(r.status, 202, r.text);
    const done = await waitComparison(d, second.id);
    assert.equal(done.state, 'succeeded', JSON.stringify(done));
    assert.ok(done.candidates[0].metrics, 'the candidate got its metrics after the gate opened');
  });
});
