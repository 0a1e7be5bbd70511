// Browser test of the fault banner: with the database file replaced under a running daemon (work
// refused, health "error"), every page shows what failed and what to do above its content, and
// the banner is absent while the server is healthy.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import test from 'node:test';
import {openBrowser, request, screenshot, sleep, SLOW, startDashboard, submit, waitJob} from './lib.mjs';

test('fault banner on every page while the database is lost', async () => {
  const d = await startDashboard();
  try {
    const id = await submit(d, {scene_file: 'sphere_on_plane.json', set: {'/image/width': 32, '/image/height': 32}});
    await waitJob(d, id);
    const {browser, page, errors} = await openBrowser();
    try {
      await page.goto(`${d.url}/#/jobs`);
      await page.getByRole('heading', {level: 1}).waitFor();
      await page.waitForFunction(() => /server ok/.test(document.getElementById('health').textContent));
      assert.equal(await page.locator('#fault-banner').isHidden(), true, 'banner shown while healthy');
      for (const s of ['', '-wal', '-shm']) fs.rmSync(d.db + s, {force: true});
      fs.writeFileSync(d.db, 'not the database\n');
      const deadline = Date.now() + 15000 * SLOW;
      for (;;) {
        const r = await request(d, 'GET', '/api/v1/health');
        if (r.json && r.json.status === 'error') break;
        assert.ok(Date.now() < deadline, 'health never "error"');
        await sleep(100);
      }
      for (const hash of ['#/jobs', '#/comparisons', '#/submit', `#/jobs/${id}`]) {
        await page.goto(`${d.url}/${hash}`);
        const banner = page.getByRole('alert').filter({hasText: 'Not accepting work'});
        await banner.waitFor();
        const text = await banner.textContent();
        assert.match(text, /deleted or replaced/, `${hash}: ${text}`);
        assert.match(text, /recovered-/, `${hash}: the banner says what to do: ${text}`);
      }
      await screenshot(page, 'fault-banner');
      // Health answers 503 while work is refused: the only console errors allowed.
      const bad = errors.filter((e) => !/status of 503/.test(e));
      assert.deepEqual(bad, []);
    } finally {
      await browser.close();
    }
  } finally {
    await d.kill9();
    fs.rmSync(d.dir, {recursive: true, force: true});
  }
});
