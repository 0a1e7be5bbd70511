// Browser test of a comparison end to end against the real comparisons API (docs/comparisons.md):
// submitted from the submit page, followed to the end without a reload, then the page checks of
// lib.mjs (table, chart points, point click, images, slider, sorting, CSV); and a candidate
// compared against another reference chosen in the form.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, assertNoReload, checkComparisonPage, getJSON, markPage, openBrowser, screenshot, SLOW,
        startDashboard} from './lib.mjs';

/** The submit page in comparison mode on the Cornell box at w x h, one timed run, 64 reference samples. */
async function openComparisonForm(page, d, w, h) {
  await page.goto(`${d.url}/#/submit`);
  await page.getByRole('radio', {name: /A comparison/}).check();
  await page.getByLabel('Scene file').selectOption('cornell_box.json');
  await page.getByLabel('Image width (pixels)').fill(String(w));
  await page.getByLabel('Image height (pixels)').fill(String(h));
  await page.getByLabel('Timed runs per candidate').fill('1');
  await page.getByLabel('Reference samples').fill('64');
}

/** Starts the comparison and waits on its page until it is no longer running; returns its id. */
async function startAndFollow(page) {
  await page.getByRole('button', {name: 'Start comparison'}).click();
  await page.waitForURL(/#\/comparisons\/\d+/);
  const id = Number(page.url().match(/#\/comparisons\/(\d+)/)[1]);
  await page.waitForFunction(() => window.__obscura.comparison && window.__obscura.comparison.state &&
                             window.__obscura.comparison.state !== 'running', null, {timeout: 120000 * SLOW});
  return id;
}

test('comparison submitted from the submit page, followed to the end', async () => {
  const d = await startDashboard({workers: 1});
  try {
    const {browser, page, errors} = await openBrowser();
    try {
      await openComparisonForm(page, d, 32, 24);
      await page.getByLabel('Label').fill('browser comparison');
      const c1 = page.getByRole('group', {name: 'Candidate 1'});
      await c1.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
      await c1.getByLabel('samples', {exact: true}).fill('4, 16');
      await page.getByRole('button', {name: 'Add candidate'}).click();
      const c2 = page.getByRole('group', {name: 'Candidate 2'});
      await c2.getByLabel('Technique', {exact: true}).selectOption('ssao');
      const backends = c2.getByRole('group', {name: 'Backends'});
      assert.ok(await backends.getByLabel('cpu').isChecked(), 'cpu is ticked by default');
      const ssaoSamples = c2.getByRole('group', {name: 'samples'});
      await ssaoSamples.getByLabel('8', {exact: true}).check();
      await ssaoSamples.getByLabel('16', {exact: true}).check();
      await page.getByText('4 candidates').waitFor();
      await assertAllNamed(page, 'submit (comparison)');
      await screenshot(page, 'comparison-submit');
      await markPage(page);
      const id = await startAndFollow(page);
      await assertNoReload(page);
      const doc = await getJSON(d, `/api/v1/comparisons/${id}`);
      assert.equal(doc.state, 'succeeded', JSON.stringify(doc).slice(0, 2000));
      assert.equal(doc.candidates.length, 4);
      assert.equal(doc.label, 'browser comparison');
      assert.equal(doc.repeats, 1);
      assert.deepEqual(doc.candidates.map((c) => `${c.technique}/${c.backend}/${c.params.samples}`).sort(),
                       ['rt_ao/cpu/16', 'rt_ao/cpu/4', 'ssao/cpu/16', 'ssao/cpu/8']);
      for (const r of doc.references) assert.equal(r.params.samples, 64);
      await checkComparisonPage(page, doc, 'comparison');
      await assertAllNamed(page, 'comparison');
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});

// "Compare against" offers the registry's other references: obscurance's W without colour
// bleeding against rt_ao; the server's refusal lands on the control, then the comparison runs.
test('a candidate compared against another reference, chosen on the submit page', async () => {
  const d = await startDashboard({workers: 1});
  try {
    const {browser, page, errors} = await openBrowser();
    try {
      await openComparisonForm(page, d, 24, 18);
      const c1 = page.getByRole('group', {name: 'Candidate 1'});
      await c1.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
      assert.equal(await c1.getByLabel('Compare against').count(), 0, 'rt_ao offers no other reference');
      await c1.getByLabel('Technique', {exact: true}).selectOption('obscurance');
      const against = c1.getByLabel('Compare against');
      assert.deepEqual(await against.locator('option').allTextContents(),
                       ['its own reference', 'rt_ao, on its obscurance (needs color_bleeding false)']);
      await against.selectOption('rt_ao');
      await c1.getByLabel('samples', {exact: true}).fill('4');
      const bleed = c1.getByRole('group', {name: 'color_bleeding'});
      await bleed.getByLabel('true', {exact: true}).check();
      await page.getByRole('button', {name: 'Start comparison'}).click();
      await page.waitForFunction(() => [...document.querySelectorAll('.field-error')].some((e) => /needs color_bleeding false/.test(e.textContent)));
      await bleed.getByLabel('true', {exact: true}).uncheck();
      await bleed.getByLabel('false', {exact: true}).check();
      const id = await startAndFollow(page);
      const doc = await getJSON(d, `/api/v1/comparisons/${id}`);
      assert.equal(doc.state, 'succeeded', JSON.stringify(doc).slice(0, 2000));
      assert.equal(doc.references[0].technique, 'rt_ao');
      assert.equal(doc.candidates[0].metrics.output, 'obscurance');
      // The candidate's job page says which output its metrics are of.
      await page.goto(`${d.url}/#/jobs/${doc.candidates[0].job_id}`);
      await page.getByText('output compared').first().waitFor();
      assert.equal(await page.locator('tr', {hasText: 'output compared'}).first().locator('td').textContent(), 'obscurance');
      assert.deepEqual(errors, [], 'no script errors');
    } finally {
      await browser.close();
    }
  } finally {
    await d.stopClean();
  }
});
