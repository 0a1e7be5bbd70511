// Browser test of what the comparison page shows about ranking, on a constructed comparison
// document (the real daemon serves the dashboard; this one comparison's JSON and its PNGs are
// answered by the test, so the figures are exact): the slider's reference is the mapped one the
// metrics compared, the noisy-reference warning, the noise floor and the timing spreads drawn on
// the chart, the spread in the table, the candidate's name on hover, a legend without an empty
// row, and points the keyboard reaches that name their candidate.
import assert from 'node:assert/strict';
import zlib from 'node:zlib';
import test from 'node:test';
import {SLOW, assertAllNamed, download, getJSON, openBrowser, request, screenshot, startDashboard} from './lib.mjs';
import {decodeExr} from '../../web/js/exr.js';

/** A w x h 8-bit grey PNG of one value. */
function greyPng(w, h, v) {
  const chunk = (type, data) => {
    const len = Buffer.alloc(4);
    len.writeUInt32BE(data.length);
    const td = Buffer.concat([Buffer.from(type, 'latin1'), data]);
    const crc = Buffer.alloc(4);
    crc.writeUInt32BE(zlib.crc32(td) >>> 0);
    return Buffer.concat([len, td, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(w, 0);
  ihdr.writeUInt32BE(h, 4);
  ihdr[8] = 8; // bit depth
  ihdr[9] = 0; // greyscale
  const raw = Buffer.alloc((w + 1) * h, v);
  for (let y = 0; y < h; y++) raw[y * (w + 1)] = 0; // filter: none
  return Buffer.concat([Buffer.from('89504e470d0a1a0a', 'hex'), chunk('IHDR', ihdr),
                        chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

const ID = 900;
const timings = (runs) => {
  const sorted = [...runs].sort((a, b) => a - b);
  const t = (v) => ({build: 0, render: v, post: 0, total: v});
  return {median: t(sorted[(sorted.length - 1) >> 1]), min: t(sorted[0]), max: t(sorted[sorted.length - 1]), runs: runs.map(t)};
};
const metrics = (rmse, atRef = false) => ({rmse, bias: 0, max_abs: rmse * 3, psnr: 20, ssim: 0.9, ref_noise: 0.006,
                                           at_reference_accuracy: atRef, pixels: 768});
const links = (job, mapped) => ({job: `/api/v1/jobs/${job}`, 'ao.png': `/api/v1/jobs/${job}/outputs/ao.png`,
  image: `/api/v1/jobs/${job}/outputs/ao.png`, 'error.png': `/api/v1/jobs/${job}/outputs/error.png`,
  'reference.png': '/api/v1/jobs/100/outputs/ao.png',
  ...(mapped ? {'reference_mapped.png': `/api/v1/jobs/${job}/outputs/reference_mapped.png`} : {})});
const cand = (index, technique, backend, params, response, runs, m, pareto) => ({
  index, job_id: 101 + index, reference_job_id: 100, technique, backend, params, response, state: 'succeeded',
  progress: 1, timings_ms: timings(runs), metrics: m, error: null, pareto, machine: null,
  links: links(101 + index, response !== 'identity')});
// hbao on Vulkan 2.7x slower than on the CPU with an RMSE 2e-9 lower: not starred.
const DOC = {
  id: ID, label: 'constructed', scene: 'cornell_box.json', state: 'succeeded', created_at: '2026-01-01T00:00:00Z',
  repeats: 3, image: {width: 32, height: 24},
  references: [{job_id: 100, technique: 'rt_ao', state: 'succeeded', progress: 1, params: {samples: 16},
                ao_stderr_mean: 0.006, timings_ms: timings([500]), links: {job: '/api/v1/jobs/100', 'ao.png': '/api/v1/jobs/100/outputs/ao.png',
                image: '/api/v1/jobs/100/outputs/ao.png'}}],
  candidates: [
    cand(0, 'hbao', 'vulkan', {directions: 8, radius: 100}, 'identity', [25, 27, 30], metrics(0.08), false),
    cand(1, 'hbao', 'cpu', {directions: 8, radius: 100}, 'identity', [9, 10, 11], metrics(0.080000002), true),
    cand(2, 'ssao', 'cpu', {samples: 8}, 'ssao_hemi', [3, 4, 5], metrics(0.3), true),
    cand(3, 'rt_ao', 'cpu', {samples: 16}, 'identity', [55, 60, 70], metrics(0.01, true), true),
  ],
  pareto: [2, 1, 3],
  ranking: {ref_noise: 0.006, at_reference_accuracy: 1, ties_within_noise: 1, noisy_reference: true,
            warning: 'the reference is too noisy to rank the candidates: 1 of 4 are at reference accuracy (RMSE below ' +
                     'twice its noise 0.006), so their RMSEs measure the reference\'s noise, not their error; render the ' +
                     'reference with more samples'},
  links: {self: `/api/v1/comparisons/${ID}`, csv: `/api/v1/comparisons/${ID}.csv`},
};

test('comparison page: mapped reference, noise floor, spreads, hover names, legend, keyboard', async () => {
  const d = await startDashboard();
  try {
    const {browser, page, errors} = await openBrowser();
    try {
      await page.route(`**/api/v1/comparisons/${ID}`, (r) => r.fulfill({json: DOC}));
      // Each PNG a different grey, so the test can tell which one an <img> shows.
      const GREY = {'ao.png': 200, 'error.png': 250, 'reference_mapped.png': 60};
      await page.route('**/api/v1/jobs/*/outputs/*.png', (r) => {
        const name = r.request().url().split('/').pop();
        r.fulfill({contentType: 'image/png', body: greyPng(32, 24, GREY[name] ?? 128)});
      });
      await page.goto(`${d.url}/#/comparisons/${ID}?candidate=2`);
      await page.waitForFunction(() => window.__obscura.comparison && window.__obscura.comparison.rendered === 4);

      // The warning, in words.
      const warn = page.locator('.noisy-reference');
      assert.match(await warn.textContent(), /^Reference too noisy to rank: 1 of 4 are at reference accuracy.*more samples\.$/);

      // Candidate 2 (ssao) was measured against the mapped reference: the slider shows that one.
      const ref = page.locator('section.selected img.ref');
      assert.equal(await ref.getAttribute('src'), '/api/v1/jobs/103/outputs/reference_mapped.png');
      await page.waitForFunction(() => document.querySelector('section.selected img.ref').complete);
      assert.equal(await ref.evaluate((i) => i.naturalWidth), 32);
      assert.match(await page.locator('section.selected figcaption.compared').textContent(),
                   /right: the reference mapped through the ssao_hemi response, as the metrics compared it/);
      assert.match(await ref.getAttribute('alt'), /mapped through ssao_hemi/);

      // The spread in the table and in the candidate's metrics.
      const header = await page.$$eval('table.candidates thead th', (ths) => ths.map((t) => t.textContent));
      const col = header.findIndex((h) => h.startsWith('Spread ms (min–max)'));
      assert.ok(col > 0, header.join(' | '));
      const spreadCell = (i) => page.locator(`table.candidates tr[data-index="${i}"] td`).nth(col).textContent();
      assert.equal(await spreadCell(1), '9.00–11.0');
      assert.equal(await spreadCell(3), '55.0–70.0');
      assert.equal(await page.locator('table.metrics tr', {hasText: 'fastest to slowest run'}).locator('td').textContent(), '3.00–5.00');
      assert.equal(await page.locator('table.candidates tr.pareto').count(), 3, 'hbao on Vulkan is not starred');

      // The chart: the noise floor and one spread bar per point, drawn.
      const chart = await page.evaluate(() => {
        const c = window.__obscura.comparison.chart, u = window.__obscura.comparison.uplot;
        // The dotted line: grey pixels on its row of the canvas.
        const ratio = window.devicePixelRatio || 1;
        const row = Math.round(c.drawn.noiseY * ratio);
        const px = u.ctx.getImageData(u.bbox.left, row - 1, u.bbox.width, 3).data;
        let grey = 0;
        for (let i = 0; i < px.length; i += 4) {
          if (px[i + 3] > 100 && Math.abs(px[i] - 0x77) < 40 && px[i] === px[i + 1] && px[i + 1] === px[i + 2]) grey++;
        }
        const y = u.valToPos(c.noiseFloor, 'y', true) / ratio;
        return {noise: c.noiseFloor, noiseY: c.drawn.noiseY, y, grey, spreads: c.drawn.spreads, list: c.spreads,
                top: u.bbox.top / ratio, bottom: (u.bbox.top + u.bbox.height) / ratio};
      });
      assert.equal(chart.noise, 0.006);
      assert.ok(chart.noiseY > chart.top && chart.noiseY < chart.bottom, JSON.stringify(chart));
      assert.ok(Math.abs(chart.noiseY - chart.y) < 1);
      assert.ok(chart.grey > 10, `the noise floor's dotted line is on the canvas: ${chart.grey} grey pixels`);
      assert.equal(chart.spreads, 4);
      assert.deepEqual(chart.list.find((x) => x.index === 0), {index: 0, min: 25, max: 30});
      assert.match(await page.locator('ul.shape-legend').textContent(), /dotted line: the reference's noise/);

      // The legend: every row shown has a label and no row is empty.
      // (A live legend was a row of "–" values: none is shown.)
      const legend = await page.$$eval('.chart .u-legend .u-series', (rows) => rows
        .filter((r) => r.getClientRects().length && getComputedStyle(r).display !== 'none')
        .map((r) => ({label: (r.querySelector('.u-label') || {}).textContent || '',
                      values: [...r.querySelectorAll('.u-value')].filter((v) => v.getClientRects().length).map((v) => v.textContent)})));
      assert.deepEqual(legend.map((r) => r.label).sort(), ['Pareto front', 'hbao', 'rt_ao', 'ssao'], JSON.stringify(legend));
      assert.deepEqual(legend.flatMap((r) => r.values), [], 'no value cells in the legend');

      // Hover: the nearest point names its candidate.
      const at = await page.evaluate(() => {
        const b = document.querySelector('.chart .pt[data-index="1"]').getBoundingClientRect();
        return {x: b.left + b.width / 2, y: b.top + b.height / 2};
      });
      await page.mouse.move(at.x + 3, at.y + 2);
      const tip = page.locator('.chart .chart-tip');
      await tip.waitFor({state: 'visible'});
      assert.equal(await tip.textContent(), 'Candidate 1: hbao on cpu');
      await page.mouse.move(5, 5);
      await tip.waitFor({state: 'hidden'});
      await screenshot(page, 'comparison-ranking');

      // Keyboard: Tab reaches the chart's points (one tab stop, on the selected candidate), each
      // named; arrows move the selection and the focus in time order; Enter selects.
      assert.equal(await page.locator('.chart .pt[tabindex="0"]').count(), 1);
      await page.locator('h1').focus();
      let onPoint = null;
      for (let i = 0; i < 80 && !onPoint; i++) {
        await page.keyboard.press('Tab');
        onPoint = await page.evaluate(() => (document.activeElement.classList.contains('pt')
          ? {index: Number(document.activeElement.dataset.index), name: document.activeElement.getAttribute('aria-label')} : null));
      }
      assert.ok(onPoint, 'Tab never reached a point of the chart');
      assert.equal(onPoint.index, 2, 'the tab stop is the selected candidate');
      assert.match(onPoint.name, /^Candidate 2: ssao on cpu: median 4\.00 ms, runs 3\.00 to 5\.00 ms, RMSE 0\.300, Pareto-optimal$/);
      await tip.waitFor({state: 'visible'});
      // Time order: 2 (4 ms), 1 (10 ms), 0 (27 ms), 3 (60 ms).
      await page.keyboard.press('ArrowRight');
      await page.waitForFunction(() => window.__obscura.comparison.selected === 1);
      assert.equal(await page.evaluate(() => document.activeElement.dataset.index), '1');
      assert.match(await page.evaluate(() => document.activeElement.getAttribute('aria-label')), /^Candidate 1: hbao on cpu/);
      // Candidate 1 compared its raw reference (identity response).
      assert.equal(await ref.getAttribute('src'), '/api/v1/jobs/100/outputs/ao.png');
      assert.match(await page.locator('section.selected figcaption.compared').textContent(), /right: the reference as rendered/);
      await page.keyboard.press('ArrowRight');
      await page.waitForFunction(() => window.__obscura.comparison.selected === 0);
      assert.match(await page.evaluate(() => document.activeElement.getAttribute('aria-label')), /^Candidate 0: hbao on vulkan.*RMSE 0\.0800$/);
      await page.keyboard.press('ArrowLeft');
      await page.waitForFunction(() => window.__obscura.comparison.selected === 1);
      await page.locator('.chart .pt[data-index="3"]').focus();
      await page.keyboard.press('Enter');
      await page.waitForFunction(() => window.__obscura.comparison.selected === 3);
      await assertAllNamed(page, 'comparison (constructed)');
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});

// References shown (docs/dashboard.md, "Comparisons"): each reference listed by its id and label,
// the table's reference column, the chart's markers grouped by reference with each reference's
// label in the legend and the note that errors of different references are not comparable, the
// common reference's scale, and another output's row under its candidate. Constructed document.
const REF = (id, job, label, roles = ['candidates']) => ({id, job_id: job, technique: 'rt_ao', state: 'succeeded', progress: 1,
  params: {samples: 16}, definition: {}, response: 'identity', label, roles, ao_stderr_mean: 0.006, timings_ms: timings([500]),
  links: {job: `/api/v1/jobs/${job}`}});
const refOf = (r) => ({id: r.id, job_id: r.job_id, label: r.label, definition: r.definition, response: r.response});
const R = [REF('R1', 100, 'rt_ao: weighting uniform, falloff sqrt, max_distance 30.81, tau 1; mapped through ssao_hemi'),
           REF('R2', 110, 'rt_ao: weighting uniform, falloff binary, max_distance 192.1, tau 1'),
           REF('R3', 120, 'rt_ao: weighting cosine, falloff binary, max_distance 200, tau 1', ['candidates', 'common'])];
const withRef = (c, r, common, pareto) => ({...c, reference: refOf(r), reference_job_id: r.job_id, outputs: [],
  common: {reference: refOf(R[2]), reference_job_id: 120, metrics: metrics(common), error: null, pareto}});
const GROUPED = {
  ...DOC, id: ID + 1, references: R, comparable: false,
  note: 'errors measured against different references are not comparable',
  candidates: [withRef(DOC.candidates[2], R[0], 0.2, false), withRef(DOC.candidates[1], R[1], 0.15, true),
               withRef(DOC.candidates[3], R[2], 0.01, true)].map((c, i) => ({...c, index: i})),
  pareto: [0, 1, 2],
  groups: ['R1', 'R2', 'R3'].map((r, i) => ({reference: r, label: R[i].label, candidates: [i], pareto: [i], ranking: DOC.ranking})),
  ranking: {...DOC.ranking, warning: null, noisy_reference: false},
  common: {reference: refOf(R[2]), pareto: [1, 2], ranking: {...DOC.ranking, warning: null, noisy_reference: false}},
  links: {self: `/api/v1/comparisons/${ID + 1}`, csv: `/api/v1/comparisons/${ID + 1}.csv`},
};
GROUPED.candidates[2].outputs = [{output: 'obscurance', reference_output: 'ao', reference_job_id: 110, reference: refOf(R[1]),
                                  metrics: metrics(0.05), error: null}];

test('comparison page: references labelled, reference column, markers by reference, the note, the common scale', async () => {
  const d = await startDashboard();
  try {
    const {browser, page, errors} = await openBrowser();
    try {
      await page.route(`**/api/v1/comparisons/${ID + 1}`, (r) => r.fulfill({json: GROUPED}));
      await page.route('**/api/v1/jobs/*/outputs/*.png', (r) => r.fulfill({contentType: 'image/png', body: greyPng(32, 24, 128)}));
      await page.goto(`${d.url}/#/comparisons/${ID + 1}`);
      await page.waitForFunction(() => window.__obscura.comparison && window.__obscura.comparison.rendered === 3);
      // The References list: each by id and label; the common one says so.
      const items = await page.locator('ul.references li').allTextContents();
      assert.equal(items.length, 3);
      R.forEach((r, i) => assert.ok(items[i].startsWith(`${r.id}: ${r.label}`), items[i]));
      assert.match(items[2], /the common reference/);
      // The reference column: each row names its reference, its label in the cell's title.
      const cells = page.locator('table.candidates td.reference');
      assert.deepEqual(await cells.allTextContents(), ['R1', 'R2', 'R3']);
      assert.equal(await cells.first().getAttribute('title'), R[0].label);
      // The chart: one series per reference named by its label, one Pareto front per reference.
      const chart = await page.evaluate(() => window.__obscura.comparison.chart);
      assert.equal(chart.byReference, true);
      assert.deepEqual(chart.series.map((x) => x.label), R.map((r) => `${r.id}: ${r.label}`));
      const legend = await page.locator('.u-legend .u-series .u-label').allTextContents();
      for (const r of R) assert.ok(legend.includes(`${r.id}: ${r.label}`), legend.join(' | '));
      assert.equal(chart.pareto, 3);
      // The note.
      assert.match(await page.locator('.not-comparable').textContent(),
                   /^Errors measured against different references are not comparable: .*3 references \(R1, R2, R3/);
      // Another output of candidate 2, in a row under it.
      assert.match(await page.locator('tr.output-row[data-of="2"]').textContent(), /candidate 2's obscurance against R2 \(ao\): RMSE 0\.05000/);
      // Common columns, and the chart on the common scale: one reference, all ranked together.
      const header = await page.$$eval('table.candidates thead th', (ths) => ths.map((t) => t.textContent));
      const col = header.findIndex((h) => h.startsWith('RMSE vs common'));
      assert.ok(col > 0, header.join(' | '));
      assert.equal(await page.locator('table.candidates tr[data-index="1"] td').nth(col).textContent(), '0.1500');
      await page.getByLabel(/the common reference R3/).check();
      await page.waitForFunction(() => window.__obscura.comparison.scale === 'common');
      assert.match(page.url(), new RegExp(`#/comparisons/${ID + 1}\\?scale=common$`), 'the route keeps the scale');
      const common = await page.evaluate(() => window.__obscura.comparison.chart);
      assert.equal(common.byReference, false, 'one reference: markers by technique again');
      assert.equal(common.points, 3);
      assert.equal(common.pareto, 2);
      assert.equal(await page.locator('.not-comparable').count(), 0, 'on one scale the note goes');
      await screenshot(page, 'comparison-references');
      await assertAllNamed(page, 'comparison with references');
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});

// The viewer opened from a real comparison's ssao candidate shows as B the reference mapped through
// ssao's response, as the metrics compared it: A - B over the covered pixels has the candidate's
// RMSE, and at a pinned wall pixel the readout's A - B is the candidate minus the mapped value
// (the raw reference there differs from B: it is not the raw job).
test('viewer: candidate against the mapped reference, A - B as the metrics measured it', async () => {
  const d = await startDashboard({workers: 2});
  try {
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'cornell_box.json',
      set: {'/image/width': 32, '/image/height': 24}, repeats: 1, reference: {samples: 16},
      candidates: [{technique: 'ssao', backend: 'cpu', params: {samples: 8}}]}});
    assert.equal(r.status, 201, r.text);
    const deadline = Date.now() + 120000 * SLOW;
    let doc;
    while ((doc = await getJSON(d, `/api/v1/comparisons/${r.json.id}`)).state === 'running') {
      assert.ok(Date.now() < deadline, 'the comparison finishes');
      await new Promise((res) => setTimeout(res, 50));
    }
    assert.equal(doc.state, 'succeeded');
    const cand = doc.candidates[0];
    assert.notEqual(cand.response, 'identity');
    const {browser, page, errors} = await openBrowser();
    try {
      await page.goto(`${d.url}/#/comparisons/${doc.id}?candidate=0`);
      await page.getByRole('link', {name: 'View candidate (A) against reference (B)'}).click();
      await page.waitForFunction(() => {
        const v = window.__obscura.viewer;
        return v && v.ready && v.b;
      });
      // The link names the mapped EXR as B; the viewer keeps it as the stack's reference.
      assert.match(page.url(), new RegExp(`#/view/${cand.job_id}\\?stack=${cand.job_id}%2Freference_mapped\\.exr&ref=2&`));
      const got = await page.evaluate(() => {
        const {a, b} = window.__obscura.viewer;
        const ch = (im, n) => im.img.channels.find((c) => c.name === n).data;
        const [ca, cb, alpha] = [ch(a, 'ao'), ch(b, 'ao'), ch(b, 'alpha')];
        let sq = 0, n = 0;
        for (let i = 0; i < ca.length; i++) if (alpha[i] > 0) { sq += (ca[i] - cb[i]) ** 2; n++; }
        return {file: b.file, rmse: Math.sqrt(sq / n)};
      });
      assert.equal(got.file, 'reference_mapped.exr');
      assert.ok(Math.abs(got.rmse - cand.metrics.rmse) < 1e-5, `A - B RMSE ${got.rmse} vs the metrics' ${cand.metrics.rmse}`);
      // A wall pixel (the back wall, a third of the way down the middle), pinned.
      const [px, py] = [16, 8];
      const s = await page.evaluate(() => window.__obscura.viewer.view);
      const box = await page.locator('canvas.viewer-canvas').boundingBox();
      await page.mouse.click(box.x + 1 + Math.floor(s.panX + (px + 0.5) * s.zoom), box.y + 1 + Math.floor(s.panY + (py + 0.5) * s.zoom));
      await page.waitForFunction(() => window.__obscura.viewer.readout && window.__obscura.viewer.readout.pinned);
      const row = await page.evaluate(() => window.__obscura.viewer.readout.rows.find((x) => x.name === 'ao'));
      const raw = await decodeExr(new Uint8Array((await download(d, await getJSON(d, `/api/v1/jobs/${cand.reference_job_id}`), 'ao.exr')).body).buffer);
      const rawAo = raw.channels.find((c) => c.name === 'ao').data[py * 32 + px];
      assert.ok(Math.abs(row.diff - (row.a - row.b)) < 1e-7);
      assert.ok(Math.abs(row.diff) <= cand.metrics.max_abs + 1e-6, `A - B ${row.diff} within the largest error ${cand.metrics.max_abs}`);
      assert.ok(Math.abs(rawAo - row.b) > 1e-3, `B ${row.b} is the mapped reference, not the raw ${rawAo}`);
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});
