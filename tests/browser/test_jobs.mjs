// Browser test of the jobs pages and the single-job submit form against a real obscurad: the
// vendor allowlist, client-side validation and a server-side refusal on the submit page, a job
// submitted from the page followed to success with its outputs, live progress and a cancel on the
// job list without reloads, filters, keyboard navigation to a job, a job rendered outside its
// technique's guaranteed range marked in the list and its warning shown on its page, a moving
// scene's per-frame figures in its Frames table, and named
// controls everywhere.
import assert from 'node:assert/strict';
import test from 'node:test';
import {assertAllNamed, assertNoReload, getJSON, imageWidths, markPage, openBrowser, request, screenshot,
        startDashboard, submit, waitJob} from './lib.mjs';

test('vendor files: only the allowlist is served from --vendor-dir', async () => {
  const d = await startDashboard();
  try {
    const js = await request(d, 'GET', '/vendor/uplot/uPlot.iife.min.js');
    assert.equal(js.status, 200);
    assert.match(js.headers['content-type'], /^text\/javascript/);
    assert.match(js.text, /uPlot/);
    const css = await request(d, 'GET', '/vendor/uplot/uPlot.min.css');
    assert.equal(css.status, 200);
    assert.match(css.headers['content-type'], /^text\/css/);
    for (const p of ['/vendor/uplot/package.json', '/vendor/uplot/dist/uPlot.esm.js', '/vendor/', '/vendor/../package.json',
                     '/vendor/uplot/../uplot/uPlot.min.css', '/vendor/playwright-core/package.json']) {
      assert.equal((await request(d, 'GET', p)).status, 404, p);
    }
    const index = await request(d, 'GET', '/');
    assert.equal(index.headers['content-security-policy'], "default-src 'self'; frame-ancestors 'none'");
    assert.match(index.text, /js\/main\.js/);
  } finally {
    await d.stopClean();
  }
});

test('jobs, job detail and submit pages', async () => {
  const d = await startDashboard({workers: 1});
  const {browser, page, errors} = await openBrowser();
  try {
    // ---- submit page: labelled controls, client-side validation, a server refusal -----------
    await page.goto(`${d.url}/#/submit`);
    await page.getByLabel('Scene file').selectOption('cornell_box.json');
    await assertAllNamed(page, 'submit (one job)');
    await page.getByLabel('Image width (pixels)').fill('32');
    await page.getByLabel('Image height (pixels)').fill('24');
    await page.getByLabel('Label').fill('from the browser');
    const block = page.getByRole('group', {name: 'Technique'});
    await block.getByLabel('Technique', {exact: true}).selectOption('rt_ao');
    await block.getByLabel('Backend').selectOption('cpu');
    // The scene's values for rt_ao arrive asynchronously; typing waits for them, so what is
    // typed below is what the check sees on any machine, however loaded.
    await block.getByText(/^Values: /).waitFor();
    const samples = block.getByLabel('samples', {exact: true});
    await samples.fill('0');
    await page.getByLabel('Priority').fill('101');
    await page.getByRole('button', {name: 'Submit job'}).click();
    // Nothing was sent: both problems are shown at their fields and the first has the focus.
    await page.getByText('Not sent: 2 problems to fix.').waitFor();
    assert.equal(await samples.getAttribute('aria-invalid'), 'true');
    assert.match(await page.locator(`#${await samples.getAttribute('id')}-err`).textContent(), /must be >= 1 \(got 0\)/);
    assert.match(await page.locator(`#${await page.getByLabel('Priority').getAttribute('id')}-err`).textContent(), /must be <= 100/);
    assert.equal(await page.evaluate(() => document.activeElement.getAttribute('aria-invalid')), 'true');
    await screenshot(page, 'submit-invalid');
    assert.equal((await getJSON(d, '/api/v1/jobs')).jobs.length, 0, 'an invalid form sends nothing');

    // Valid for the form, refused by the server: the problem lands next to max_distance.
    await page.getByLabel('Priority').fill('60');
    await samples.fill('4');
    await block.getByLabel('falloff').selectOption('"sqrt"');
    await block.getByLabel('max_distance').fill('null');
    await page.getByRole('button', {name: 'Submit job'}).click();
    await page.getByText('The server refused it (422)').waitFor();
    const md = block.getByLabel('max_distance');
    assert.equal(await md.getAttribute('aria-invalid'), 'true');
    assert.match(await page.locator(`#${await md.getAttribute('id')}-err`).textContent(), /needs a finite max_distance/);
    await screenshot(page, 'submit-server-problem');

    // ---- a job from the form, followed to success without a reload ---------------------------
    await md.fill('');
    await block.getByLabel('falloff').selectOption('');
    await markPage(page);
    await page.getByRole('button', {name: 'Submit job'}).click();
    await page.waitForURL(/#\/jobs\/\d+$/);
    const id = Number(page.url().match(/#\/jobs\/(\d+)$/)[1]);
    assert.equal(await page.getByRole('heading', {level: 1}).textContent(), `Job ${id}`);
    await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
    await assertNoReload(page);
    const job = await getJSON(d, `/api/v1/jobs/${id}`);
    assert.equal(job.state, 'succeeded');
    assert.equal(job.label, 'from the browser');
    assert.equal(job.priority, 60);
    assert.deepEqual([job.image.width, job.image.height, job.backend.requested], [32, 24, 'cpu']);
    // rt_ao writes the AO, bent normals as colours and depth as PNGs: all load at the image size.
    assert.deepEqual(await imageWidths(page, 'img.output'), [32, 32, 32], 'ao, bent_normal and depth PNGs load');
    for (const name of ['ao.png', 'bent_normal.png', 'depth.png']) {
      assert.equal(await page.locator(`img.output[src$="/${name}"]`).count(), 1, name);
    }
    // Captions come from the registry's declared outputs (typed_outputs[].description).
    assert.match(await page.locator('figure:has(img[src$="/bent_normal.png"]) figcaption').textContent(),
                 /Bent normals as colours/);
    await page.getByRole('heading', {name: 'Timings'}).waitFor();
    for (const stage of ['load', 'build', 'render', 'write', 'total']) {
      assert.equal(await page.locator('table.timings th', {hasText: new RegExp(`^${stage}$`)}).count(), 1, stage);
    }
    await page.getByRole('heading', {name: 'Parameters'}).waitFor();
    assert.match(await page.locator('.params-slot code').textContent(), /samples=4 /);
    assert.deepEqual(await page.$$eval('ul.downloads a', (as) => as.map((a) => a.textContent).sort()), ['ao.exr', 'ao.png', 'bent_normal.png', 'depth.png', 'summary.json']);
    // Inside every guaranteed range: no warnings, so no warnings section.
    assert.deepEqual(job.warnings, []);
    assert.equal(await page.locator('section.warnings').count(), 0);
    await assertAllNamed(page, 'job detail');
    await screenshot(page, 'job-detail');

    // ---- the job list: live progress, a queued job behind it, cancel ------------------------
    const long = await submit(d, {scene_file: 'cornell_box.json', label: 'long',
      // Unbounded rays (the Cornell box's own max_distance of 200 would stay): its first tiles end
      // sooner, so the progress bar moves within the wait below.
      technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 65536, max_distance: null}}, set: {'/image/width': 256, '/image/height': 256}});
    const behind = await submit(d, {scene_file: 'sphere_on_plane.json', label: 'behind',
      technique: {name: 'ssao', backend: 'cpu'}, set: {'/image/width': 32, '/image/height': 24}});
    await page.getByRole('link', {name: 'Jobs', exact: true}).click();
    await page.waitForURL(/#\/jobs$/);
    await markPage(page);
    const progressOf = (jid) => page.evaluate((j) => {
      const p = document.querySelector(`tr[data-id="${j}"] progress`);
      return p ? p.value : -1;
    }, jid);
    await page.waitForFunction((j) => { const p = document.querySelector(`tr[data-id="${j}"] progress`); return p && p.value > 0; }, long);
    const p1 = await progressOf(long);
    assert.ok(p1 > 0 && p1 < 1, `running job's progress ${p1}`);
    // The bar moves on its own while the page stays as it is.
    await page.waitForFunction(([j, v]) => document.querySelector(`tr[data-id="${j}"] progress`).value > v, [long, p1]);
    assert.match(await page.locator(`tr[data-id="${long}"]`).textContent(), /running/);
    assert.match(await page.locator(`tr[data-id="${behind}"]`).textContent(), /queued/);
    await screenshot(page, 'jobs-running');
    await page.getByRole('button', {name: `Cancel job ${long}`}).click();
    await page.locator(`tr[data-id="${long}"]`, {hasText: 'cancelled'}).waitFor();
    await page.locator(`tr[data-id="${behind}"]`, {hasText: 'succeeded'}).waitFor();
    await assertNoReload(page);
    assert.equal((await waitJob(d, long)).state, 'cancelled');

    // ---- filters ---------------------------------------------------------------------------
    const shown = () => page.$$eval('table.jobs tbody tr', (trs) => trs.map((t) => Number(t.dataset.id)));
    const expectRows = async (ids) => {
      await page.waitForFunction((want) => JSON.stringify([...document.querySelectorAll('table.jobs tbody tr')].map((t) => Number(t.dataset.id))) === want,
                                 JSON.stringify(ids));
      assert.deepEqual(await shown(), ids);
    };
    await expectRows([behind, long, id]);
    await page.getByLabel('State').selectOption('cancelled');
    await expectRows([long]);
    await page.getByLabel('State').selectOption('succeeded');
    await expectRows([behind, id]);
    await page.getByLabel('Technique').selectOption('ssao');
    await expectRows([behind]);
    await page.getByLabel('Technique').selectOption('hbao');
    await expectRows([]);
    await page.getByLabel('Technique').selectOption('');
    await page.getByLabel('State').selectOption('');
    await page.getByLabel('Backend').selectOption('cpu');
    await expectRows([behind, long, id]);
    await page.getByLabel('Backend').selectOption('');
    await assertAllNamed(page, 'jobs');
    await screenshot(page, 'jobs');

    // ---- keyboard: from the filters to a job, arrow keys between jobs, Enter opens it -------
    await page.getByLabel('Backend').focus();
    let onLink = false;
    for (let i = 0; i < 10 && !onLink; i++) {
      await page.keyboard.press('Tab');
      onLink = await page.evaluate(() => document.activeElement.classList.contains('job-link'));
    }
    assert.ok(onLink, 'Tab reaches the first job link');
    assert.equal(await page.evaluate(() => document.activeElement.getAttribute('href')), `#/jobs/${behind}`);
    await page.keyboard.press('ArrowDown');
    assert.equal(await page.evaluate(() => document.activeElement.getAttribute('href')), `#/jobs/${long}`);
    await page.keyboard.press('Enter');
    await page.waitForURL(new RegExp(`#/jobs/${long}$`));
    await page.locator('.job-state', {hasText: 'cancelled'}).waitFor();
    assert.equal(await page.evaluate(() => document.activeElement.tagName), 'H1', 'focus moves to the new page heading');
    assert.match(await page.locator('dl.facts').textContent(), /cancelled by request/);

    // ---- a job outside its technique's guaranteed range: marked in the list, warned on its page ---
    const wide = await submit(d, {scene_file: 'sphere_on_plane.json', label: 'too wide',
      technique: {name: 'ssao', backend: 'cpu'}, set: {'/image/width': 32, '/image/height': 24, '/camera/fov_y': 175}});
    const wj = await waitJob(d, wide);
    assert.equal(wj.state, 'succeeded');
    assert.equal(wj.warnings.length, 1, JSON.stringify(wj.warnings));
    assert.match(wj.warnings[0], /^camera fov_y 175 degrees is outside \[[^\]]+\] degrees where ssao on cpu/);
    await page.goto(`${d.url}/#/jobs`);
    const marker = page.locator(`tr[data-id="${wide}"] .warn-marker`);
    await marker.waitFor();
    assert.equal(await marker.getAttribute('aria-label'), '1 warning');
    assert.equal(await marker.getAttribute('title'), wj.warnings[0]);
    assert.equal(await page.locator(`tr[data-id="${behind}"] .warn-marker`).count(), 0, 'no marker without warnings');
    await page.locator(`tr[data-id="${wide}"] a.job-link`).click();
    await page.waitForURL(new RegExp(`#/jobs/${wide}$`));
    await page.getByRole('heading', {name: 'Warnings'}).waitFor();
    assert.deepEqual(await page.$$eval('section.warnings li', (lis) => lis.map((l) => l.textContent)), wj.warnings);
    await assertAllNamed(page, 'job with warnings');
    await screenshot(page, 'job-warnings');

    // ---- a scene with a moving object: one row per frame with the job's figures -------------------
    const moving = await submit(d, {label: 'moving box', camera: {type: 'perspective', position: [0, 2, 4], look_at: [0, 0.3, 0], fov_y: 50},
      image: {width: 24, height: 18},
      objects: [{shape: {type: 'quad', vertices: [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]}, material: {reflectivity: [0.7, 0.7, 0.7]}},
        {shape: {type: 'box', min: [-0.3, 0, -0.3], max: [0.3, 0.6, 0.3]}, material: {reflectivity: [0.3, 0.8, 0.3]},
         transform: {translate: [-1, 0, 0]}, motion: [{translate: [0, 0, 0]}, {translate: [1, 0, 0]}]}],
      technique: {name: 'obscurance_map', params: {method: 'rays', samples: 8, patch_size: 0.5, d_max: 0.8}}});
    const mj = await waitJob(d, moving);
    assert.equal(mj.state, 'succeeded', mj.error);
    await page.goto(`${d.url}/#/jobs/${moving}`);
    await page.getByRole('heading', {name: 'Frames (3)'}).waitFor();
    const frameRows = await page.$$eval('table.frames tbody tr', (trs) => trs.map((tr) => [...tr.children].map((c) => c.textContent)));
    assert.deepEqual(frameRows.map((r) => r[0]), ['0', '1', '2']);
    const heads = await page.$$eval('table.frames thead th', (ths) => ths.map((t) => t.textContent));
    const col = (name) => heads.indexOf(name);
    assert.ok(col('patches updated') > 0 && col('speed-up') > 0 && col('patches differing') > 0, heads.join('|'));
    for (const [i, f] of mj.frames.entries()) {
      assert.equal(frameRows[i][col('patches updated')], String(f.patches_updated));
      if (i > 0) assert.equal(frameRows[i][col('patches differing')], '0', 'exact (the default) equals a full recompute');
    }
    assert.equal(frameRows[0][col('speed-up')], '', 'frame 0 is the full map: no speed-up');
    await assertAllNamed(page, 'job with frames');

    // ---- what a render built, with its memory: proximity_ao's fields and their corner copies ------
    const fielded = await submit(d, {scene_file: 'sphere_on_plane.json', label: 'fields',
      technique: {name: 'proximity_ao', backend: 'cpu', params: {volume_res: 16, min_res: 8, steps: 6}},
      set: {'/image/width': 24, '/image/height': 18}});
    const fj = await waitJob(d, fielded);
    assert.equal(fj.state, 'succeeded', fj.error);
    const fields = fj.built.filter((b) => b.name === 'proximity_field');
    assert.ok(fields.length >= 2, JSON.stringify(fj.built));
    await page.goto(`${d.url}/#/jobs/${fielded}`);
    const total = fj.built.reduce((a, b) => a + b.bytes, 0);
    const size = total < 1024 ? `${total} B` : total < 1 << 20 ? `${(total / 1024).toFixed(1)} KiB` : `${(total / (1 << 20)).toFixed(1)} MiB`;
    await page.getByRole('heading', {name: `Built (${size})`}).waitFor();
    const builtRows = await page.$$eval('table.built tbody tr', (trs) => trs.map((tr) => [...tr.children].map((c) => c.textContent)));
    assert.equal(builtRows.length, fj.built.length);
    const builtHeads = await page.$$eval('table.built thead th', (ths) => ths.map((t) => t.textContent));
    const vox = builtHeads.indexOf('voxels'), tri = builtHeads.indexOf('triangles');
    assert.ok(vox > 0 && tri > 0, builtHeads.join('|'));
    assert.equal(fj.built[0].name, 'bvh', 'the camera rays\' BVH first');
    for (const [i, b] of fj.built.entries()) {
      assert.equal(builtRows[i][0], b.name);
      assert.equal(builtRows[i][vox], b.dims ? b.dims.join(' × ') : '');
      assert.equal(builtRows[i][tri], b.triangles !== undefined ? String(b.triangles) : '');
    }
    assert.ok((await page.locator('table.timings th', {hasText: /^voxelise \(stage\)$/}).count()) === 1, 'stages named as stages');
    await assertAllNamed(page, 'job with built structures');
    await screenshot(page, 'job-built');

    // ---- API text is shown as text; the skip link stays on the page; Delete leaves the page --------
    const xss = '<img src=x onerror="window.__pwned=1">';
    const tiny = await submit(d, {scene_file: 'sphere_on_plane.json', label: xss,
      technique: {name: 'ssao', backend: 'cpu'}, set: {'/image/width': 32, '/image/height': 24}});
    await page.goto(`${d.url}/#/jobs/${tiny}`);
    await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
    assert.ok((await page.locator('dl.facts').textContent()).includes(xss), 'the label is shown literally');
    assert.equal(await page.evaluate(() => window.__pwned), undefined, 'no markup from the API ran');
    await page.locator('a.skip').focus();
    await page.keyboard.press('Enter');
    assert.match(page.url(), new RegExp(`#/jobs/${tiny}$`), 'the skip link does not change the page');
    assert.equal(await page.evaluate(() => document.activeElement.id), 'view');
    await page.getByRole('button', {name: `Delete job ${tiny}`}).click();
    await page.getByRole('dialog').getByRole('button', {name: 'Delete'}).click();
    await page.waitForURL(/#\/jobs$/);
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${tiny}`)).status, 404, 'the job is gone');

    assert.deepEqual(errors, [], 'no script errors');
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
