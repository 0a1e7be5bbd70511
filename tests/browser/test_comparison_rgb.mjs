// Browser test of a comparison on an RGB output: path_trace at a few paths per pixel against
// path_trace with many, created through the API, then its page: the page checks of lib.mjs (table,
// chart points, point click, images, slider, sorting, CSV) and what is particular to radiance: the
// error axis and the facts name the luminance RMSE, the table has the per-channel RMSE and relative
// MSE columns, the captions name path_trace as the reference, and the images are the final.png
// outputs at the comparison's size.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, checkComparisonPage, getJSON, imageWidths, openBrowser, request, screenshot, sleep, SLOW,
        startDashboard} from './lib.mjs';

const BODY = {
  scene_file: 'cornell_box.json',
  set: {'/image/width': 32, '/image/height': 24},
  label: 'browser radiance',
  repeats: 1,
  reference: {samples: 1024},
  candidates: [{technique: 'path_trace', backend: 'cpu', params: {samples: [4, 16, 64]}}],
};

test('an RGB comparison: luminance RMSE on the chart and in the table, per-channel columns, images', async () => {
  const d = await startDashboard({workers: 1});
  try {
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: BODY});
    assert.equal(r.status, 201, r.text);
    const id = r.json.id;
    let doc;
    const deadline = Date.now() + 240000 * SLOW;
    for (;;) {
      doc = await getJSON(d, `/api/v1/comparisons/${id}`);
      if (doc.state !== 'running') break;
      assert.ok(Date.now() < deadline, 'the comparison finishes');
      await sleep(100);
    }
    assert.equal(doc.state, 'succeeded', JSON.stringify(doc).slice(0, 2000));
    assert.ok(doc.candidates.every((c) => c.metrics && c.metrics.rgb), 'every candidate has RGB metrics');

    const {browser, page, errors} = await openBrowser();
    try {
      await page.goto(`${d.url}/#/comparisons/${id}`);
      await checkComparisonPage(page, doc, 'comparison-rgb');

      // The error measure: on the chart's axis, in its text summary and in the facts.
      const chart = await page.evaluate(() => ({axis: window.__obscura.comparison.uplot.axes[1].label,
                                               info: window.__obscura.comparison.chart.yLabel,
                                               aria: document.querySelector('.chart').getAttribute('aria-label')}));
      assert.equal(chart.axis, 'RMSE of radiance luminance (log scale)');
      assert.equal(chart.info, chart.axis);
      assert.match(chart.aria, /RMSE of radiance luminance \d/);
      assert.equal(await page.locator('dd.error-measure').textContent(), 'RMSE of radiance luminance');
      // Outputs of other names compared by luminance (obscurance's final against path_trace's
      // radiance) are one measure; AO beside them is another.
      const names = await page.evaluate(async () => {
        const {errorName} = await import('/js/chart.js');
        const c = (output, rgb) => ({metrics: {output, rgb: rgb ? {} : undefined}});
        return [errorName([c('radiance', true), c('final', true)]), errorName([c(null), c('final', true)]),
                errorName([c(null), c(null)])];
      });
      assert.deepEqual(names, ['RMSE of luminance (final, radiance)', 'RMSE (AO; final luminance)', 'RMSE of AO']);
      assert.match(await page.locator('dl.facts').textContent(), new RegExp(`R1: path_trace: max_bounces \\d+.* — job ${doc.references[0].job_id} \\(succeeded`));

      // The table: RMSE (luminance) as the API gives it, the per-channel RMSE and relative MSE.
      const heads = await page.$$eval('table.candidates thead th', (ths) => ths.map((t) => t.textContent.replace(/[▲▼]/g, '').trim()));
      // The metric columns follow the table (GET /api/v1/metrics): FLIP here is HDR-FLIP; figures
      // equal to another (RMSE and SSIM of luminance) and the reference's noise have none.
      for (const h of ['RMSE', 'PSNR dB', 'SSIM', 'FLIP', 'RMSE R / G / B', 'Rel. MSE']) assert.ok(heads.includes(h), `column ${h} in ${heads}`);
      for (const h of ['RMSE of luminance', 'SSIM of luminance', 'Reference noise']) assert.ok(!heads.includes(h), `no column ${h} in ${heads}`);
      assert.match(await page.locator('table.candidates thead th', {hasText: 'FLIP'}).getAttribute('title'), /HDR-FLIP .*\(lower is better\)/);
      const cell = (index, head) => page.locator(`table.candidates tr[data-index="${index}"] td`).nth(heads.indexOf(head)).textContent();
      for (const c of doc.candidates) {
        assert.equal(await cell(c.index, 'RMSE'), c.metrics.rmse.toPrecision(4));
        assert.equal(await cell(c.index, 'RMSE R / G / B'), c.metrics.rgb.rmse.map((v) => v.toPrecision(3)).join(' / '));
        assert.equal(await cell(c.index, 'Rel. MSE'), c.metrics.rgb.rel_mse.toPrecision(4));
        assert.equal(await cell(c.index, 'FLIP'), c.metrics.flip.toPrecision(4));
      }

      // The selected candidate (checkComparisonPage clicked one): its RGB figures and heatmap caption.
      const selected = page.locator('section.selected');
      assert.match(await selected.locator('table.metrics').textContent(), /output comparedradiance \(luminance\)/);
      assert.match(await selected.locator('table.metrics').textContent(), /RMSE of luminance/);
      assert.match(await selected.locator('figure.heatmap figcaption').textContent(), /of radiance luminance/);

      // Images: the reference tile names path_trace, and every image is a 32-pixel-wide final.png.
      assert.match(await page.locator('figure.tile.ref figcaption').textContent(), /path_trace/);
      const srcs = await page.$$eval('.grid img, section.selected img.ref, section.selected img.cand', (imgs) => imgs.map((i) => i.getAttribute('src')));
      assert.equal(srcs.length, doc.candidates.length + 3);
      for (const s of srcs) assert.match(s, /^\/api\/v1\/jobs\/\d+\/outputs\/final\.png$/);
      const widths = await imageWidths(page, '.grid img');
      assert.deepEqual(widths, widths.map(() => 32));
      await screenshot(page, 'comparison-rgb-final');
      await assertAllNamed(page, 'comparison (RGB)');
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});
