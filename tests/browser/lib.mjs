// Shared helpers of the dashboard's browser tests (tests/browser/test_*.mjs): a real obscurad
// (tests/server/lib.mjs) serving web/ and the uPlot files, Debian's chromium driven headless by
// playwright-core with the network kept off, screenshots, accessibility checks, and the checks of
// a finished comparison page that both comparison tests share.
//
//   node tests/browser/test_X.mjs <obscurad> <obscura> [artifacts-dir]
// (ctest passes all three; OBSCURA_ARTIFACTS or build/test-artifacts/browser otherwise).

import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {createRequire} from 'node:module';
import {ROOT, startDaemon, SLOW} from '../server/lib.mjs';

export * from '../server/lib.mjs';
const require = createRequire(path.join(ROOT, 'package.json'));
const {chromium} = require('playwright-core');

const args = process.argv.slice(2).filter((a) => !a.startsWith('--test'));
export const ARTIFACTS = path.resolve(args[2] || process.env.OBSCURA_ARTIFACTS || path.join(ROOT, 'build/test-artifacts/browser'));
fs.mkdirSync(ARTIFACTS, {recursive: true});
export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';

/** obscurad with the dashboard and its npm-served chart library (cwd is ctest's, not the repo). */
export function startDashboard(opts = {}) {
  return startDaemon({...opts, args: ['--vendor-dir', path.join(ROOT, 'node_modules'), '--quiet', ...(opts.args || [])]});
}

/**
 * Headless chromium that cannot reach anything but loopback: no proxy, every host name but
 * 127.0.0.1 unresolvable, and the background services (updates, sync, safe browsing, metrics)
 * off. Returns {browser, page, errors}: errors collects uncaught page errors and console errors.
 */
export async function openBrowser() {
  assert.ok(fs.existsSync(CHROMIUM), `no chromium at ${CHROMIUM} (Debian package chromium)`);
  const flags = ['--disable-background-networking', '--disable-component-update', '--no-first-run',
    '--disable-sync', '--disable-default-apps', '--disable-domain-reliability', '--disable-breakpad',
    '--disable-client-side-phishing-detection', '--disable-features=OptimizationHints,MediaRouter,Translate',
    '--no-pings', '--metrics-recording-only', '--proxy-server=direct://', '--proxy-bypass-list=*',
    '--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1', '--disable-gpu', '--disable-dev-shm-usage'];
  // Chromium's sandbox refuses to run as root (CI containers); elsewhere it stays on.
  if (process.getuid && process.getuid() === 0) flags.push('--no-sandbox');
  const browser = await chromium.launch({executablePath: CHROMIUM, headless: true, args: flags, timeout: 60000 * SLOW});
  const context = await browser.newContext({viewport: {width: 1280, height: 900}, acceptDownloads: true});
  context.setDefaultTimeout(30000 * SLOW);
  const page = await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(`pageerror: ${e.message} ${e.stack}`));
  page.on('console', (m) => {
    // 4xx answers are expected (a refused submission, a probe of the comparisons API) and the
    // page shows them; a 5xx or anything else logged as an error is a bug.
    if (m.type() === 'error' && !/Failed to load resource: the server responded with a status of 4\d\d/.test(m.text())) {
      errors.push(`console: ${m.text()}`);
    }
  });
  return {browser, page, errors};
}

export async function screenshot(page, name) {
  const file = path.join(ARTIFACTS, `${name}.png`);
  await page.screenshot({path: file, fullPage: true});
  return file;
}

/** Marks the document; noReload(page) later proves the page was never reloaded in between. */
export const markPage = (page) => page.evaluate(() => { window.__sentinel = 'still here'; });
export async function assertNoReload(page) {
  assert.equal(await page.evaluate(() => window.__sentinel), 'still here', 'the page was reloaded');
}

const CONTROL_ROLES = 'textbox|combobox|checkbox|radio|button|slider|spinbutton|listbox|searchbox|switch|link';
/**
 * Every interactive element in chromium's accessibility tree has a name, and every form control a
 * <label>, aria-label or aria-labelledby. Returns the number of controls looked at.
 */
export async function assertAllNamed(page, where) {
  const snap = await page.locator('body').ariaSnapshot();
  const unnamed = snap.split('\n').filter((l) => new RegExp(`^\\s*- (${CONTROL_ROLES})(\\s*\\[[^\\]]*\\])*:?\\s*$`).test(l));
  assert.deepEqual(unnamed, [], `${where}: controls without an accessible name:\n${snap}`);
  const bare = await page.$$eval('input, select, textarea', (els) => els
    .filter((e) => e.type !== 'hidden' && !(e.labels && e.labels.length) && !e.getAttribute('aria-label') && !e.getAttribute('aria-labelledby'))
    .map((e) => e.outerHTML.slice(0, 120)));
  assert.deepEqual(bare, [], `${where}: form controls without a label`);
  const n = snap.split('\n').filter((l) => new RegExp(`^\\s*- (${CONTROL_ROLES}) "`).test(l)).length;
  assert.ok(n > 0, `${where}: no controls found in the accessibility tree`);
  return n;
}

/** Resolves once every <img> matching selector has loaded; returns their natural widths. */
export async function imageWidths(page, selector) {
  await page.waitForFunction((sel) => [...document.querySelectorAll(sel)].every((i) => i.complete), selector);
  return page.$$eval(selector, (imgs) => imgs.map((i) => i.naturalWidth));
}

// The metric columns are the metric table's (`obscura metrics`), in its order; then what each row
// is measured against and the common reference's figures.
export const CSV_HEADER = 'index,job_id,technique,backend,params,state,total_ms,build_ms,render_ms,post_ms,runs,' +
  'rmse,bias,max_abs,psnr,ssim,flip,angle_deg,ref_noise,patch_rmse,rmse_r,rmse_g,rmse_b,rmse_luminance,ssim_luminance,rel_mse,' +
  'at_reference_accuracy,pareto,cpu_model,cores,vulkan_device,output,total_ms_min,total_ms_max,' +
  'reference,reference_label,common_rmse,common_bias,common_psnr,common_ssim,common_flip,common_pareto,device';

/**
 * The checks of a finished comparison page (`doc` is its GET /api/v1/comparisons/{id} answer):
 * one table row per candidate, one chart point per candidate with metrics (counted in uPlot's own
 * data arrays), a click on a point selects that candidate, images load, the slider moves the clip,
 * sorting by RMSE, and the CSV download. `prefix` names the screenshots.
 */
export async function checkComparisonPage(page, doc, prefix) {
  const n = doc.candidates.length;
  await page.waitForFunction((k) => window.__obscura.comparison && window.__obscura.comparison.rendered === k, n);
  assert.equal(await page.locator('table.candidates tbody tr[data-index]').count(), n, 'one table row per candidate');

  // The chart: points per technique series, read from uPlot's data arrays.
  const withMetrics = doc.candidates.filter((c) => c.metrics);
  const chart = await page.evaluate(() => {
    const u = window.__obscura.comparison.uplot;
    return {labels: u.series.map((s) => s.label), counts: u.data.map((a) => a.filter((v) => v !== null).length),
            canvas: !!document.querySelector('.chart canvas'), aria: document.querySelector('.chart').getAttribute('aria-label')};
  });
  assert.ok(chart.canvas, 'uPlot drew a canvas');
  // One series per technique; per reference (named by its label) when the candidates have several.
  const byRef = new Set(withMetrics.map((c) => c.reference.id)).size > 1;
  const keyOf = (c) => (byRef ? c.reference.id : c.technique);
  const nameOf = (k) => (byRef ? `${k}: ${doc.references.find((r) => r.id === k).label}` : k);
  const techs = [...new Set(withMetrics.map(keyOf))].map(nameOf);
  assert.deepEqual(chart.labels.slice(1, 1 + techs.length).sort(), [...techs].sort(), 'one series per technique or reference');
  let total = 0;
  for (const t of [...new Set(withMetrics.map(keyOf))]) {
    const k = chart.labels.indexOf(nameOf(t));
    assert.equal(chart.counts[k], withMetrics.filter((c) => keyOf(c) === t).length, `points of ${t}`);
    total += chart.counts[k];
  }
  assert.equal(total, withMetrics.length, 'one point per candidate with metrics');
  // One front (one per reference when the markers are grouped by reference).
  const fronts = chart.labels.map((l, i) => (String(l).startsWith('Pareto front') ? chart.counts[i] : 0));
  assert.equal(fronts.reduce((a, b) => a + b, 0), doc.pareto.length, 'Pareto front points');
  assert.match(chart.aria, new RegExp(`${withMetrics.length} candidates`), 'the chart has a text summary');

  // Clicking a point selects its candidate. Measured timings vary from run to run, so two points
  // may land on the same pixels: the point clicked is the last one (in time order) that lies at
  // least 10 px from every other. Measured after two frames, once layout (and uPlot's resize) has
  // settled.
  const target = await page.evaluate(async () => {
    // The chart in the viewport first: the page above it (references, notes, the budget's
    // answer) may push it below the fold, where a click reaches nothing.
    window.__obscura.comparison.uplot.over.scrollIntoView({block: 'center'});
    for (let k = 0; k < 2; k++) await new Promise((r) => requestAnimationFrame(r));
    const u = window.__obscura.comparison.uplot;
    const order = window.__obscura.comparison.chart.order;
    const box = u.over.getBoundingClientRect();
    const pts = order.map((index, i) => {
      const series = u.data.findIndex((a, si) => si > 0 && si < u.data.length && a[i] !== null && a[i] !== undefined);
      return {index, x: box.left + u.valToPos(u.data[0][i], 'x'), y: box.top + u.valToPos(u.data[series][i], 'y')};
    });
    const apart = (p) => pts.every((q) => q === p || Math.hypot(q.x - p.x, q.y - p.y) >= 10);
    for (let i = pts.length - 1; i >= 0; i--) if (apart(pts[i])) return pts[i];
    return pts[pts.length - 1];
  });
  await page.mouse.move(target.x, target.y);
  await page.mouse.click(target.x, target.y);
  await page.waitForFunction((i) => window.__obscura.comparison.selected === i, target.index);
  assert.equal(await page.locator(`table.candidates tr[data-index="${target.index}"]`).getAttribute('aria-selected'), 'true');
  assert.match(await page.locator('section.selected h2').textContent(), new RegExp(`Candidate ${target.index}:`));

  // Images: grid, slider pair, heatmap.
  const widths = await imageWidths(page, '.grid img, section.selected img');
  assert.ok(widths.length >= n + 2, `images shown: ${widths.length}`);
  for (const w of widths) assert.ok(w > 0, `an image did not load: widths ${widths}`);
  assert.equal(await page.locator('section.selected img.error').count(), 1, 'error heatmap shown');

  // The slider: keyboard moves it and the candidate's clip follows.
  const clip0 = await page.locator('img.cand').evaluate((i) => i.style.clipPath);
  assert.equal(clip0, 'inset(0px 50% 0px 0px)');
  const slider = page.getByLabel('Split between candidate (left) and reference (right)');
  await slider.focus();
  for (let i = 0; i < 5; i++) await page.keyboard.press('ArrowRight');
  assert.equal(await slider.inputValue(), '55');
  assert.equal(await page.locator('img.cand').evaluate((i) => i.style.clipPath), 'inset(0px 45% 0px 0px)');
  await screenshot(page, `${prefix}-selected`);

  // Sorting by RMSE, both ways; rows without metrics go last.
  const rmseOrder = (dir) => [...withMetrics].sort((a, b) => dir * (a.metrics.rmse - b.metrics.rmse) || a.index - b.index).map((c) => String(c.index));
  const rowOrder = () => page.$$eval('table.candidates tbody tr[data-index]', (trs) => trs.map((t) => t.dataset.index));
  await page.getByRole('button', {name: 'RMSE', exact: true}).click();
  assert.deepEqual((await rowOrder()).slice(0, withMetrics.length), rmseOrder(1));
  assert.equal(await page.locator('th[aria-sort="ascending"]').textContent(), 'RMSE ▲');
  await page.getByRole('button', {name: 'RMSE', exact: true}).click();
  assert.deepEqual((await rowOrder()).slice(0, withMetrics.length), rmseOrder(-1));

  // CSV download.
  const [download] = await Promise.all([page.waitForEvent('download'), page.getByRole('link', {name: 'Download CSV'}).click()]);
  const file = path.join(ARTIFACTS, `${prefix}.csv`);
  await download.saveAs(file);
  const lines = fs.readFileSync(file, 'utf8').trim().split(/\r?\n/);
  assert.equal(lines[0], CSV_HEADER, 'CSV header as in docs/comparisons.md');
  const outputs = doc.candidates.reduce((a, c) => a + (c.outputs ? c.outputs.length : 0), 0);
  assert.equal(lines.length, n + outputs + 1, 'one CSV row per candidate and per other output of it');
  await screenshot(page, prefix);
}
