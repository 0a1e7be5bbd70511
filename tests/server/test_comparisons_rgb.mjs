// Comparisons on an RGB primary output against real daemons (docs/comparisons.md,
// docs/metrics.md "RGB outputs"): path_trace at 4 to 256 paths per pixel sample against path_trace
// at 4096 on the bundled Cornell box, end to end: the reference job, the RGB metrics (per-channel
// and luminance RMSE, SSIM of luminance, relative MSE) falling as samples grow, timings, the Pareto
// set, the CSV, and the final.png links. Also: a reference backend that the reference technique
// lacks is refused, and radiance RMSEs never answer an AO time budget. Images are 32x24 so the
// 4096-path reference takes a few seconds on two cores; nothing depends on timing.
import assert from 'node:assert/strict';
import {test} from 'node:test';

import {SLOW, download, exrHeader, getJSON, getJob, pngSize, request, sleep, validate,
        withDaemon} from './lib.mjs';

const SMALL = {'/image/width': 32, '/image/height': 24};
const SAMPLES = [4, 16, 64, 256];

const BODY = {
  scene_file: 'cornell_box.json',
  set: SMALL,
  label: 'path_trace convergence',
  repeats: 2,
  reference: {samples: 4096},
  candidates: [{technique: 'path_trace', backend: 'cpu', params: {samples: SAMPLES}}],
};

async function waitComparison(d, id, timeoutMs = 240000 * SLOW) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const c = await getJSON(d, `/api/v1/comparisons/${id}`);
    validate('Comparison', c);
    if (c.state !== 'running') return c;
    if (Date.now() > deadline) throw new Error(`comparison ${id} still running: ${JSON.stringify(c).slice(0, 2000)}`);
    await sleep(50);
  }
}

/** RFC 4180 CSV (no quoted line breaks here) into header-keyed rows. */
function csvRows(text) {
  assert.ok(text.endsWith('\r\n'), 'CSV ends with CRLF');
  const split = (line) => {
    const out = [];
    let f = '', q = false;
    for (let i = 0; i < line.length; i++) {
      const ch = line[i];
      if (q && ch === '"' && line[i + 1] === '"') (f += '"', i++);
      else if (ch === '"') q = !q;
      else if (ch === ',' && !q) (out.push(f), (f = ''));
      else f += ch;
    }
    out.push(f);
    return out;
  };
  const [head, ...rest] = text.slice(0, -2).split('\r\n').map(split);
  return {head, rows: rest.map((r) => Object.fromEntries(head.map((h, i) => [h, r[i]])))};
}

const csvNum = (s) => (s === '' ? null : Number(s));

/** GETs a link and checks that it is a PNG of the comparison's size. */
async function assertPng(d, url) {
  const r = await request(d, 'GET', url);
  assert.equal(r.status, 200, `GET ${url}: ${r.status}`);
  assert.equal(r.headers['content-type'], 'image/png', url);
  assert.deepEqual(pngSize(r.body), {width: 32, height: 24}, url);
}

/** One candidate of the path_trace comparison: its reference, RGB metrics, timings and images. */
async function assertCandidate(d, x, ref) {
  assert.equal(x.reference_job_id, ref.job_id);
  assert.equal(x.response, 'identity');
  assert.equal(x.params.seed, 1);
  for (const k of ['max_bounces', 'rr_depth', 'light_sampling', 'sampler', 'exposure']) {
    assert.equal(ref.params[k], x.params[k], `the reference keeps the candidate's ${k}`);
  }
  const m = x.metrics;
  assert.ok(m, `candidate ${x.index} has metrics`);
  assert.equal(m.output, 'radiance');
  assert.equal(m.rgb.rmse.length, 3);
  for (const v of m.rgb.rmse) assert.ok(Number.isFinite(v) && v > 0, `per-channel RMSE ${m.rgb.rmse}`);
  assert.ok(m.rgb.rmse_luminance > 0);
  assert.ok(m.rgb.ssim_luminance > 0 && m.rgb.ssim_luminance <= 1, `SSIM ${m.rgb.ssim_luminance}`);
  assert.ok(m.rgb.rel_mse > 0);
  // The scalar fields are those of the luminance image (stored in float, hence the margin).
  assert.ok(Math.abs(m.rmse - m.rgb.rmse_luminance) <= 1e-4 * m.rgb.rmse_luminance, JSON.stringify(m));
  assert.ok(Math.abs(m.ssim - m.rgb.ssim_luminance) <= 1e-6, JSON.stringify(m));
  assert.ok(m.ref_noise > 0, 'the reference noise comes from radiance_stderr');
  assert.ok(m.pixels > 0 && m.pixels <= 32 * 24);
  assert.equal(x.timings_ms.runs.length, 2, 'repeats timed runs');
  for (const k of ['build', 'render', 'post', 'total']) assert.equal(typeof x.timings_ms.median[k], 'number');
  assert.equal(x.links.image, `/api/v1/jobs/${x.job_id}/outputs/final.png`);
  assert.equal(x.links['reference.png'], `/api/v1/jobs/${ref.job_id}/outputs/final.png`);
  assert.equal(x.links['ao.png'], undefined);
  await assertPng(d, x.links.image);
  await assertPng(d, x.links['reference.png']);
  await assertPng(d, x.links['error.png']);
  const job = await getJob(d, x.job_id);
  assert.deepEqual(exrHeader((await download(d, job, 'error.exr')).body).channels, ['error']);
}

/** The CSV of comparison `c`: the compared output and the RGB figures, equal to the JSON. */
async function assertCsv(d, c) {
  const csv = await request(d, 'GET', c.links.csv);
  assert.equal(csv.status, 200);
  assert.match(csv.headers['content-type'], /^text\/csv/);
  const {head, rows} = csvRows(csv.text);
  // The metric columns are the metric table's, in its order (GET /api/v1/metrics).
  const table = (await request(d, 'GET', '/api/v1/metrics')).json.metrics.map((m) => m.name);
  assert.deepEqual(head.slice(11, 11 + table.length), table);
  assert.deepEqual(head.slice(-12, -9), ['output', 'total_ms_min', 'total_ms_max']);
  assert.equal(head.at(-1), 'device');
  assert.equal(rows.length, 4);
  for (const [k, x] of c.candidates.entries()) {
    const f = rows[k];
    assert.equal(Number(f.index), x.index);
    assert.equal(f.output, 'radiance');
    assert.deepEqual([f.rmse_r, f.rmse_g, f.rmse_b].map(csvNum), x.metrics.rgb.rmse);
    for (const key of ['rmse_luminance', 'ssim_luminance', 'rel_mse']) assert.equal(csvNum(f[key]), x.metrics.rgb[key], key);
    assert.equal(csvNum(f.rmse), x.metrics.rmse);
    assert.equal(csvNum(f.flip), x.metrics.flip);
    assert.ok(x.metrics.flip > 0 && x.metrics.flip < 1, `HDR-FLIP ${x.metrics.flip}`);
    assert.equal(f.pareto, String(x.pareto));
    assert.equal(csvNum(f.total_ms), x.timings_ms.median.total);
  }
}

test('path_trace at 4..256 paths against path_trace at 4096: RGB metrics, Pareto set, CSV, images', async () => {
  await withDaemon({}, async (d) => {
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: BODY});
    assert.equal(r.status, 201, r.text);
    validate('ComparisonCreated', r.json);
    assert.deepEqual([r.json.candidates, r.json.references], [4, 1]);
    const c = await waitComparison(d, r.json.id);
    assert.equal(c.state, 'succeeded', JSON.stringify(c.candidates.map((x) => [x.state, x.error])));

    // One reference: path_trace itself at 4096 paths per pixel sample, another seed, the same
    // light transport as the candidates.
    assert.equal(c.references.length, 1);
    const ref = c.references[0];
    assert.equal(ref.technique, 'path_trace');
    assert.equal(ref.state, 'succeeded');
    assert.equal(ref.params.samples, 4096);
    assert.equal(ref.params.seed, 7919);
    const refJob = await getJob(d, ref.job_id);
    assert.equal(refJob.technique, 'path_trace');
    assert.equal(refJob.backend.actual, 'cpu');
    assert.equal(ref.ao_stderr_mean, null, 'a radiance reference has no ao_stderr');
    assert.equal(ref.timings_ms.runs.length, 1);
    assert.equal(ref.links.image, `/api/v1/jobs/${ref.job_id}/outputs/final.png`);
    assert.equal(ref.links['ao.png'], undefined);
    await assertPng(d, ref.links.image);

    assert.deepEqual(c.candidates.map((x) => [x.technique, x.backend, x.params.samples]),
                     SAMPLES.map((s) => ['path_trace', 'cpu', s]));
    for (const x of c.candidates) await assertCandidate(d, x, ref);

    // Convergence: each 4x more paths lowers the error (about halves it); the renders are
    // deterministic, and the bound at 64x leaves a wide margin (about 0.1 is measured).
    const lum = c.candidates.map((x) => x.metrics.rgb.rmse_luminance);
    for (let k = 1; k < lum.length; k++) assert.ok(lum[k] < lum[k - 1], `luminance RMSE falls: ${lum}`);
    assert.ok(lum[3] < 0.5 * lum[0], `rmse(256) < 0.5 rmse(4): ${lum}`);
    const rel = c.candidates.map((x) => x.metrics.rgb.rel_mse);
    assert.ok(rel[3] < 0.25 * rel[0], `relative MSE falls: ${rel}`);
    assert.ok(c.candidates[3].metrics.ssim > c.candidates[0].metrics.ssim);
    // HDR-FLIP sees the noise fall too (perceived differences shrink with the error).
    const flip = c.candidates.map((x) => x.metrics.flip);
    for (let k = 1; k < flip.length; k++) assert.ok(flip[k] < flip[k - 1], `HDR-FLIP falls: ${flip}`);
    console.log(`# luminance RMSE ${lum.map((v) => v.toPrecision(3))}, SSIM ${c.candidates.map((x) => x.metrics.ssim.toPrecision(4))}, ` +
                `HDR-FLIP ${flip.map((v) => v.toPrecision(3))}`);

    // Pareto set: non-empty, flags agree with the list, ascending time.
    assert.ok(c.pareto.length >= 1);
    assert.deepEqual(c.candidates.filter((x) => x.pareto).map((x) => x.index).sort((a, b) => a - b),
                     [...c.pareto].sort((a, b) => a - b));
    const times = c.pareto.map((i) => c.candidates[i].timings_ms.median.total);
    assert.deepEqual(times, [...times].sort((a, b) => a - b));

    await assertCsv(d, c);

    const list = await getJSON(d, '/api/v1/comparisons');
    assert.deepEqual(list.comparisons.map((x) => [x.label, x.state, x.candidates, x.done]),
                     [['path_trace convergence', 'succeeded', 4, 4]]);

    // Radiance RMSEs are not AO RMSEs: an AO time budget finds nothing measured.
    const e = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', set: SMALL, technique: 'auto', time_budget_ms: 1e6}});
    assert.equal(e.status, 422, e.text);
    assert.ok(e.json.problems.some((p) => p.startsWith('request: /time_budget_ms: nothing has been measured')), e.text);
  });
});

test('a reference backend the reference technique lacks is refused at /reference/backend', async () => {
  await withDaemon({}, async (d) => {
    const body = {...BODY, reference: {samples: 16, backend: 'vulkan'}, candidates: [{technique: 'path_trace', params: {samples: [4, 16]}}]};
    const r = await request(d, 'POST', '/api/v1/comparisons', {body});
    assert.equal(r.status, 422, r.text);
    validate('Error', r.json);
    const named = r.json.problems.filter((p) => p.startsWith('request: /reference/backend: the reference of /candidates/0 (path_trace): '));
    assert.equal(named.length, 1, JSON.stringify(r.json.problems));
    // "auto" resolves per reference technique: path_trace runs on the CPU.
    const ok = await request(d, 'POST', '/api/v1/comparisons', {body: {...body, reference: {samples: 16, backend: 'auto'}, repeats: 1}});
    assert.equal(ok.status, 201, ok.text);
    const c = await waitComparison(d, ok.json.id);
    assert.equal(c.state, 'succeeded');
    assert.equal((await getJob(d, c.references[0].job_id)).backend.actual, 'cpu');
  });
});
