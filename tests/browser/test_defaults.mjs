// Browser test of the first minutes: an empty install says how to submit a first job; the submit
// form's values (a bundled scene's own technique shows the scene's params, another technique its
// defaults with the lengths fitted to the scene's size and a note saying so, a field typed by
// hand survives, a job sent from the form runs with those values); paste mode sends the pasted
// document's params, not a bundled scene's, and a 422 points at the pasted text; the labels of
// the job page, the header's running count, the chart's axes and the viewer's compare list.
import assert from 'node:assert/strict';
import test from 'node:test';
import {getJSON, openBrowser, request, screenshot, sql, startDashboard, submit, waitJob} from './lib.mjs';

test('the submit form shows the scene\'s params, or defaults fitted to the scene', async () => {
  const d = await startDashboard({workers: 1});
  const {browser, page, errors} = await openBrowser();
  try {
    // ---- an empty install says how to submit a first job ---------------------------------------
    await page.goto(`${d.url}/#/jobs`);
    const empty = page.locator('.empty-state');
    await empty.getByRole('heading', {name: 'No jobs yet'}).waitFor();
    assert.equal(await empty.getByRole('link', {name: 'Submit page'}).getAttribute('href'), '#/submit');
    assert.match(await empty.textContent(), /obscura submit scenes\/cornell_box\.json/);
    assert.equal(await page.locator('table.jobs').isVisible(), false, 'no empty table');
    await page.locator('#filter-state').selectOption('failed');
    await empty.getByText('No jobs match these filters.').waitFor();
    await screenshot(page, 'jobs-empty-install');

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

    await pasteMode(d, page);
    await labels(d, page, c.json.id);
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});

// A pasted scene document: the values a bundled scene filled in are cleared (its own params are
// sent), and the server's problems are pointed at in the text.
async function pasteMode(d, page) {
  await page.goto(`${d.url}/#/submit`);
  await page.getByLabel('Scene file').selectOption('cornell_box.json');
  const block = page.getByRole('group', {name: 'Technique'});
  await block.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
  await block.locator('.defaults-note').getByText('declares for rt_ao').waitFor();
  assert.equal(await block.getByLabel('max_distance').inputValue(), '200');
  await page.getByLabel('Paste a scene document').check();
  await block.locator('.defaults-note').getByText('declares for rt_ao').waitFor({state: 'detached'});
  for (const name of ['max_distance', 'falloff']) assert.equal(await block.getByLabel(name).inputValue(), '', `${name} cleared`);
  assert.equal(await block.getByLabel('samples', {exact: true}).inputValue(), '');
  const doc = {
    camera: {type: 'perspective', position: [0, 1, -3], look_at: [0, 0, 0], fov_y: 40},
    image: {width: 16, height: 12},
    objects: [{shape: {type: 'quad', vertices: [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]}},
              {shape: {type: 'sphere', center: [0, 0.5, 0], radius: 0.5}}],
    technique: {name: 'rt_ao', params: {samples: 3, max_distance: 0.75}},
  };
  const text = JSON.stringify(doc, null, 2);
  await page.getByLabel('Scene JSON').fill(text);
  await page.getByRole('button', {name: 'Submit job'}).click();
  await page.waitForURL(/#\/jobs\/\d+$/);
  const id = Number(page.url().match(/#\/jobs\/(\d+)$/)[1]);
  const stored = JSON.parse(sql(d.db, `SELECT doc FROM jobs WHERE id = ${id}`)[0][0]).technique;
  assert.equal(stored.params.samples, 3, "the pasted document's samples, not the Cornell box's 64");
  assert.equal(stored.params.max_distance, 0.75, "the pasted document's max_distance, not the Cornell box's 200");
  await waitJob(d, id);

  // The server refuses a bad radius (a 422 naming inline: /objects/1/shape/radius): the textarea
  // says where, the value is selected, and the listed problem has a button that selects it.
  await page.goto(`${d.url}/#/submit`);
  await page.getByLabel('Paste a scene document').check();
  const bad = text.replace('"radius": 0.5', '"radius": -0.5');
  assert.notEqual(bad, text);
  const ta = page.getByLabel('Scene JSON');
  await ta.fill(bad);
  await page.getByRole('button', {name: 'Submit job'}).click();
  const place = page.locator('.problems button.text-place');
  await place.waitFor();
  const at = bad.indexOf('-0.5');
  const before = bad.slice(0, at).split('\n');
  const where = `line ${before.length}, column ${before[before.length - 1].length + 1}`;
  assert.equal(await place.textContent(), where);
  const err = await page.locator(`#${await ta.getAttribute('id')}-err`).textContent();
  assert.match(err, new RegExp(`^${where}: /objects/1/shape/radius: must be > 0`));
  assert.equal(await ta.getAttribute('aria-invalid'), 'true');
  const selected = () => page.evaluate(() => { const t = document.activeElement; return t.value.slice(t.selectionStart, t.selectionEnd); });
  assert.equal(await selected(), '-0.5', 'the offending value is selected');
  await ta.evaluate((t) => t.setSelectionRange(0, 0));
  await place.click();
  assert.equal(await selected(), '-0.5');
  await screenshot(page, 'submit-paste-422');

  // Not JSON at all: the parser's place as a line and column, before anything is sent.
  await ta.fill('{\n  "image": {"width": 8,,\n}');
  await page.getByRole('button', {name: 'Submit job'}).click();
  assert.match(await page.locator(`#${await ta.getAttribute('id')}-err`).textContent(), /^not a scene document: line 2, column \d+: /);
}

// The job page's image line and work, the header's running count beside a running row, the
// chart's ticks, the viewer's compare list.
async function labels(d, page, cid) {
  const small = {'/image/width': 16, '/image/height': 16};
  // (Its label makes a compare-list entry longer than the 22em the viewer's selects had.)
  const pt = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'path_trace', backend: 'cpu', params: {samples: 12}}, set: small,
    label: 'twelve paths per pixel, a label long enough to be cut'});
  const va = await submit(d, {scene_file: 'volume_torus.json', technique: {name: 'volume_ao', backend: 'cpu', params: {samples: 4}}, set: small});
  await waitJob(d, pt);
  await waitJob(d, va);
  await page.goto(`${d.url}/#/jobs/${pt}`);
  const image = page.locator('dd.image-text');
  await image.getByText('12 paths per pixel').waitFor();
  assert.equal(await image.textContent(), '16×16, 1 pixel sample (image.spp) × 12 paths = 12 paths per pixel');
  await page.goto(`${d.url}/#/jobs/${va}`);
  const work = page.locator('.work-per-pixel');
  await page.waitForFunction(() => { const w = document.querySelector('.work-per-pixel'); return w && w.textContent !== '…'; });
  const summary = await getJSON(d, `/api/v1/jobs/${va}/outputs/summary.json`);
  assert.equal(Number(await work.textContent()), Number(summary.work_per_pixel_sample.toPrecision(4)));
  assert.doesNotMatch(await work.textContent(), /samples|step/, 'a number, not the rule');
  assert.match(await page.getByRole('row', {name: /work per pixel sample/}).textContent(), /work per pixel sample/);

  // A running job: the header's count and the rows agree.
  const long = await submit(d, {scene_file: 'cornell_box.json', set: {'/image/width': 128, '/image/height': 96,
    '/technique/params/samples': 65536}, label: 'long'});
  await page.goto(`${d.url}/#/jobs`);
  await page.locator(`tr[data-id="${long}"] .state`, {hasText: 'running'}).or(
    page.locator(`tr[data-id="${long}"]`, {hasText: 'running'})).first().waitFor();
  await page.locator('#health', {hasText: '· 1 running'}).waitFor({timeout: 3000});
  assert.equal((await request(d, 'POST', `/api/v1/jobs/${long}/cancel`)).status, 202);
  await waitJob(d, long);
  await page.locator('#health', {hasText: '· 0 running'}).waitFor({timeout: 3000});

  // The chart's log axes: at least four ticks each (one point spans a factor of 16).
  await page.goto(`${d.url}/#/comparisons/${cid}`);
  await page.waitForFunction(() => { const u = window.__obscura.comparison && window.__obscura.comparison.uplot;
    return u && u.axes.every((a) => Array.isArray(a._values)); });
  const labels = await page.evaluate(() => window.__obscura.comparison.uplot.axes.map((a) => a._values.filter((v) => v !== null)));
  for (const v of labels) {
    assert.ok(v.length >= 4, `axis labels ${JSON.stringify(v)}`);
    assert.equal(new Set(v).size, v.length, `distinct labels ${JSON.stringify(v)}`);
  }

  // The viewer's compare list is as wide as its longest entry (not cut at 22em).
  await page.goto(`${d.url}/#/view/${va}?compare=1`);
  const sel = page.locator('#v-compare');
  await page.waitForFunction(() => document.querySelectorAll('#v-compare option').length > 1);
  const fit = await sel.evaluate((s) => {
    const cs = getComputedStyle(s);
    const ctx = document.createElement('canvas').getContext('2d');
    ctx.font = `${cs.fontWeight} ${cs.fontSize} ${cs.fontFamily}`;
    const widest = Math.max(...[...s.options].map((o) => ctx.measureText(o.text).width));
    return {widest, width: s.clientWidth};
  });
  assert.ok(fit.width >= fit.widest, `select ${fit.width}px, its longest entry ${fit.widest}px`);
}
