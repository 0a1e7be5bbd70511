// Browser test of what the comparison page shows about ranking, on a constructed comparison
// document (the real daemon serves the dashboard; this one comparison's JSON and its PNGs are
// answered by the test, so the figures are exact): the slider's reference is the mapped one the
// metrics compared, the noisy-reference warning, the noise floor and the timing spreads drawn on
// the chart, the spread in the table, the candidate's name on hover, a legend without an empty
// row, and points the keyboard reaches that name their candidate.
import assert from 'node:assert/strict';
import zlib from 'node:zlib';
import test from 'node:test';
import {assertAllNamed, openBrowser, screenshot, startDashboard} from './lib.mjs';

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
