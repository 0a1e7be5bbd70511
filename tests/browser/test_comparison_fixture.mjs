// Browser test of the comparison pages against a contract-shaped comparison document
// (docs/comparisons.md) served by playwright's request interception, running first and then
// finished, whose images are real job outputs of a real obscurad: the same page checks as the
// end-to-end test (lib.mjs), plus live update and the way from a candidate to its job, so the
// page is tested whatever the server implements.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, assertNoReload, checkComparisonPage, CSV_HEADER, markPage, openBrowser, screenshot,
        startDashboard, submit, waitAll} from './lib.mjs';

/** A comparison document as docs/comparisons.md describes it, built around real finished jobs. */
function fixture(id, ref, cands, {finished}) {
  const rmse = [0.21, 0.09, 0.15, 0.12];
  const candidates = cands.map((j, i) => {
    const done = finished || i < 2;
    const total = j.timings_ms.build + j.timings_ms.render + 0.05;
    return {
      index: i, job_id: j.id, reference_job_id: ref.id, technique: j.technique, backend: j.backend.actual,
      params: {samples: [4, 16, 8, 16][i]}, state: done ? 'succeeded' : 'running', progress: done ? 1 : 0.5,
      timings_ms: done ? {median: {build: j.timings_ms.build, render: j.timings_ms.render, post: 0.05, total},
                          runs: [{build: j.timings_ms.build, render: j.timings_ms.render, post: 0.05, total}]} : null,
      metrics: done ? {rmse: rmse[i], bias: -0.01 * i, max_abs: 0.5, psnr: 20 - i, ssim: 0.8, ref_noise: 0.02,
                       at_reference_accuracy: false} : null,
      pareto: false, machine: {cpu_model: 'test cpu', cores: 2, vulkan_device: null},
      // error.png stands in with the reference's image: this test checks the page, not the metrics.
      links: {job: `/api/v1/jobs/${j.id}`, 'ao.png': j.links.outputs['ao.png'], 'error.png': ref.links.outputs['ao.png'],
              'reference.png': ref.links.outputs['ao.png']},
    };
  });
  // Pareto: nothing else both faster and more accurate.
  const pts = candidates.filter((c) => c.metrics);
  for (const c of pts) {
    c.pareto = !pts.some((o) => o !== c && o.timings_ms.median.total <= c.timings_ms.median.total && o.metrics.rmse < c.metrics.rmse);
  }
  return {
    id, label: 'fixture', scene: 'cornell_box.json', state: finished ? 'succeeded' : 'running', created_at: ref.created_at,
    repeats: 1, image: {width: 32, height: 24},
    references: [{job_id: ref.id, state: 'succeeded', params: {samples: 64, falloff: 'binary'}, ao_stderr_mean: 0.02,
                  timings_ms: ref.timings_ms, links: {job: `/api/v1/jobs/${ref.id}`, 'ao.png': ref.links.outputs['ao.png']}}],
    candidates,
    pareto: pts.filter((c) => c.pareto).sort((a, b) => a.timings_ms.median.total - b.timings_ms.median.total).map((c) => c.index),
    links: {self: `/api/v1/comparisons/${id}`, csv: `/api/v1/comparisons/${id}.csv`},
  };
}

function csv(doc) {
  const q = (s) => (/[",\n]/.test(s) ? `"${s.replace(/"/g, '""')}"` : s);
  return `${CSV_HEADER}\r\n${doc.candidates.map((c) => [c.index, c.job_id, c.technique, c.backend,
    q(Object.entries(c.params).map(([k, v]) => `${k}=${v}`).join(';')), c.state, c.timings_ms.median.total, c.timings_ms.median.build,
    c.timings_ms.median.render, c.timings_ms.median.post, 1, c.metrics.rmse, c.metrics.bias, c.metrics.max_abs, c.metrics.psnr,
    c.metrics.ssim, c.metrics.ref_noise, c.metrics.at_reference_accuracy, c.pareto, q(c.machine.cpu_model), 2, ''].join(',')).join('\r\n')}\r\n`;
}

test('comparison page against a contract-shaped document (live update, chart, slider, CSV)', async () => {
  const d = await startDashboard({workers: 1});
  const {browser, page, errors} = await openBrowser();
  try {
    const small = {scene_file: 'cornell_box.json', set: {'/image/width': 32, '/image/height': 24}};
    const ids = [];
    ids.push(await submit(d, {...small, technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 64}}}));
    for (const s of [4, 16]) ids.push(await submit(d, {...small, technique: {name: 'rt_ao', backend: 'cpu', params: {samples: s}}}));
    for (const s of [8, 16]) ids.push(await submit(d, {...small, technique: {name: 'ssao', backend: 'cpu', params: {samples: s}}}));
    const [ref, ...cands] = await waitAll(d, ids);
    for (const j of [ref, ...cands]) assert.equal(j.state, 'succeeded');

    // Two answers while running (half the candidates measured), then the finished comparison.
    let gets = 0;
    const finished = fixture(7, ref, cands, {finished: true});
    // Chromium cancels downloads whose request playwright fulfils (microsoft/playwright#28253), so
    // the fixture's CSV link is a data: URL; the page uses links.csv either way.
    finished.links.csv = `data:text/csv;charset=utf-8,${encodeURIComponent(csv(finished))}`;
    await page.route(/\/api\/v1\/comparisons(\/|\?|$)/, (route) => {
      const url = new URL(route.request().url());
      if (url.pathname === '/api/v1/comparisons') {
        return route.fulfill({json: {comparisons: [{id: 7, label: 'fixture', scene: 'cornell_box.json', state: gets > 2 ? 'succeeded' : 'running',
                                                    created_at: ref.created_at, candidates: 4, done: gets > 2 ? 4 : 2}], next: null}});
      }
      if (url.pathname === '/api/v1/comparisons/7') {
        gets++;
        return route.fulfill({json: gets > 2 ? finished : fixture(7, ref, cands, {finished: false})});
      }
      return route.fulfill({status: 404, json: {error: 'not found', problems: []}});
    });

    await page.goto(`${d.url}/#/comparisons`);
    await page.getByRole('link', {name: 'Comparison 7'}).waitFor();
    await assertAllNamed(page, 'comparison list');
    await markPage(page);
    await page.getByRole('link', {name: 'Comparison 7'}).click();
    await page.waitForURL(/#\/comparisons\/7$/);
    // While running: two points; then four, without a reload.
    await page.waitForFunction(() => window.__obscura.comparison.chart && window.__obscura.comparison.chart.points === 2);
    assert.match(await page.locator('.cmp-state').textContent(), /running/);
    await screenshot(page, 'fixture-running');
    await page.waitForFunction(() => window.__obscura.comparison.state === 'succeeded');
    await assertNoReload(page);
    assert.ok(gets >= 3);
    await checkComparisonPage(page, finished, 'fixture-comparison');
    await assertAllNamed(page, 'comparison (fixture)');

    // The candidate opens as a job with its metrics.
    const sel = await page.evaluate(() => window.__obscura.comparison.selected);
    await page.locator('a.open-job').click();
    await page.waitForURL(new RegExp(`#/jobs/${finished.candidates[sel].job_id}\\?comparison=7$`));
    await page.getByRole('heading', {name: 'Metrics against the reference'}).waitFor();
    assert.match(await page.locator('table.metrics').textContent(), new RegExp(`RMSE${finished.candidates[sel].metrics.rmse}`));
    assert.deepEqual(errors, [], 'no script errors');
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
