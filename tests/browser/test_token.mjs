// Browser test of the dashboard on a daemon with a token: the page asks for the token, logs in
// (POST /api/v1/session), and then the job page's images load and its downloads work although an
// <img> or a link cannot send the bearer header; the list's thumbnails and a comparison's slider,
// heatmap and grid too. Also the header's
// counts after a submission from the page, the comparison form's defaults taken from the server,
// and the favicon the page links.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import test from 'node:test';
import {getJSON, openBrowser, pngSize, request, screenshot, sleep, SLOW, startDashboard, submit, waitJob} from './lib.mjs';

const TOKEN = 'browser-token-0123456789abcdef';

/**
 * The natural widths of the images matching selector once there are some and all have loaded. The
 * pages re-render as they poll, so the images are read in the same turn as they are checked.
 */
async function loadedWidths(page, selector) {
  try {
    const h = await page.waitForFunction((sel) => {
      const imgs = [...document.querySelectorAll(sel)];
      return imgs.length > 0 && imgs.every((i) => i.complete && i.naturalWidth > 0) && imgs.map((i) => i.naturalWidth);
    }, selector);
    return h.jsonValue();
  } catch (e) {
    const now = await page.$$eval(selector, (imgs) => imgs.map((i) => `${i.getAttribute('src')}: complete ${i.complete}, ${i.naturalWidth}`));
    throw new Error(`images ${selector} did not all load: ${now.join('; ') || 'none'} (${e.message.split('\n')[0]})`);
  }
}

test('with a token the job page shows its images and downloads its outputs', async () => {
  const d = await startDashboard({token: TOKEN});
  const {browser, page, errors} = await openBrowser();
  try {
    const id = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}},
      set: {'/image/width': 24, '/image/height': 16}});
    assert.equal((await waitJob(d, id)).state, 'succeeded');

    // No token yet: the API answers 401 and the header asks for the token.
    await page.goto(`${d.url}/#/jobs/${id}`);
    const box = page.locator('#token-box');
    await box.waitFor({state: 'visible'});
    await page.getByLabel('API token').fill(TOKEN);
    await page.getByRole('button', {name: 'Use token'}).click();
    await page.waitForFunction(() => window.__obscura.session && window.__obscura.session.token_required === true);

    // The cookie is HttpOnly: the page's script cannot read it, the browser sends it.
    assert.equal(await page.evaluate(() => document.cookie), '', 'the session cookie is not readable by scripts');
    const cookies = await page.context().cookies();
    const c = cookies.find((k) => k.name === 'obscura_session');
    assert.ok(c, `a session cookie: ${JSON.stringify(cookies)}`);
    assert.equal(c.httpOnly, true);
    assert.equal(c.sameSite, 'Strict');

    await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
    const widths = await loadedWidths(page, 'img.output');
    assert.ok(widths.length >= 1, 'the job page shows its images');
    assert.ok(widths.every((w) => w === 24), `every image loaded at the job's width: ${widths}`);
    await screenshot(page, 'token-job');

    // A download through the plain link.
    const [download] = await Promise.all([page.waitForEvent('download'),
      page.locator('ul.downloads a', {hasText: /^ao\.png$/}).click()]);
    assert.equal(await download.failure(), null, 'the download succeeded');
    const file = fs.readFileSync(await download.path());
    assert.deepEqual(pngSize(file), {width: 24, height: 16}, 'the downloaded file is the PNG');

    // After a reload the stored token logs in before the page's images load.
    await page.context().clearCookies();
    await page.reload();
    await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
    assert.ok((await loadedWidths(page, 'img.output')).every((w) => w === 24), 'images load after a reload');
    assert.ok(await box.isHidden(), 'no token prompt with a stored token');

    // The job list's thumbnails.
    await page.getByRole('link', {name: 'Jobs', exact: true}).click();
    await page.locator(`tr[data-id="${id}"]`).waitFor();
    const thumbs = await loadedWidths(page, 'img.thumb');
    assert.ok(thumbs.length >= 1 && thumbs.every((w) => w > 0), `thumbnails load: ${thumbs}`);

    // A comparison's slider, heatmap and image grid.
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'sphere_on_plane.json',
      set: {'/image/width': 16, '/image/height': 12}, repeats: 1, reference: {samples: 16},
      candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: [2, 4]}}]}});
    assert.equal(r.status, 201, r.text);
    const deadline = Date.now() + 120000 * SLOW;
    for (;;) {
      const doc = await getJSON(d, `/api/v1/comparisons/${r.json.id}`);
      if (doc.state !== 'running') break;
      assert.ok(Date.now() < deadline, 'the comparison finishes');
      await sleep(100);
    }
    await page.goto(`${d.url}/#/comparisons/${r.json.id}`);
    await page.waitForFunction(() => window.__obscura.comparison && window.__obscura.comparison.rendered === 2);
    await page.getByRole('button', {name: 'Show candidate 1'}).click();
    await page.locator('figure.heatmap img').waitFor();
    const cmp = await loadedWidths(page, 'main img');
    assert.ok(cmp.length >= 6 && cmp.every((w) => w === 16), `the comparison's images load: ${cmp}`);
    assert.equal((await loadedWidths(page, 'figure.heatmap img'))[0], 16, 'the heatmap loads');
    await screenshot(page, 'token-comparison');
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});

test('header counts follow a submission; comparison defaults from the server; favicon', async () => {
  const d = await startDashboard({token: TOKEN});
  const {browser, page, errors} = await openBrowser();
  try {
    await page.goto(`${d.url}/`);
    await page.evaluate((t) => localStorage.setItem('obscura-token', t), TOKEN);
    await page.goto(`${d.url}/#/submit?mode=comparison`);
    await page.reload();
    await page.locator('#health', {hasText: '0 queued · 0 running'}).waitFor();

    // The reference's default samples is the server's (1024), not rt_ao's own default (64).
    const defaults = (await getJSON(d, '/api/v1/techniques')).comparison_defaults;
    assert.deepEqual(defaults, {repeats: 3, reference_samples: 1024});
    const ref = page.getByLabel('Reference samples');
    assert.equal(await ref.inputValue(), '1024');
    const hint = await page.locator(`#${await ref.getAttribute('id')}-desc`).textContent();
    assert.match(hint, /default 1024/);
    assert.doesNotMatch(hint, /default 64/);
    assert.equal(await page.getByLabel('Timed runs per candidate').inputValue(), '3');

    // A submission from the page wakes the header's poll: it shows the job without waiting for
    // the next idle poll.
    const wakes = await page.evaluate(() => window.__obscura.health.wakes);
    const long = await page.evaluate(async () => {
      const {api} = await import('/js/api.js');
      const r = await api('/api/v1/jobs', {method: 'POST', json: {scene_file: 'cornell_box.json', label: 'long',
        technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 65536}}, set: {'/image/width': 256, '/image/height': 256}}});
      return r.id;
    });
    await page.locator('#health', {hasText: /1 (queued|running)/}).waitFor();
    assert.ok(await page.evaluate(() => window.__obscura.health.wakes) > wakes, 'the submission woke the header poll');
    const cancel = await request(d, 'POST', `/api/v1/jobs/${long}/cancel`);
    assert.equal(cancel.status, 202);
    await waitJob(d, long);

    // The favicon the page links loads (as an image the browser can decode).
    const icon = await page.evaluate(async () => {
      const href = document.querySelector('link[rel="icon"]').href;
      const img = new Image();
      img.src = href;
      await img.decode();
      return {href, width: img.naturalWidth};
    });
    assert.match(icon.href, /\/favicon\.svg$/);
    assert.ok(icon.width > 0, 'the favicon decodes');
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
