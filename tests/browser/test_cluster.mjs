// Browser test of two obscurad sharing one PostgreSQL store: a job submitted to node A and
// rendered there (node C is started only after it finished, so nothing else could run it) is
// listed on node C's dashboard, and its page on node C shows its images, which node C fetches
// from the store (the nodes share no results directory).
// The store is a fresh database on the CTest fixture's server (OBSCURA_TEST_PG_URL) or, without
// one, on a throwaway server started here with tests/pg/pg.sh.
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import test from 'node:test';
import {ROOT, download, getJob, imageWidths, openBrowser, screenshot, startDashboard, submit,
        waitJob} from './lib.mjs';

const PG_BIN = process.env.OBSCURA_PG_BIN || '/usr/lib/postgresql/15/bin';
const PG_SH = path.join(ROOT, 'tests', 'pg', 'pg.sh');

function psql(url, query) {
  const r = spawnSync('psql', ['-X', '-q', '-v', 'ON_ERROR_STOP=1', '-d', url, '-c', query], {encoding: 'utf8'});
  assert.equal(r.status, 0, `psql ${query}: ${r.stderr}`);
}

function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.once('error', reject);
    s.listen(0, '127.0.0.1', () => {
      const {port} = s.address();
      s.close(() => resolve(port));
    });
  });
}

/** A fresh, empty database; returns {url, drop()}. */
async function freshStore() {
  const shared = process.env.OBSCURA_TEST_PG_URL;
  if (shared) {
    const name = `obscura_browser_${process.pid}`;
    const admin = shared.replace(/\/[^/]*$/, '/postgres');
    psql(admin, `DROP DATABASE IF EXISTS ${name}`);
    psql(admin, `CREATE DATABASE ${name}`);
    return {url: shared.replace(/\/[^/]*$/, `/${name}`), drop: () => psql(admin, `DROP DATABASE ${name} WITH (FORCE)`)};
  }
  const base = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-browser-pg-'));
  fs.chmodSync(base, 0o755);  // pg.sh runs the server as postgres when we are root
  const env = {...process.env, OBSCURA_PG_BIN: PG_BIN};
  const r = spawnSync('sh', [PG_SH, 'start', path.join(base, 'pg'), String(await freePort())], {encoding: 'utf8', env});
  assert.equal(r.status, 0, `pg.sh start: ${r.stdout}${r.stderr}`);
  return {url: r.stdout.trim().split('\n').pop(), drop: () => {
    spawnSync('sh', [PG_SH, 'stop', path.join(base, 'pg')], {env});
    fs.rmSync(base, {recursive: true, force: true});
  }};
}

test('node C\'s dashboard shows node A\'s job and its images', async () => {
  const store = await freshStore();
  const node = (name) => startDashboard({workers: 1, store: store.url, args: ['--node-name', name]});
  const started = [];
  try {
    const a = await node('node-a');
    started.push(a);
    const id = await submit(a, {scene_file: 'cornell_box.json', label: 'rendered on A',
                                technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}},
                                set: {'/image/width': 48, '/image/height': 36}});
    const done = await waitJob(a, id);
    assert.equal(done.state, 'succeeded', done.error);
    assert.equal(done.node, 'node-a');
    const c = await node('node-c');
    started.push(c);
    // The same bytes from C, which never rendered it.
    const viaA = await download(a, done, 'ao.png');
    const viaC = await download(c, await getJob(c, id), 'ao.png');
    assert.ok(viaA.body.equals(viaC.body), 'ao.png from node C differs from node A\'s');

    const {browser, page, errors} = await openBrowser();
    try {
      await page.goto(`${c.url}/#/jobs`);
      const row = page.locator('table.jobs tbody tr', {hasText: 'rendered on A'});
      await row.waitFor();
      assert.match(await row.textContent(), /succeeded/);
      await screenshot(page, 'cluster-jobs-on-c');

      await page.goto(`${c.url}/#/jobs/${id}`);
      assert.equal(await page.getByRole('heading', {level: 1}).textContent(), `Job ${id}`);
      await page.locator('.job-state', {hasText: 'succeeded'}).waitFor();
      assert.equal(await page.locator('.job-node').textContent(), 'node-a', 'the job page names the node that ran it');
      assert.deepEqual(await imageWidths(page, 'img.output'), [48, 48, 48], 'ao, bent_normal and depth PNGs load from node C');
      for (const name of ['ao.png', 'bent_normal.png', 'depth.png']) {
        assert.equal(await page.locator(`img.output[src$="/${name}"]`).count(), 1, name);
      }
      await screenshot(page, 'cluster-job-on-c');
      assert.deepEqual(errors, []);
    } finally {
      await browser.close();
    }
    for (const d of started.reverse()) await d.stopClean();
    for (const d of started) fs.rmSync(d.dir, {recursive: true, force: true});
    started.length = 0;
  } finally {
    for (const d of started) await d.kill9();
    store.drop();
  }
});
