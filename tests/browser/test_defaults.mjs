// Browser test of the submit form's values: a bundled scene's own technique shows the scene's
// params, another technique its defaults with the lengths fitted to the scene's size and a note
// saying so, a field typed by hand survives, and a job sent from the form runs with those values.
import assert from 'node:assert/strict';
import test from 'node:test';
import {openBrowser, request, screenshot, sql, startDashboard, waitJob} from './lib.mjs';

test('the submit form shows the scene\'s params, or defaults fitted to the scene', async () => {
  const d = await startDashboard({workers: 1});
  const {browser, page, errors} = await openBrowser();
  try {
    await page.goto(`${d.url}/#/submit`);
    await page.getByLabel('Scene file').selectOption('cornell_box.json');
    const block = page.getByRole('group', {name: 'Technique'});
    await block.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
    const note = block.locator('.defaults-note');
    await note.getByText('the parameters cornell_box.json declares for rt_ao').waitFor();
    assert.equal(await block.getByLabel('max_distance').inputValue(), '200');
    assert.equal(await block.getByLabel('samples', {exact: true}).inputValue(), '64');
    assert.equal(await block.getByLabel('falloff').inputValue(), '"binary"');
    assert.equal(await block.getByLabel('Backend').inputValue(), 'cpu');
    await screenshot(page, 'submit-scene-params');

    // Another technique: hbao's radius from the scene's size (a 960-unit diagonal), said so.
    await block.getByLabel('Technique', {exact: true}).selectOption('hbao');
    await note.getByText("hbao's defaults (cornell_box.json declares rt_ao)").waitFor();
    assert.match(await note.textContent(), /hbao radius = [0-9.]+ derived from the scene's size/);
    const radius = Number(await block.getByLabel('radius', {exact: true}).inputValue());
    assert.ok(radius > 200 && radius < 400, `radius ${radius}`);
    assert.equal(await block.getByLabel('directions').inputValue(), '8');
    await screenshot(page, 'submit-derived-defaults');

    // Sent as shown (a small image, the CPU): the radius the form showed, an AO that is neither
    // the white of the fixed default radius 1 nor black.
    await page.getByLabel('Image width (pixels)').fill('32');
    await page.getByLabel('Image height (pixels)').fill('32');
    await block.getByLabel('Backend').selectOption('cpu');
    await page.getByRole('button', {name: 'Submit job'}).click();
    await page.waitForURL(/#\/jobs\/\d+$/);
    const id = Number(page.url().match(/#\/jobs\/(\d+)$/)[1]);
    const job = await waitJob(d, id);
    assert.equal(job.state, 'succeeded');
    const stored = JSON.parse(sql(d.db, `SELECT doc FROM jobs WHERE id = ${id}`)[0][0]).technique;
    assert.equal(stored.params.radius, radius);
    assert.ok(job.stats.ao.mean > 0.2 && job.stats.ao.mean < 0.95, `ao mean ${job.stats.ao.mean}`);

    // Back on the form: a value typed before the scene's params arrive is kept.
    await page.goto(`${d.url}/#/submit`);
    await page.getByLabel('Scene file').selectOption('cornell_box.json');
    const b2 = page.getByRole('group', {name: 'Technique'});
    await b2.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
    await b2.getByLabel('samples', {exact: true}).fill('5');
    await b2.locator('.defaults-note').getByText('declares for rt_ao').waitFor();
    assert.equal(await b2.getByLabel('samples', {exact: true}).inputValue(), '5');
    assert.equal(await b2.getByLabel('max_distance').inputValue(), '200');

    // A job and a comparison sent without the lengths keep the server's notes: their pages say
    // which values were derived.
    const small = {'/image/width': 16, '/image/height': 16};
    const j = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'cornell_box.json', technique: {name: 'hbao'}, set: small}});
    assert.equal(j.status, 201, j.text);
    assert.equal(j.json.notes.length, 1);
    await page.goto(`${d.url}/#/jobs/${j.json.id}`);
    const derived = page.getByRole('region', {name: 'Derived parameters'});
    await derived.waitFor();
    assert.equal((await derived.locator('li').allTextContents()).join('|'), j.json.notes[0]);
    const c = await request(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'cornell_box.json', set: small, repeats: 1,
      reference: {samples: 4}, candidates: [{technique: 'hbao', backend: 'cpu'}]}});
    assert.equal(c.status, 201, c.text);
    await page.goto(`${d.url}/#/comparisons/${c.json.id}`);
    const dd = page.locator('dl.facts dd.notes');
    await dd.waitFor();
    assert.equal(await dd.textContent(), c.json.notes[0]);
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
