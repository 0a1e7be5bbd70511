// Browser test of the job list's keyset paging: with 60 jobs and pages of 50 the second page shows
// the other 10, a page opened from its URL (no history of pages before it) still goes back to the
// newer page, and a filter stays with every page.
import assert from 'node:assert/strict';
import test from 'node:test';
import {openBrowser, startDashboard, submit, waitAll} from './lib.mjs';

const SET = {'/image/width': 24, '/image/height': 16};
const job = (name, i) => ({scene_file: 'sphere_on_plane.json', label: `paging ${i}`, set: SET,
  technique: {name, backend: 'cpu', params: name === 'rt_ao' ? {samples: 2} : {}}});

// Waits until the rows are exactly these jobs (newest first; the list redraws as it polls), and
// says which were shown instead when they never are.
async function shows(page, want, what) {
  const read = () => page.$$eval('table.jobs tbody tr[data-id]', (trs) => trs.map((t) => Number(t.dataset.id)));
  try {
    await page.waitForFunction((w) => JSON.stringify([...document.querySelectorAll('table.jobs tbody tr[data-id]')]
      .map((t) => Number(t.dataset.id))) === w, JSON.stringify(want));
  } catch {
    assert.deepEqual(await read(), want, what);
  }
}

test('the job list pages through 60 jobs, both ways, keeping its filter', async () => {
  const d = await startDashboard();
  const {browser, page, errors} = await openBrowser();
  try {
    // Every 12th job is ssao, the rest rt_ao: 55 rt_ao jobs, so a filtered second page holds 5.
    const all = [];
    for (let i = 0; i < 60; i++) all.push(await submit(d, job(i % 12 === 5 ? 'ssao' : 'rt_ao', i)));
    await waitAll(d, all);
    const newest = [...all].reverse();
    const rt = newest.filter((_, k) => (59 - k) % 12 !== 5);
    assert.equal(rt.length, 55);

    await page.goto(`${d.url}/#/jobs`);
    await shows(page, newest.slice(0, 50));
    await page.getByRole('button', {name: 'Older ›'}).click();
    await page.waitForURL(/after=\d+/);
    await shows(page, newest.slice(50), 'the second page shows the other 10');
    assert.ok(await page.getByRole('button', {name: 'Older ›'}).isDisabled(), 'nothing older');

    // Opened from its URL, the page knows no pages before it: Newer reads the keyset upwards.
    await page.reload();
    await shows(page, newest.slice(50));
    await page.getByRole('button', {name: '‹ Newer'}).click();
    await shows(page, newest.slice(0, 50));
    assert.doesNotMatch(page.url(), /after=/);

    // A page deep in the history, opened from its URL: Newer shows the 50 jobs just above it, not
    // the newest page.
    await page.goto(`${d.url}/#/jobs?after=${all[5]}`);
    await shows(page, newest.slice(55));
    await page.getByRole('button', {name: '‹ Newer'}).click();
    await shows(page, newest.slice(5, 55));
    assert.match(page.url(), new RegExp(`after=${all[54] + 1}`));

    // Filtered: 55 rt_ao jobs are 50 + 5, and the filter stays in the URL of every page.
    await page.getByLabel('Technique').selectOption('rt_ao');
    await page.waitForURL(/technique=rt_ao/);
    await shows(page, rt.slice(0, 50));
    await page.getByRole('button', {name: 'Older ›'}).click();
    await page.waitForURL(/after=\d+/);
    assert.match(page.url(), /technique=rt_ao/);
    await shows(page, rt.slice(50));
    await page.reload();
    await shows(page, rt.slice(50));
    await page.getByRole('button', {name: '‹ Newer'}).click();
    await shows(page, rt.slice(0, 50));
    assert.match(page.url(), /technique=rt_ao/);
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
