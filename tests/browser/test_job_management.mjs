// Browser test of job management on the job list and job pages against a real obscurad: the jobs
// of a comparison grouped under one row with each job's role and parameters, a comparison deleted
// as a whole, delete behind a confirmation dialog, retry of a cancelled job, clone into the submit
// form, bulk cancel and delete, paging beyond the newest 50, filters kept in the URL, full dates,
// the list's narrow layout at 800 px, and on job pages: no "null", the device or threads it ran
// on, what a screen-space technique did, readable numbers and the job's log.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, getJSON, openBrowser, request, screenshot, startDashboard, submit, waitAll, waitJob} from './lib.mjs';

const SMALL = {'/image/width': 24, '/image/height': 16};
const tiny = (label) => ({scene_file: 'sphere_on_plane.json', label, technique: {name: 'ssao', backend: 'cpu'}, set: SMALL});
// Long enough to hold the one worker while the test acts on a queued job (tens of seconds), cut
// into tiles so that its cancel lands within one.
const BLOCKER = {scene_file: 'cornell_box.json', set: {'/image/width': 128, '/image/height': 96, '/technique/params/samples': 65536}, priority: 100, label: 'blocker'};

const noOverflow = (page) => page.evaluate(() => document.documentElement.scrollWidth <= window.innerWidth);

test('grouping, confirm, retry, clone, bulk actions, paging, URL filters, narrow layout', async () => {
  const d = await startDashboard({workers: 1});
  const {browser, page, errors} = await openBrowser();
  try {
    // ---- a comparison and plain jobs -----------------------------------------------------------
    const plain = await submit(d, tiny('plain one'));
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, label: 'steps sweep', reference: {samples: 16},
      candidates: [{technique: 'hbao', backend: 'cpu', params: {steps: [2, 4]}}]}});
    assert.equal(r.status, 201, r.text);
    const cid = r.json.id;
    const c = await getJSON(d, `/api/v1/comparisons/${cid}`);
    const members = [...c.references.map((x) => x.job_id), ...c.candidates.map((x) => x.job_id)];
    await waitAll(d, [plain, ...members]);

    await page.goto(`${d.url}/#/jobs`);
    const group = page.locator(`tr.group[data-id="c${cid}"]`);
    await group.waitFor();
    assert.equal(await group.getByRole('link', {name: `Comparison ${cid}`}).getAttribute('href'), `#/comparisons/${cid}`);
    await group.getByText('steps sweep').waitFor();
    // A comparison's jobs start folded under its row; Show unfolds them.
    assert.equal(await page.locator(`tr[data-id="${members[0]}"]`).isHidden(), true, 'folded at first');
    assert.equal(await group.getByRole('button', {name: `Show the jobs of comparison ${cid}`}).getAttribute('aria-expanded'), 'false');
    await group.getByRole('button', {name: `Show the jobs of comparison ${cid}`}).click();
    // Each member says what it is in the comparison, not the same scene and label again.
    for (const x of c.candidates) {
      await page.locator(`tr[data-id="${x.job_id}"] .role`, {hasText: `candidate ${x.index}: hbao on cpu`}).waitFor();
      assert.match(await page.locator(`tr[data-id="${x.job_id}"] .role`).textContent(), new RegExp(`steps=${x.params.steps}`));
    }
    assert.match(await page.locator(`tr[data-id="${c.references[0].job_id}"] .role`).textContent(), /^reference: rt_ao .*samples=16/);
    // The group row comes right above its jobs.
    const order = await page.$$eval('table.jobs tbody tr', (trs) => trs.map((t) => t.dataset.id));
    assert.deepEqual(order, [`c${cid}`, ...members.slice().sort((a, b) => b - a).map(String), String(plain)]);
    // Collapsing hides its jobs.
    await group.getByRole('button', {name: `Hide the jobs of comparison ${cid}`}).click();
    await page.locator(`tr[data-id="${members[0]}"]`).waitFor({state: 'hidden'});
    await group.getByRole('button', {name: `Show the jobs of comparison ${cid}`}).click();
    await page.locator(`tr[data-id="${members[0]}"]`).waitFor();
    // Jobs of a comparison have no Delete of their own.
    assert.equal(await page.getByRole('button', {name: `Delete job ${members[0]}`}).count(), 0);
    // Full dates in the list.
    assert.match(await page.locator(`tr[data-id="${plain}"] td.created`).textContent(), /20\d\d/);
    await assertAllNamed(page, 'jobs with a comparison');
    await screenshot(page, 'jobs-grouped');

    // A candidate's page shows its metrics without ?comparison= in its URL.
    await page.goto(`${d.url}/#/jobs/${c.candidates[0].job_id}`);
    await page.getByRole('heading', {name: 'Metrics against the reference'}).waitFor();
    assert.equal(await page.getByRole('link', {name: new RegExp(`^comparison ${cid}`)}).getAttribute('href'), `#/comparisons/${cid}`);
    await page.goto(`${d.url}/#/jobs`);
    await group.waitFor();

    // ---- delete asks first; Keep keeps --------------------------------------------------------
    await page.getByRole('button', {name: `Delete job ${plain}`}).click();
    const dialog = page.getByRole('dialog');
    await dialog.waitFor();
    assert.match(await dialog.textContent(), new RegExp(`Delete job ${plain} and its outputs\\?`));
    assert.equal(await page.evaluate(() => document.activeElement.textContent), 'Keep', 'the focus starts on Keep');
    await screenshot(page, 'jobs-confirm');
    await dialog.getByRole('button', {name: 'Keep'}).click();
    await dialog.waitFor({state: 'detached'});
    assert.equal((await getJSON(d, `/api/v1/jobs/${plain}`)).state, 'succeeded', 'Keep deletes nothing');
    await page.getByRole('button', {name: `Delete job ${plain}`}).click();
    await page.keyboard.press('Escape');
    await dialog.waitFor({state: 'detached'});
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${plain}`)).status, 200, 'Escape deletes nothing');

    // ---- the comparison deleted as a whole ----------------------------------------------------
    await group.getByRole('button', {name: `Delete comparison ${cid}`}).click();
    await dialog.getByRole('button', {name: 'Delete comparison'}).click();
    await group.waitFor({state: 'detached'});
    for (const id of members) assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 404);
    assert.equal((await request(d, 'GET', `/api/v1/comparisons/${cid}`)).status, 404);

    // ---- retry a cancelled job from the list --------------------------------------------------
    const blocker = await submit(d, BLOCKER);
    await waitJob(d, blocker, (j) => j.state === 'running');
    const queued = await submit(d, tiny('cancel me'));
    await page.getByRole('button', {name: `Cancel job ${queued}`}).click();
    await page.locator(`tr[data-id="${queued}"]`, {hasText: 'cancelled'}).waitFor();
    await page.getByRole('button', {name: `Cancel job ${blocker}`}).click();
    // A running render stops at its next tile: on a loaded machine that can take a while.
    await page.locator(`tr[data-id="${blocker}"]`, {hasText: 'cancelled'}).waitFor({timeout: 120000});
    await page.getByRole('button', {name: `Retry job ${queued}`}).click();
    await page.locator(`tr[data-id="${queued}"]`, {hasText: 'succeeded'}).waitFor();
    const retried = await getJSON(d, `/api/v1/jobs/${queued}`);
    assert.equal(retried.state, 'succeeded');
    assert.equal(retried.label, 'cancel me');

    // ---- clone into the submit form ----------------------------------------------------------
    await page.getByRole('link', {name: `Clone job ${plain} into the submit form`}).click();
    await page.waitForURL(new RegExp(`#/submit\\?clone=${plain}$`));
    await page.getByText(`Filled from job ${plain}`).waitFor();
    assert.equal(await page.getByLabel('Scene file').inputValue(), 'sphere_on_plane.json');
    assert.equal(await page.getByLabel('Image width (pixels)').inputValue(), '24');
    assert.equal(await page.getByLabel('Label').inputValue(), 'plain one');
    const block = page.getByRole('group', {name: 'Technique'});
    assert.equal(await block.getByLabel('Technique', {exact: true}).inputValue(), 'ssao');
    assert.equal(await block.getByLabel('Backend').inputValue(), 'cpu');
    await page.getByLabel('Label').fill('cloned');
    await page.getByRole('button', {name: 'Submit job'}).click();
    await page.waitForURL(/#\/jobs\/\d+$/);
    const cloneId = Number(page.url().match(/#\/jobs\/(\d+)$/)[1]);
    const clone = await waitJob(d, cloneId);
    const orig = await getJSON(d, `/api/v1/jobs/${plain}/document`);
    const copy = await getJSON(d, `/api/v1/jobs/${cloneId}/document`);
    assert.equal(copy.label, 'cloned');
    const tech = (t) => ({name: t.name, backend: t.backend, params: t.params || {}});
    assert.deepEqual(tech(copy.document.technique), tech(orig.document.technique));
    assert.deepEqual({...copy.document, technique: null}, {...orig.document, technique: null}, 'the clone renders the same scene');
    assert.equal(clone.state, 'succeeded');

    // ---- bulk delete with one confirmation ----------------------------------------------------
    await page.goto(`${d.url}/#/jobs`);
    for (const id of [plain, cloneId]) await page.getByRole('checkbox', {name: `Select job ${id}`}).check();
    await page.getByText('2 selected').waitFor();
    await page.getByRole('button', {name: 'Delete selected'}).click();
    assert.match(await dialog.textContent(), /Delete 2 jobs/);
    await dialog.getByRole('button', {name: 'Delete'}).click();
    await page.locator(`tr[data-id="${plain}"]`).waitFor({state: 'detached'});
    for (const id of [plain, cloneId]) assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 404);

    // ---- bulk cancel --------------------------------------------------------------------------
    const b2 = await submit(d, BLOCKER);
    await waitJob(d, b2, (j) => j.state === 'running');
    const q1 = await submit(d, tiny('q1'));
    const q2 = await submit(d, tiny('q2'));
    await page.locator(`tr[data-id="${q2}"]`, {hasText: 'queued'}).waitFor();
    await page.getByRole('checkbox', {name: 'Select every job on this page'}).check();
    await page.getByRole('button', {name: 'Cancel selected'}).click();
    for (const id of [b2, q1, q2]) assert.equal((await waitJob(d, id)).state, 'cancelled', `job ${id}`);

    // ---- paging beyond the newest 50, filters in the URL ---------------------------------------
    const many = [];
    for (let i = 0; i < 52; i++) many.push(await submit(d, tiny(`page ${i}`)));
    await waitAll(d, many);
    await page.goto(`${d.url}/#/jobs?state=succeeded`);
    assert.equal(await page.getByLabel('State').inputValue(), 'succeeded', 'the filter comes from the URL');
    await page.locator(`tr[data-id="${many[51]}"]`).waitFor();
    assert.equal(await page.locator('table.jobs tbody tr').count(), 50);
    await page.getByRole('button', {name: 'Older ›'}).click();
    await page.waitForURL(/after=\d+/);
    assert.match(page.url(), /state=succeeded/);
    await page.locator(`tr[data-id="${many[0]}"]`).waitFor();
    assert.equal(await page.locator(`tr[data-id="${many[51]}"]`).count(), 0);
    // The URL of a page opens that page.
    await page.reload();
    await page.locator(`tr[data-id="${many[0]}"]`).waitFor();
    assert.equal(await page.getByLabel('State').inputValue(), 'succeeded');
    await page.getByRole('button', {name: '« Newest'}).click();
    await page.locator(`tr[data-id="${many[51]}"]`).waitFor();
    assert.doesNotMatch(page.url(), /after=/);
    await page.getByLabel('State').selectOption('cancelled');
    await page.waitForURL(/state=cancelled/);
    await page.locator(`tr[data-id="${q2}"]`).waitFor();
    assert.equal(await page.locator(`tr[data-id="${many[51]}"]`).count(), 0);

    // ---- narrow window: no horizontal overflow -------------------------------------------------
    await page.getByLabel('State').selectOption('');
    await page.locator(`tr[data-id="${many[51]}"]`).waitFor();
    assert.ok(await noOverflow(page), 'no overflow at 1280 px');
    await page.setViewportSize({width: 800, height: 900});
    assert.ok(await noOverflow(page), 'the job list fits 800 px');
    await screenshot(page, 'jobs-800');
    await page.goto(`${d.url}/#/jobs/${many[51]}`);
    await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
    assert.ok(await noOverflow(page), 'a job page fits 800 px');

    assert.deepEqual(errors, [], 'no script errors');
  } finally {
    await browser.close();
    await d.stopClean();
  }
});

test('job pages: no "null" text, where it ran, what a screen-space technique did, readable numbers', async () => {
  const d = await startDashboard({workers: 1, args: ['--max-render-seconds', '1', '--no-estimate-render-time']});
  const {browser, page, errors} = await openBrowser();
  const text = () => page.locator('main').innerText();
  try {
    // Failed (time limit), cancelled while queued, running: none prints a null.
    const failed = await submit(d, BLOCKER);
    await page.goto(`${d.url}/#/jobs/${failed}`);
    await page.locator('.job-state', {hasText: 'running'}).waitFor();
    assert.doesNotMatch(await text(), /null/, 'running job page');
    await page.locator('.job-state', {hasText: 'failed'}).waitFor();
    assert.doesNotMatch(await text(), /null/, 'failed job page');
    assert.match(await text(), /time limit/);
    // Its log on the page: claimed, stopped at the limit, failed.
    const log = page.locator('pre.job-log');
    await log.filter({hasText: 'running -> failed (render time limit of 1 s exceeded)'}).waitFor();
    assert.match(await log.textContent(), /submitted -> queued[\s\S]*queued -> running \(cpu lane, attempt 1\)[\s\S]*time limit/);
    await page.getByRole('button', {name: `Retry job ${failed}`}).waitFor();
    const blocker = await submit(d, {...BLOCKER, priority: 100});
    await waitJob(d, blocker, (j) => j.state === 'running');
    const cancelled = await submit(d, tiny('to cancel'));
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${cancelled}/cancel`)).status, 202);
    await page.goto(`${d.url}/#/jobs/${cancelled}`);
    await page.locator('.job-state', {hasText: 'cancelled'}).waitFor();
    assert.doesNotMatch(await text(), /null/, 'cancelled job page');
    await waitJob(d, blocker);

    // ssao: its depth-buffer samples per pixel, not "rays traced"; hbao: directions × steps.
    // A radius with binary noise prints as people write it.
    const ssao = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'ssao', backend: 'cpu',
      params: {samples: 24, radius: 0.1 + 0.2}}, set: SMALL});
    const hbao = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'hbao', backend: 'cpu',
      params: {directions: 4, steps: 3}}, set: SMALL});
    await waitAll(d, [ssao, hbao]);
    await page.goto(`${d.url}/#/jobs/${ssao}`);
    await page.locator('.work-per-pixel', {hasText: '24'}).waitFor();
    let t = await text();
    assert.match(t, /depth-buffer samples per pixel \(samples\)\s+24/);
    assert.doesNotMatch(t, /rays traced/);
    assert.match(t, /radius=0\.3 /);
    assert.doesNotMatch(t, /0\.30000000000000004/);
    assert.match(t, /ssao on cpu, \d+ threads?:/);
    await page.locator('pre.job-log', {hasText: 'running -> succeeded (ssao/cpu 24x16'}).waitFor();
    assert.doesNotMatch(t, /thread\(s\)|null/);
    await page.goto(`${d.url}/#/jobs/${hbao}`);
    await page.locator('.work-per-pixel', {hasText: '4 × 3 = 12'}).waitFor();
    assert.match(await text(), /depth-buffer samples per pixel \(directions × steps\)\s+4 × 3 = 12/);

    // A Vulkan job names its device instead of a thread count (the answers are rewritten as a
    // Vulkan lane would give them: the test daemon has none).
    await page.route(`**/api/v1/jobs/${hbao}`, async (route) => {
      const j = await (await route.fetch()).json();
      j.backend.actual = 'vulkan';
      j.machine = {cpu_model: 'test cpu', cores: 2, vulkan_device: 'llvmpipe (LLVM 15.0.6, 256 bits)'};
      await route.fulfill({json: j});
    });
    await page.route(`**/api/v1/jobs/${hbao}/outputs/summary.json`, async (route) => {
      const sum = await (await route.fetch()).json();
      sum.backend = 'vulkan';
      await route.fulfill({json: sum});
    });
    await page.goto(`${d.url}/#/jobs`);
    await page.goto(`${d.url}/#/jobs/${hbao}`);
    await page.getByText('hbao on vulkan (device llvmpipe (LLVM 15.0.6, 256 bits)):').waitFor();
    assert.doesNotMatch(await page.locator('.params-slot').innerText(), /thread/);

    // An inline scene shows the name it was submitted with.
    const doc = (await getJSON(d, `/api/v1/jobs/${ssao}/document`)).document;
    const inline = await submit(d, {...doc, scene_name: 'my_scene.json'});
    await page.goto(`${d.url}/#/jobs`);
    await page.locator(`tr[data-id="${inline}"] td.scene`, {hasText: 'my_scene.json (inline)'}).waitFor();
    await page.goto(`${d.url}/#/jobs/${inline}`);
    await page.locator('dl.facts dd', {hasText: 'my_scene.json (inline)'}).waitFor();
    // Its clone pastes the document and keeps the name.
    await page.getByRole('link', {name: `Clone job ${inline} into the submit form`}).click();
    await page.getByText(`Filled from job ${inline} (my_scene.json, its document pasted)`).waitFor();
    assert.equal(await page.locator('#source-paste').isChecked(), true);
    await page.getByRole('button', {name: 'Submit job'}).click();
    await page.waitForURL(/#\/jobs\/\d+$/);
    const inlineClone = await getJSON(d, `/api/v1/jobs/${page.url().match(/#\/jobs\/(\d+)$/)[1]}`);
    assert.deepEqual([inlineClone.scene, inlineClone.scene_name], ['inline', 'my_scene.json']);

    // The list and a job page at 800 px.
    await page.setViewportSize({width: 800, height: 900});
    await page.goto(`${d.url}/#/jobs/${ssao}`);
    await page.locator('.work-per-pixel', {hasText: '24'}).waitFor();
    assert.ok(await noOverflow(page), 'a job page fits 800 px');
    await screenshot(page, 'job-800');
    assert.deepEqual(errors.filter((e) => !/status of 4\d\d/.test(e)), [], 'no script errors');
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
