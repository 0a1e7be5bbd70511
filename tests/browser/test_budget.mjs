// Browser test of the budget question and of where each time came from (docs/dashboard.md, "The
// budget question and where times came from"): the devices in the header, the comparison's budget
// input, readout and chart line, its "Timed on" column, the list's answer, a time-budget job
// submitted from the form with its reasoning and actual time, and a job's device label.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, getJSON, openBrowser, request, screenshot, SLOW, sleep, startDashboard, waitJob} from './lib.mjs';

async function waitDone(d, id) {
  const deadline = Date.now() + 120000 * SLOW;
  for (;;) {
    const c = await getJSON(d, `/api/v1/comparisons/${id}`);
    if (c.state !== 'running') return c;
    assert.ok(Date.now() < deadline, 'comparison never finished');
    await sleep(100);
  }
}

test('budget: form, chart line and readout, list answer, auto job reasoning, device labels', async () => {
  // --vulkan: lavapipe here, so the software label is what a reader sees.
  const d = await startDashboard({workers: 1, args: ['--vulkan']});
  try {
    const health = await getJSON(d, '/api/v1/health');
    const vk = health.devices.vulkan;
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: {'/image/width': 16, '/image/height': 12}, repeats: 1, budget_ms: 1000,
      reference: {samples: 16}, candidates: [{technique: 'ssao', params: {samples: 8}}, {technique: 'hbao', backend: 'cpu', params: {directions: 4, steps: 2}}]}});
    assert.equal(r.status, 201, r.text);
    const c = await waitDone(d, r.json.id);
    assert.equal(c.state, 'succeeded');
    const {browser, page, errors} = await openBrowser();
    try {
      // The header names every device the times come from.
      await page.goto(`${d.url}/#/comparisons`);
      await page.waitForFunction((l) => document.getElementById('health').textContent.includes(l), health.devices.cpu.label);
      if (vk) assert.ok((await page.locator('#health').textContent()).includes(vk.label));
      // The list answers without opening the comparison: per reference, best and best under 1000 ms.
      const cell = page.locator('td.answer').first();
      await cell.waitFor();
      assert.match(await cell.textContent(), /best #\d+ \w+\/(cpu|vulkan) .*ms, RMSE/);
      assert.match(await cell.textContent(), /1000 ms/);
      assert.equal(await page.locator('td.answer li').count(), c.answer.groups.length);

      // The comparison page: the request's budget, the readout, the chart's line, the devices.
      await page.goto(`${d.url}/#/comparisons/${c.id}`);
      const budget = page.getByLabel('Time budget (ms)');
      await budget.waitFor();
      assert.equal(await budget.inputValue(), '1000');
      await page.locator('output.budget-readout', {hasText: 'best under 1000 ms'}).first().waitFor();
      await page.waitForFunction(() => window.__obscura.comparison.chart && window.__obscura.comparison.chart.drawn &&
                                 window.__obscura.comparison.chart.drawn.budgetX !== null);
      const times = c.candidates.map((x) => x.timings_ms.median.total);
      // Under the fastest: no candidate fits, said per reference; the line moves with the input.
      const low = Math.min(...times) / 2;
      await budget.fill(String(low));
      await budget.dispatchEvent('change');
      await page.locator('output.budget-readout', {hasText: 'fits'}).waitFor();
      assert.equal(await page.evaluate(() => window.__obscura.comparison.budget), low);
      const text = await page.locator('output.budget-readout').textContent();
      assert.equal((text.match(/none of \d+ fits/g) || []).length, c.answer.groups.length, text);
      assert.ok(await page.evaluate(() => window.__obscura.comparison.chart.budget) === low);
      const timedOn = page.locator('table.candidates td', {hasText: health.devices.cpu.label});
      assert.ok(await timedOn.count() >= 1, 'a Timed on column with the device label');
      if (vk) assert.ok((await page.locator('.device-key').textContent()).includes(vk.label));
      await assertAllNamed(page, 'comparison with a budget');
      await screenshot(page, 'budget-comparison');

      // A time-budget job from the form: the reasoning, then its actual time against the expected.
      await page.goto(`${d.url}/#/submit`);
      await page.getByRole('radio', {name: /technique auto \(fastest within a time budget\)/}).check();
      await page.getByLabel('Scene file').selectOption('cornell_box.json');
      await page.getByLabel('Image width (pixels)').fill('16');
      await page.getByLabel('Image height (pixels)').fill('12');
      assert.match(await page.locator('#time-budget-ms-desc').textContent(), /comparison candidates this server has measured/);
      await page.getByLabel('Time budget (ms)').fill('1000');
      await page.getByRole('button', {name: 'Submit job'}).click();
      await page.waitForURL(/#\/jobs\/\d+/);
      const jid = Number(page.url().match(/#\/jobs\/(\d+)/)[1]);
      await page.getByRole('heading', {name: 'Why this configuration (auto)'}).waitFor();
      const j = await waitJob(d, jid);
      assert.equal(j.state, 'succeeded', j.error);
      await page.locator('section.choice', {hasText: 'ran in'}).waitFor();
      const choice = await page.locator('section.choice').textContent();
      assert.match(choice, /Budget 1000 ms\. Picked \w+ on (cpu|vulkan)/);
      assert.match(choice, /ran in [\d.]+ ms \(median of its timed renders\) against [\d.]+ ms expected/);
      // The scale the pick was ranked on, named, and what was left out as measured elsewhere.
      assert.ok(choice.includes(`Every RMSE weighed here is measured against ${j.choice.reference_label}`), choice);
      assert.equal(await page.locator('table.alternatives tbody tr').count(), j.choice.alternatives.length);
      await assertAllNamed(page, 'auto job');
      await screenshot(page, 'budget-job');

      // A Vulkan candidate's job page says where its time came from.
      const vc = c.candidates.find((x) => x.backend === 'vulkan');
      if (vc) {
        await page.goto(`${d.url}/#/jobs/${vc.job_id}`);
        await page.locator('section p.device', {hasText: vk.label}).waitFor();
        assert.match(vk.label, /\((software|GPU|other)\)$/);
      }
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});
