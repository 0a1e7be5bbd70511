// Test of the dashboard's image viewer (web/js/viewer.js, viewcanvas.js, exr.js): the EXR decoder
// against files written by another encoder (OpenImageIO's OpenEXR, tests/data/exr/README.md), then
// in the browser against real jobs: opened from a job page, decoded channel statistics equal to the
// renderer's summary.json, zoom and pan (buttons, keys, wheel, drag), a pinned pixel's readout
// against the decoded data and the PNG the renderer wrote, exposure +1 doubling the linear value
// before the tone map, A/B toggle and split wipe with the difference readout, the comparison page's
// way in, Escape, named controls and the 800 px layout.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import test from 'node:test';
import {assertAllNamed, getJSON, openBrowser, request, ROOT, screenshot, SLOW, startDashboard, submit, waitAll} from './lib.mjs';
import {decodeExr, ExrError} from '../../web/js/exr.js';
import {quantize as viewQuantize, toneByte} from '../../web/js/viewcanvas.js';

const FIXTURES = path.join(ROOT, 'tests/data/exr');
const load = (name) => {
  const b = fs.readFileSync(path.join(FIXTURES, name));
  return decodeExr(b.buffer.slice(b.byteOffset, b.byteOffset + b.length));
};

// renderer/core/png.c's quantisation, written out again: sRGB curve, clamp, round half up, NaN 0.
const srgb = (v) => (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055);
const linear = (b) => {
  const v = b / 255;
  return v <= 0.04045 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4);
};
const quantize = (v, gamma) => (Number.isNaN(v) ? 0 : Math.floor((gamma ? srgb(Math.min(1, Math.max(0, v))) : Math.min(1, Math.max(0, v))) * 255 + 0.5));

test('EXR decoder: every compression obscura can write, HALF and FLOAT, refusals', async () => {
  const ref = await load('checker_none.exr');
  assert.deepEqual([ref.width, ref.height, ref.compression], [24, 19, 'NONE']);
  assert.deepEqual(ref.channels.map((c) => `${c.name}:${c.type}`), ['B:FLOAT', 'G:FLOAT', 'R:FLOAT']);
  // oiiotool's checker of 5x3 cells: colour 1 (0.25, 0.5, 1) and colour 2 (2, 0.125, -3).
  const c1 = {R: 0.25, G: 0.5, B: 1}, c2 = {R: 2, G: 0.125, B: -3};
  const first = ref.channels.find((c) => c.name === 'R').data[0] === c1.R ? [c1, c2] : [c2, c1];
  for (const c of ref.channels) {
    for (let y = 0; y < 19; y++) {
      for (let x = 0; x < 24; x++) {
        const cell = (Math.floor(x / 5) + Math.floor(y / 3)) % 2;
        assert.equal(c.data[y * 24 + x], first[cell][c.name], `${c.name} at (${x}, ${y})`);
      }
    }
  }
  for (const [file, compression, type] of [['checker_rle.exr', 'RLE', 'FLOAT'], ['checker_zips.exr', 'ZIPS', 'FLOAT'],
    ['checker_zip.exr', 'ZIP', 'FLOAT'], ['checker_half_zip.exr', 'ZIP', 'HALF']]) {
    const img = await load(file);
    assert.equal(img.compression, compression, file);
    assert.ok(img.channels.every((c) => c.type === type), file);
    // The checker's values are exact in HALF too: every file decodes to the same bits.
    img.channels.forEach((c, k) => assert.deepEqual(c.data, ref.channels[k].data, `${file} ${c.name}`));
  }
  // Smooth float data does not compress: ZIPS chunks stored as they are (size == raw size).
  const smooth = await load('fill_none.exr'), stored = await load('fill_zips.exr');
  assert.equal(stored.compression, 'ZIPS');
  stored.channels.forEach((c, k) => assert.deepEqual(c.data, smooth.channels[k].data, `fill ${c.name}`));
  for (const [file, why] of [['refuse_piz.exr', /PIZ compression is not read/], ['refuse_tiled.exr', /tiled EXR files/],
    ['refuse_uint.exr', /pixel type UINT/]]) {
    await assert.rejects(load(file), (e) => e instanceof ExrError && why.test(e.message), file);
  }
  await assert.rejects(decodeExr(new Uint8Array([1, 2, 3, 4, 5, 6, 7, 8]).buffer), /not an OpenEXR file/);
  const whole = fs.readFileSync(path.join(FIXTURES, 'checker_zip.exr'));
  const cut = whole.subarray(0, whole.length - 40);
  await assert.rejects(decodeExr(cut.buffer.slice(cut.byteOffset, cut.byteOffset + cut.length)), ExrError, 'a truncated file');
});

test('tone map: the table search gives the PNG writer\'s byte for every kind of float', () => {
  const f = new Float32Array(1), bits = new Uint32Array(f.buffer);
  const specials = [0, -0, -1, 1, 2, Infinity, -Infinity, NaN, 1e-45, 0.0031308, 0.5, 0.99999994];
  let n = 0;
  const check = (v) => {
    assert.equal(toneByte(v), viewQuantize(v, true), `float ${v}`);
    assert.equal(viewQuantize(v, true), quantize(v, true), `float ${v} against the test's own quantisation`);
    n++;
  };
  specials.forEach(check);
  // Every float32 in [2^-20, 1.5) at a stride, and each step's float and the one before it.
  for (let b = 0x35800000; b < 0x3fc00000; b += 997) {
    bits[0] = b;
    check(f[0]);
  }
  for (let q = 1; q < 256; q++) {
    let lo = 0, hi = 0x3f800000;
    while (lo < hi) {
      const mid = (lo + hi) >>> 1;
      bits[0] = mid;
      if (quantize(f[0], true) >= q) hi = mid;
      else lo = mid + 1;
    }
    for (const b of [lo - 1, lo]) {
      bits[0] = b;
      check(f[0]);
    }
  }
  assert.ok(n > 100000);
});

// ---- in the browser -----------------------------------------------------------------------------


const viewer = (page) => page.evaluate(() => {
  const v = window.__obscura.viewer;
  return {...v.view, ready: v.ready, output: v.output, stops: v.stops, b: v.b ? v.b.id : null, readout: v.readout || null};
});
/** Waits until the viewer is ready, showing job `b` as B and output `output` when given. */
const waitViewer = (page, want = {}) => page.waitForFunction((w) => {
  const v = window.__obscura.viewer;
  return v && v.ready && (w.b === undefined || (v.b && v.b.id === w.b)) && (w.output === undefined || v.output === w.output);
}, want);
/** Canvas coordinates of the centre of image pixel (x, y); page coordinates with the canvas box. */
async function spot(page, x, y) {
  const s = await viewer(page);
  const box = await page.locator('canvas.viewer-canvas').boundingBox();
  const cx = Math.floor(s.panX + (x + 0.5) * s.zoom), cy = Math.floor(s.panY + (y + 0.5) * s.zoom);
  return {cx, cy, px: box.x + 1 + cx, py: box.y + 1 + cy};
}
const canvasRGB = (page, cx, cy) => page.evaluate(([x, y]) =>
  [...document.querySelector('canvas.viewer-canvas').getContext('2d').getImageData(x, y, 1, 1).data].slice(0, 3), [cx, cy]);
/** RGB of pixel (x, y) of a PNG as the browser decodes it. */
const pngRGB = (page, url, x, y) => page.evaluate(async ([u, px, py]) => {
  const img = new Image();
  img.src = u;
  await img.decode();
  const c = document.createElement('canvas');
  c.width = img.naturalWidth;
  c.height = img.naturalHeight;
  const g = c.getContext('2d');
  g.drawImage(img, 0, 0);
  return [...g.getImageData(px, py, 1, 1).data].slice(0, 3);
}, [url, x, y]);
/** The float value of channel `name` at pixel (x, y) of image A or B, as decoded. */
const decoded = (page, which, name, x, y) => page.evaluate(([w, n, px, py]) => {
  const im = window.__obscura.viewer[w].img;
  return im.channels.find((c) => c.name === n).data[py * im.width + px];
}, [which, name, x, y]);
const readoutCell = (page, channel, col) => page.locator(`.readout-box tr[data-channel="${channel}"] td.${col}`).textContent();

/** The viewer's stack, shown image and reference, as the page holds them. */
const stackState = (page) => page.evaluate(() => {
  const v = window.__obscura.viewer;
  return {ids: v.stack.map((e) => e.id), cur: v.cur, ref: v.ref, a: v.a.id, show: v.show};
});

/**
 * The error maps of A against the reference B, computed here again from the decoded EXRs (stored
 * as float32, as the viewer's map is): per pixel, for channel `ch`, the mode's error; covered
 * where B's alpha is above 0 and the error finite; the ramp's range (signed: ± the largest
 * |error|, the others 0 to the largest) and the counts of 64 equal bins over it.
 */
const expectedError = (page, mode, ch) => page.evaluate(([m, c]) => {
  const v = window.__obscura.viewer, w = v.a.img.width;
  const plane = (img, n) => (img.channels.find((x) => x.name === n) || {}).data;
  const A = plane(v.a.img, c), B = plane(v.b.img, c), alpha = plane(v.b.img, 'alpha');
  const f = {signed: (a, b) => a - b, absolute: (a, b) => Math.abs(a - b), relative: (a, b) => Math.abs(a - b) / (Math.abs(b) + 0.01),
             squared: (a, b) => (a - b) ** 2}[m];
  const e = new Float32Array(A.length), cov = [];
  let top = 0;
  for (let i = 0; i < A.length; i++) {
    e[i] = f(A[i], B[i]);
    cov[i] = (!alpha || alpha[i] > 0) && Number.isFinite(e[i]);
    if (cov[i]) top = Math.max(top, m === 'signed' ? Math.abs(e[i]) : e[i]);
  }
  const [lo, hi] = m === 'signed' ? [-top, top] : [0, top];
  const counts = new Array(64).fill(0);
  for (let i = 0; i < A.length; i++) if (cov[i]) counts[Math.min(63, Math.max(0, Math.floor(((e[i] - lo) / (hi - lo)) * 64)))]++;
  return {lo, hi, counts, total: cov.filter(Boolean).length, e: [...e], cov, w};
}, [mode, ch]);

/**
 * A stack of three images (rt_ao at 8 and at 2 samples, hbao) restored from its URL; number keys
 * switch the image shown; each error mode's value at pinned pixels and its histogram against the
 * EXRs; the URL keeps the error mode across a reload.
 */
async function checkStack(page, d, {ao, ao2, hb, pt}) {
  await page.goto(`${d.url}/#/view/${ao}?stack=${ao2},${hb}&ref=2`);
  await page.waitForFunction(() => { const v = window.__obscura.viewer; return v && v.ready && v.stack && v.stack.length === 3; });
  assert.deepEqual(await stackState(page), {ids: [ao, ao2, hb], cur: 0, ref: 1, a: ao, show: 'image'}, 'the URL gives the stack');
  assert.equal(await page.locator('ol.image-stack li').count(), 3);
  const [px, py] = [9, 14];
  const at = await spot(page, px, py);
  await page.locator('canvas.viewer-canvas').focus();
  for (const [key, id] of [['3', hb], ['2', ao2], ['1', ao]]) {
    await page.keyboard.press(key);
    const st = await stackState(page);
    assert.deepEqual([st.cur, st.a], [Number(key) - 1, id], `key ${key} shows job ${id}`);
    const g = quantize(await decoded(page, 'a', 'ao', px, py), false);
    assert.deepEqual(await canvasRGB(page, at.cx, at.cy), [g, g, g], `the canvas shows job ${id}`);
    assert.equal(await page.locator('ol.image-stack li.current').getAttribute('data-index'), String(Number(key) - 1));
  }
  assert.match(page.url(), new RegExp(`stack=${ao2}%2C${hb}&ref=2`), 'the URL keeps the stack');
  await page.mouse.click(at.px, at.py);
  const pins = [[px, py], [3, 20], [30, 2]];
  for (const mode of ['signed', 'absolute', 'relative', 'squared']) {
    await page.getByLabel('Error map', {exact: true}).selectOption(mode);
    await page.waitForFunction((m) => window.__obscura.viewer.error && window.__obscura.viewer.error.mode === m && window.__obscura.viewer.error.counts, mode);
    const want = await expectedError(page, mode, 'ao');
    const got = await page.evaluate(() => window.__obscura.viewer.error);
    assert.deepEqual([got.lo, got.hi], [want.lo, want.hi], `${mode}: the ramp's range`);
    assert.deepEqual(got.counts, want.counts, `${mode}: the histogram's counts`);
    assert.equal(got.total, want.total, `${mode}: covered pixels`);
    assert.ok(want.total > 300 && want.hi > 0, `${mode}: the two renders differ: ${JSON.stringify(want).slice(0, 200)}`);
    for (const [x, y] of pins) {
      const e = want.e[y * want.w + x], va = await decoded(page, 'a', 'ao', x, y), vb = await decoded(page, 'b', 'ao', x, y);
      if (mode === 'signed') assert.equal(e, Math.fround(va - vb), 'the test\'s own A − B');
      assert.equal(await page.evaluate(([x_, y_]) => window.__obscura.viewer.errorAt(x_, y_), [x, y]), want.cov[y * want.w + x] ? e : null,
        `${mode} at (${x}, ${y})`);
    }
    assert.ok(want.cov[py * want.w + px], `pixel (${px}, ${py}) is covered`);
    const shown = Number(await page.locator('.readout-error .err-value').textContent());
    assert.ok(Math.abs(shown - want.e[py * want.w + px]) <= 1e-6 * Math.max(1, Math.abs(shown)), `${mode}: the readout's error`);
    const ticks = await page.locator('.error-panel .ticks span').allTextContents();
    assert.equal(ticks.length, 3, 'the legend has its scale');
    assert.ok(Math.abs(Number(ticks[2]) - want.hi) <= 0.005 * want.hi, `${mode}: the legend ends at ${want.hi}: ${ticks}`);
    assert.match(await page.locator('canvas.histogram').getAttribute('aria-label'), new RegExp(`over ${want.total} covered pixels`));
  }
  await screenshot(page, 'viewer-error-squared');
  assert.match(page.url(), /show=squared/);
  // A ramp maximum of the user's: the histogram's bins span it, larger errors in the last bin.
  await page.getByLabel('Ramp maximum', {exact: true}).fill('0.001');
  await page.getByLabel('Ramp maximum', {exact: true}).press('Enter');
  await page.waitForFunction(() => window.__obscura.viewer.error.hi === 0.001);
  // The URL restores the stack, the reference and the mode.
  await page.reload();
  await page.waitForFunction(() => { const v = window.__obscura.viewer; return v && v.ready && v.error && v.error.counts; });
  assert.deepEqual(await stackState(page), {ids: [ao, ao2, hb], cur: 0, ref: 1, a: ao, show: 'squared'}, 'a reload restores the view');
  assert.equal(await page.evaluate(() => window.__obscura.viewer.error.hi), 0.001);
  // A file by name: a job's EXR output as "<job>/<file>.exr"; a bad name says why.
  await page.getByLabel('or by name', {exact: true}).fill(`${ao2}/nope.exr`);
  await page.getByLabel('or by name', {exact: true}).press('Enter');
  await page.waitForFunction(() => /Cannot add \d+\/nope.exr: job \d+ has no output nope.exr/.test(document.querySelector('p.error').textContent));
  // The file an entry already shows is not added twice; path_trace's radiance.exr by name is.
  await page.getByLabel('or by name', {exact: true}).fill(`${ao2}/ao.exr`);
  await page.getByLabel('or by name', {exact: true}).press('Enter');
  await page.waitForFunction(() => document.querySelector('p.error').textContent === '');
  assert.equal(await page.evaluate(() => window.__obscura.viewer.stack.length), 3, 'no twin entry');
  await page.getByLabel('or by name', {exact: true}).fill(`${pt}/radiance.exr`);
  await page.getByLabel('or by name', {exact: true}).press('Enter');
  await page.waitForFunction(() => window.__obscura.viewer.stack.length === 4);
  assert.match(page.url(), new RegExp(`stack=${ao2}%2C${hb}%2C${pt}%2Fradiance.exr&`), 'a named file keeps its name in the URL');
  await page.getByRole('button', {name: `Remove job ${pt} radiance.exr from the stack`}).click();
  await page.waitForFunction(() => window.__obscura.viewer.stack.length === 3);
  // The reference chosen in the stack: hbao; E steps on to the next mode.
  await page.getByLabel(`job ${hb} as the reference (B)`).check();
  await page.locator('canvas.viewer-canvas').focus();
  await page.keyboard.press('e');
  await page.waitForFunction(() => window.__obscura.viewer.show === 'flip' && window.__obscura.viewer.ref === 2);
  // FLIP is the server's (GET /api/v1/diff, the C implementation): the viewer shows its map.
  await page.getByLabel('Ramp maximum', {exact: true}).fill('');
  await page.getByLabel('Ramp maximum', {exact: true}).press('Enter');
  await page.waitForFunction(() => { const e = window.__obscura.viewer.error; return e && e.mode === 'flip' && e.counts && e.hi === 1; });
  const server = await page.evaluate(async ([a, b, pts]) => {
    const {decodeExr} = await import('/js/exr.js');
    const r = await fetch(`/api/v1/diff?a=${a}/ao.exr&b=${b}/ao.exr&channel=ao&hdr=0`);
    const m = (await decodeExr(await r.arrayBuffer())).channels[0].data, w = window.__obscura.viewer.a.img.width;
    return {mean: Number(r.headers.get('X-Obscura-Flip-Mean')), at: pts.map(([x, y]) => [m[y * w + x], window.__obscura.viewer.errorAt(x, y)])};
  }, [ao, hb, pins]);
  for (const [want, got] of server.at) assert.ok(got === null || got === want, `the viewer's FLIP is the server's: ${want} ${got}`);
  assert.ok(server.at.some(([w, g]) => g !== null && w > 0), 'FLIP of hbao against rt_ao is not 0');
  assert.equal(await page.evaluate(() => window.__obscura.viewer.error.mean), server.mean);
  assert.equal(await page.evaluate(() => window.__obscura.viewer.error.lo), 0);
  assert.match(await page.locator('.flip-mean').textContent(), /Mean FLIP over every pixel/);
  await screenshot(page, 'viewer-error-flip');
  await assertAllNamed(page, 'viewer stack');
}

/**
 * A running job opened in the viewer: its preview appears (partly rendered: some pixels still
 * empty) and refreshes; once the job succeeds its final EXR replaces the preview, and every
 * pixel the preview had rendered holds the final value.
 */
async function checkPreview(page, d) {
  const W = 256;
  const id = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 128}},
    set: {'/image/width': W, '/image/height': W}});
  await page.goto(`${d.url}/#/view/${id}`);
  await page.waitForFunction(() => { const v = window.__obscura.viewer; return v && v.ready && v.stack && v.stack[0].live && v.a && v.a.img; },
    null, {timeout: 20000 * SLOW});
  assert.match(await page.locator('.viewer-note').textContent(), /Running: the preview of the tiles rendered so far/);
  const seen = await page.evaluate(() => {
    const im = window.__obscura.viewer.a.img, ch = (n) => im.channels.find((c) => c.name === n).data;
    const ao = ch('ao'), alpha = ch('alpha'), done = [];
    for (let i = 0; i < ao.length; i++) if (ao[i] > 0 || alpha[i] > 0) done.push([i, ao[i]]);
    return {done, n: ao.length, names: im.channels.map((c) => c.name)};
  });
  assert.deepEqual(seen.names, ['alpha', 'ao'], 'the preview holds the primary output and alpha');
  assert.ok(seen.done.length > 0 && seen.done.length < seen.n, `partly rendered: ${seen.done.length} of ${seen.n}`);
  await screenshot(page, 'viewer-preview');
  await page.waitForFunction(() => !window.__obscura.viewer.stack[0].live && window.__obscura.viewer.stack[0].file === 'ao.exr',
    null, {timeout: 60000 * SLOW});
  const final = await page.evaluate((idx) => {
    const ao = window.__obscura.viewer.a.img.channels.find((c) => c.name === 'ao').data;
    return idx.map((i) => ao[i]);
  }, seen.done.map(([i]) => i));
  assert.deepEqual(final, seen.done.map(([, v]) => v), 'the preview\'s pixels are the final ones');
  assert.doesNotMatch(await page.locator('.viewer-note').textContent(), /Running/);
}

async function checkStatistics(page, summary) {
  // Every channel's mean, min, max and count over the covered pixels (alpha > 0; alpha itself over
  // all), computed from the decoded floats, equals the renderer's summary.json.
  const mine = await page.evaluate(() => {
    const im = window.__obscura.viewer.a.img;
    const alpha = im.channels.find((c) => c.name === 'alpha').data;
    const out = {};
    for (const c of im.channels) {
      let sum = 0, n = 0, lo = Infinity, hi = -Infinity;
      c.data.forEach((v, i) => {
        if (c.name !== 'alpha' && !(alpha[i] > 0)) return;
        sum += v;
        n++;
        lo = Math.min(lo, v);
        hi = Math.max(hi, v);
      });
      out[c.name] = {mean: sum / n, min: lo, max: hi, count: n};
    }
    return out;
  });
  let checked = 0;
  for (const o of Object.values(summary.outputs)) {
    for (const [name, st] of Object.entries(o.channels || {})) {
      assert.ok(mine[name], `channel ${name} decoded`);
      assert.equal(mine[name].count, st.count, `${name} count`);
      for (const k of ['mean', 'min', 'max']) {
        assert.ok(Math.abs(mine[name][k] - st[k]) <= 1e-6 * Math.max(1, Math.abs(st[k])), `${name} ${k}: ${mine[name][k]} vs ${st[k]}`);
      }
      checked++;
    }
  }
  return checked;
}

async function checkZoomPan(page) {
  const canvas = page.locator('canvas.viewer-canvas');
  const s0 = await viewer(page);
  assert.ok(s0.fitted && s0.zoom > 1, `fitted at first: ${JSON.stringify(s0)}`);
  await page.getByRole('button', {name: 'Zoom in'}).click();
  assert.equal((await viewer(page)).zoom, s0.zoom * 2, 'the + button doubles the zoom');
  await canvas.focus();
  await page.keyboard.press('-');
  assert.equal((await viewer(page)).zoom, s0.zoom, '- halves it');
  await page.keyboard.press('a');
  assert.equal((await viewer(page)).zoom, 1, 'A is actual size');
  await page.keyboard.press('f');
  const fit = await viewer(page);
  assert.deepEqual([fit.zoom, fit.panX, fit.panY, fit.fitted], [s0.zoom, s0.panX, s0.panY, true], 'F fits again');
  // The wheel zooms about the pointer: the image point under it stays put.
  const box = await canvas.boundingBox();
  const [mx, my] = [Math.round(box.x + box.width * 0.3), Math.round(box.y + box.height * 0.4)];
  const under = () => page.evaluate(([x, y]) => {
    const s = window.__obscura.viewer.view;
    return [(x - s.panX) / s.zoom, (y - s.panY) / s.zoom];
  }, [mx - box.x - 1, my - box.y - 1]);
  await page.mouse.move(mx, my);
  const before = await under();
  await page.mouse.wheel(0, -100);
  await page.waitForFunction((z) => window.__obscura.viewer.view.zoom > z, s0.zoom);
  assert.ok(Math.abs((await viewer(page)).zoom - s0.zoom * 1.25) < 1e-9, 'a wheel step zooms by 1.25');
  const after = await under();
  assert.ok(Math.hypot(after[0] - before[0], after[1] - before[1]) < 1e-6, `the point under the pointer stays: ${before} ${after}`);
  // Dragging pans by the distance dragged; an arrow key by 40 px.
  const p0 = await viewer(page);
  await page.mouse.move(box.x + 200, box.y + 200);
  await page.mouse.down();
  await page.mouse.move(box.x + 230, box.y + 180, {steps: 4});
  await page.mouse.move(box.x + 250, box.y + 170, {steps: 4});
  await page.mouse.up();
  const p1 = await viewer(page);
  assert.deepEqual([p1.panX - p0.panX, p1.panY - p0.panY, p1.zoom], [50, -30, p0.zoom], 'drag pans');
  await canvas.focus();
  await page.keyboard.press('ArrowLeft');
  await page.keyboard.press('ArrowUp');
  const p2 = await viewer(page);
  assert.deepEqual([p2.panX - p1.panX, p2.panY - p1.panY], [40, 40], 'arrow keys pan');
  await page.keyboard.press('f');
}

test('image viewer: zoom, pan, readout, exposure, A/B, keyboard, 800 px', async () => {
  const d = await startDashboard({workers: 8});
  const {browser, page, errors} = await openBrowser();
  try {
    const size = {'/image/width': 32, '/image/height': 24};
    const pt = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'path_trace', backend: 'cpu', params: {samples: 8}}, set: size});
    const ao = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 8}}, set: size});
    const hb = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'hbao', backend: 'cpu'}, set: size});
    const ao2 = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 2}}, set: size});
    const other = await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'ssao', backend: 'cpu'}, set: {'/image/width': 16, '/image/height': 12}});
    const cmp = await request(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'sphere_on_plane.json', set: {'/image/width': 16, '/image/height': 12},
      repeats: 1, reference: {samples: 16}, candidates: [{technique: 'hbao', backend: 'cpu'}]}});
    assert.equal(cmp.status, 201, cmp.text);
    await waitAll(d, [pt, ao, hb, other, ao2]);

    // ---- opened from the job page by clicking its AO image -------------------------------------
    await page.goto(`${d.url}/#/jobs/${ao}`);
    await page.locator('img.output[data-name="ao.png"]').click();
    await page.waitForURL(new RegExp(`#/view/${ao}\\?`));
    await waitViewer(page);
    let s = await viewer(page);
    assert.equal(s.output, 'ao', 'the clicked PNG\'s output is shown');
    assert.match(page.url(), /output=ao&view=grey/, 'the route keeps what is shown');
    const aoSummary = await getJSON(d, `/api/v1/jobs/${ao}/outputs/summary.json`);
    assert.ok(await checkStatistics(page, aoSummary) >= 10, 'every channel of rt_ao checked');
    await checkZoomPan(page);

    // ---- a pinned pixel: readout, PNG grey level, canvas ---------------------------------------
    const [px, py] = [20, 10];
    let at = await spot(page, px, py);
    await page.mouse.click(at.px, at.py);
    s = await viewer(page);
    assert.deepEqual([s.readout.x, s.readout.y, s.readout.pinned], [px, py, true], 'click pins the pixel');
    assert.match(await page.locator('.readout-where').textContent(), new RegExp(`x ${px}, y ${py}`));
    const v = await decoded(page, 'a', 'ao', px, py);
    assert.ok(v >= 0 && v <= 1, `AO in range: ${v}`);
    assert.ok(Math.abs(Number(await readoutCell(page, 'ao', 'a')) - v) <= 1e-6, 'the readout shows the decoded value');
    const grey = quantize(v, false);
    assert.deepEqual(await pngRGB(page, `/api/v1/jobs/${ao}/outputs/ao.png`, px, py), [grey, grey, grey], 'ao.png holds the value, linear');
    assert.deepEqual(await canvasRGB(page, at.cx, at.cy), [grey, grey, grey], 'the canvas shows it as ao.png does');
    // Hovering elsewhere keeps the pin; Shift+arrow moves it by a pixel.
    await page.mouse.move(at.px - 3 * s.zoom, at.py);
    assert.equal((await viewer(page)).readout.x, px, 'the pin holds while hovering');
    await page.locator('canvas.viewer-canvas').focus();
    await page.keyboard.press('Shift+ArrowRight');
    assert.equal((await viewer(page)).readout.x, px + 1, 'Shift+ArrowRight moves the pin');
    await page.keyboard.press('Shift+ArrowLeft');
    await assertAllNamed(page, 'viewer');
    await screenshot(page, 'viewer-ao');

    // ---- A/B against hbao: toggle, difference, split wipe --------------------------------------
    const cands = await page.evaluate(() => window.__obscura.viewer.candidates);
    assert.ok(cands.includes(hb) && cands.includes(pt) && !cands.includes(other) && !cands.includes(ao),
      `same-size finished jobs only: ${cands}`);
    await page.getByLabel('Compare with').selectOption(String(hb));
    await waitViewer(page, {b: hb});
    const vb = await decoded(page, 'b', 'ao', px, py);
    assert.ok(Math.abs(Number(await readoutCell(page, 'ao', 'b')) - vb) <= 1e-6, 'B\'s value');
    assert.ok(Math.abs(Number(await readoutCell(page, 'ao', 'diff')) - (v - vb)) <= 1e-6, 'A − B');
    assert.equal(await readoutCell(page, 'ao_raw', 'a'), '–', 'a channel only B has');
    assert.notEqual(await readoutCell(page, 'ao_raw', 'b'), '–');
    const greyB = quantize(vb, false);
    assert.deepEqual(await pngRGB(page, `/api/v1/jobs/${hb}/outputs/ao.png`, px, py), [greyB, greyB, greyB]);
    await page.locator('canvas.viewer-canvas').focus();
    await page.keyboard.press('b');
    assert.equal((await viewer(page)).showing, 'B', 'B flips to B');
    assert.deepEqual(await canvasRGB(page, at.cx, at.cy), [greyB, greyB, greyB], 'the canvas shows B');
    await page.getByRole('button', {name: 'A/B'}).click();
    assert.equal((await viewer(page)).showing, 'A', 'the button flips back');
    assert.deepEqual(await canvasRGB(page, at.cx, at.cy), [grey, grey, grey]);
    // Split: A left of the divider, B right of it; dragging the divider moves it.
    await page.getByLabel('Mode').selectOption('split');
    assert.match(page.url(), new RegExp(`stack=${hb}&ref=2.*mode=split`), 'the route keeps B and the mode');
    s = await viewer(page);
    const box = await page.locator('canvas.viewer-canvas').boundingBox();
    const width = Math.round(box.width - 2);
    const divider = s.split * width;
    const left = await spot(page, 3, 12), right = await spot(page, 28, 12);
    assert.ok(left.cx < divider && right.cx > divider);
    const l = quantize(await decoded(page, 'a', 'ao', 3, 12), false), r = quantize(await decoded(page, 'b', 'ao', 28, 12), false);
    assert.deepEqual(await canvasRGB(page, left.cx, left.cy), [l, l, l], 'A left of the divider');
    assert.deepEqual(await canvasRGB(page, right.cx, right.cy), [r, r, r], 'B right of it');
    await page.mouse.move(box.x + 1 + divider, box.y + 100);
    await page.mouse.down();
    await page.mouse.move(box.x + 1 + divider - 100, box.y + 100, {steps: 5});
    await page.mouse.up();
    s = await viewer(page);
    assert.ok(Math.abs(s.split * width - (divider - 100)) < 1.5, `the divider follows the drag: ${s.split * width}`);
    assert.equal(Number(await page.getByLabel('Split position (%)').inputValue()), Math.round(s.split * 100));
    await screenshot(page, 'viewer-split');
    await page.locator('canvas.viewer-canvas').focus();
    await page.keyboard.press('s');
    assert.equal((await viewer(page)).mode, 'toggle', 'S leaves the split');
    assert.match(page.url(), /mode=toggle/);

    // ---- a stack: keys, error maps, histograms, the URL ----------------------------------------
    await checkStack(page, d, {ao, ao2, hb, pt});

    // ---- exposure on path_trace's radiance ----------------------------------------------------
    await page.goto(`${d.url}/#/view/${pt}`);
    await waitViewer(page, {output: 'radiance'});
    const summary = await getJSON(d, `/api/v1/jobs/${pt}/outputs/summary.json`);
    await checkStatistics(page, summary);
    assert.equal((await viewer(page)).stops, 0, 'the exposure starts at the PNG\'s');
    // A dark covered pixel: its brightest channel's sRGB byte at least 50 (quantisation under 3 %)
    // and twice its value still below 1.
    const dark = await page.evaluate(() => {
      const im = window.__obscura.viewer.a.img;
      const ch = (n) => im.channels.find((c) => c.name === n).data;
      const [R, G, B, A] = [ch('radiance.R'), ch('radiance.G'), ch('radiance.B'), ch('alpha')];
      let best = null;
      for (let i = 0; i < R.length; i++) {
        const m = Math.max(R[i], G[i], B[i]);
        if (A[i] > 0 && m > 0.035 && m < 0.45 && (!best || m < best.m)) best = {i, m, rgb: [R[i], G[i], B[i]]};
      }
      return best && {x: best.i % im.width, y: Math.floor(best.i / im.width), rgb: best.rgb, m: best.m};
    });
    assert.ok(dark, 'a dark pixel exists');
    at = await spot(page, dark.x, dark.y);
    const c0 = await canvasRGB(page, at.cx, at.cy);
    assert.deepEqual(c0, dark.rgb.map((x) => quantize(x, true)), 'exposure 0: the tone map of the value');
    assert.deepEqual(c0, await pngRGB(page, `/api/v1/jobs/${pt}/outputs/final.png`, dark.x, dark.y), 'exposure 0 shows final.png');
    // A range input takes keys, not typing: three steps of a quarter stop up from 0.25.
    const exposure = page.getByLabel('Exposure (stops)');
    await exposure.evaluate((e) => { e.value = '0.25'; e.dispatchEvent(new Event('input', {bubbles: true})); });
    await exposure.focus();
    for (let i = 0; i < 3; i++) await page.keyboard.press('ArrowRight');
    await page.waitForFunction(() => window.__obscura.viewer.stops === 1);
    const c1 = await canvasRGB(page, at.cx, at.cy);
    assert.deepEqual(c1, dark.rgb.map((x) => quantize(2 * x, true)), 'exposure +1: the tone map of twice the value');
    const k = dark.rgb.indexOf(dark.m);
    const ratio = linear(c1[k]) / linear(c0[k]);
    assert.ok(Math.abs(ratio - 2) < 0.12, `+1 stop doubles the linear value: ${linear(c0[k])} -> ${linear(c1[k])}`);
    assert.match(page.url(), /exposure=1/);
    await screenshot(page, 'viewer-exposure');

    // ---- 800 px wide: nothing overflows, the readout goes under the canvas ----------------------
    await page.setViewportSize({width: 800, height: 700});
    await page.waitForFunction(() => document.querySelector('canvas.viewer-canvas').width <= 800);
    const layout = await page.evaluate(() => {
      const c = document.querySelector('canvas.viewer-canvas').getBoundingClientRect();
      const r = document.querySelector('.readout-panel').getBoundingClientRect();
      return {scroll: document.documentElement.scrollWidth, left: c.left, right: c.right, width: c.width, readoutTop: r.top, canvasBottom: c.bottom};
    });
    assert.ok(layout.scroll <= 800, `no horizontal scrolling at 800 px: ${JSON.stringify(layout)}`);
    assert.ok(layout.left >= 0 && layout.right <= 800 && layout.width > 600, `the canvas fits: ${JSON.stringify(layout)}`);
    assert.ok(layout.readoutTop >= layout.canvasBottom, 'the readout is below the canvas');
    assert.ok((await viewer(page)).fitted, 'still fitted after the resize');
    await screenshot(page, 'viewer-800');
    await page.setViewportSize({width: 1280, height: 900});

    // P pins the pixel at the canvas's centre (the readout without a pointer), P again unpins.
    await page.locator('canvas.viewer-canvas').focus();
    await page.keyboard.press('p');
    s = await viewer(page);
    const centre = await page.evaluate(() => {
      const c = document.querySelector('canvas.viewer-canvas'), v = window.__obscura.viewer.view;
      return [Math.floor((c.width / 2 - v.panX) / v.zoom), Math.floor((c.height / 2 - v.panY) / v.zoom)];
    });
    assert.deepEqual([s.readout.x, s.readout.y, s.readout.pinned], [...centre, true], 'P pins the centre pixel');
    assert.ok(Math.abs(Number(await readoutCell(page, 'radiance.G', 'a')) - await decoded(page, 'a', 'radiance.G', ...centre)) <= 1e-6);
    await page.keyboard.press('p');
    const after = (await viewer(page)).readout;
    assert.ok(after === null || after.pinned === false, 'P again unpins');

    // Escape closes the viewer: back to the job.
    await page.locator('canvas.viewer-canvas').focus();
    await page.keyboard.press('Escape');
    await page.waitForURL(new RegExp(`#/jobs/${pt}$`));

    // ---- a running job's preview -----------------------------------------------------------
    await checkPreview(page, d);

    // ---- from a comparison: candidate (A) against its reference (B), split --------------------
    const deadline = Date.now() + 120000 * SLOW;
    let doc;
    for (;;) {
      doc = await getJSON(d, `/api/v1/comparisons/${cmp.json.id}`);
      if (doc.state !== 'running') break;
      assert.ok(Date.now() < deadline, 'the comparison finishes');
      await new Promise((res) => setTimeout(res, 100));
    }
    assert.equal(doc.state, 'succeeded');
    const cand = doc.candidates[0];
    await page.goto(`${d.url}/#/comparisons/${doc.id}?candidate=${cand.index}`);
    await page.getByRole('link', {name: 'View candidate (A) against reference (B)'}).click();
    await waitViewer(page, {b: cand.reference_job_id});
    s = await viewer(page);
    assert.deepEqual([page.url().match(/#\/view\/(\d+)/)[1], s.mode], [String(cand.job_id), 'split']);
    await page.getByRole('link', {name: '✕ Close'}).click();
    await page.waitForURL(new RegExp(`#/comparisons/${doc.id}\\?candidate=${cand.index}$`));
    assert.deepEqual(errors, [], 'no script errors');
  } finally {
    await browser.close();
    await d.stopClean();
  }
});

test('image viewer with a token: the EXR loads with the bearer header', async () => {
  const TOKEN = 'viewer-token-0123456789abcdef';
  const d = await startDashboard({token: TOKEN});
  const {browser, page, errors} = await openBrowser();
  try {
    const id = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}},
      set: {'/image/width': 16, '/image/height': 12}});
    await waitAll(d, [id]);
    await page.goto(`${d.url}/#/jobs`);
    await page.evaluate((t) => localStorage.setItem('obscura-token', t), TOKEN);
    await page.goto(`${d.url}/#/view/${id}`);
    await page.reload();
    await waitViewer(page, {output: 'ao'});
    const s = await viewer(page);
    assert.deepEqual([s.w, s.h], [16, 12], 'the EXR was read');
    assert.deepEqual(errors, []);
  } finally {
    await browser.close();
    await d.stopClean();
  }
});
