// Every bundled scene (scaled down) through the daemon, both submission forms, the CPU techniques:
// the job completes, its outputs decode, and its EXR and primary PNG are byte for byte what `obscura
// render` writes for the same document. Also the output serving rules (ETag, ranges, HEAD) and the
// read-only listings (scenes, techniques, health, metrics).
//
//   node tests/server/test_scenes.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {spawnSync} from 'node:child_process';
import {test} from 'node:test';

import {OBSCURA, SCENES_DIR, cliRender, download, exrHeader, getJSON, getJob, pngSize, request,
        sha256, submit, validate, waitAll, withDaemon} from './lib.mjs';

const W = 24, H = 24;
// Small enough for the sanitizer build; scenes that need more than the image size scaled get it here.
const SMALL = {'/image/width': W, '/image/height': H};
const EXTRA = {displaced_sphere: {'/objects/0/shape/subdivisions': 6}};
// The cheap setting of each scene's technique: samples, or what it has instead.
const CHEAP = {hangar: {'/technique/params/steps': 8},
               ibl_sky: {'/technique/params/shadow_maps': 8, '/technique/params/map_size': 64},
               volume_torus_mesh: {'/technique/params/grid': 32}};
const sceneFiles = fs.readdirSync(SCENES_DIR).filter((f) => f.endsWith('.json')).sort();

// One case: the job body and the CLI invocation that must give the same images.
function cases() {
  const out = [];
  for (const f of sceneFiles) {
    const base = f.replace(/\.json$/, '');
    const sets = {...SMALL, ...(CHEAP[base] || {'/technique/params/samples': 8}), ...(EXTRA[base] || {})};
    out.push({name: `${base} (scene_file)`, body: {scene_file: f, set: sets, label: `bundled ${base}`},
              cli: {file: f, sets}});
  }
  // The wrapper's technique replaces the file's, like --technique/--backend (params dropped).
  for (const t of ['ssao', 'hbao']) {
    out.push({name: `cornell_box ${t} cpu`, body: {scene_file: 'cornell_box.json', technique: {name: t, backend: 'cpu'}, set: SMALL},
              cli: {file: 'cornell_box.json', sets: SMALL, technique: t, backend: 'cpu'}});
  }
  // Inline documents, the overrides applied here; meshes resolve inside --scenes-dir.
  for (const [f, extra] of [['sphere_on_plane.json', {priority: 80}], ['teapot.json', {label: 'inline teapot'}]]) {
    const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, f), 'utf8'));
    doc.image.width = W;
    doc.image.height = H;
    doc.technique.params.samples = 4;
    doc.technique.params.seed = 7;
    out.push({name: `${f} inline`, body: {...doc, ...extra},
              cli: {file: f, sets: {...SMALL, '/technique/params/samples': 4, '/technique/params/seed': 7}}});
  }
  // `set` on an inline document, applied before validation.
  const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, 'cornell_box.json'), 'utf8'));
  out.push({name: 'cornell_box inline with set', body: {...doc, set: {...SMALL, '/technique/params/falloff': 'sqrt'}},
            cli: {file: 'cornell_box.json', sets: {...SMALL, '/technique/params/falloff': 'sqrt'}}});
  return out;
}

test('bundled scenes match the CLI bit for bit', async () => {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-cli-'));
  await withDaemon({}, async (d) => {
    const cs = cases();
    for (const c of cs) c.id = await submit(d, c.body);
    // The CLI renders meanwhile.
    for (const [i, c] of cs.entries()) {
      c.dir = cliRender(path.join(SCENES_DIR, c.cli.file), path.join(tmp, String(i)), c.cli);
    }
    const jobs = await waitAll(d, cs.map((c) => c.id));
    const registry = (await getJSON(d, '/api/v1/techniques')).techniques;
    for (const [i, c] of cs.entries()) {
      const j = jobs[i];
      assert.equal(j.state, 'succeeded', `${c.name}: ${j.state}: ${j.error}`);
      assert.equal(j.progress, 1);
      assert.equal(j.attempts, 1);
      assert.equal(j.error, null);
      assert.equal(j.backend.actual, 'cpu');
      assert.deepEqual({w: j.image.width, h: j.image.height}, {w: W, h: H}, c.name);
      assert.equal(j.scene, c.body.scene_file || 'inline');
      assert.equal(j.label, c.body.label ?? null);
      assert.equal(j.priority, c.body.priority ?? 50);
      for (const t of ['created_at', 'started_at', 'finished_at']) assert.ok(Date.parse(j[t]) > 0, `${c.name}: ${t}`);
      assert.ok(Date.parse(j.created_at) <= Date.parse(j.started_at) && Date.parse(j.started_at) <= Date.parse(j.finished_at));
      // Every output the CLI wrote (bent normals only where the technique has them), no other.
      const names = fs.readdirSync(c.dir).sort();
      // The files the technique declares: its EXR, each PNG, summary.json.
      const reg = registry.find((t) => t.name === j.technique);
      const primary = reg.typed_outputs.find((o) => o.primary);
      const exrName = reg.exr, pngName = primary.png;
      const want = [exrName, ...reg.typed_outputs.filter((o) => o.png).map((o) => o.png), 'summary.json'].sort();
      assert.deepEqual(names, want, `${c.name}: CLI outputs`);
      assert.deepEqual(j.outputs.map((o) => o.name).sort(), want, c.name);
      assert.deepEqual(Object.keys(j.links.outputs).sort(), want);
      for (const n of want.filter((x) => x !== 'summary.json' && x !== exrName && x !== pngName)) {
        const b = (await download(d, j, n)).body;
        assert.deepEqual(pngSize(b), {width: W, height: H}, `${c.name}: ${n} size`);
        assert.ok(b.equals(fs.readFileSync(path.join(c.dir, n))), `${c.name}: ${n} differs from the CLI's`);
      }

      const exr = (await download(d, j, exrName)).body;
      const png = (await download(d, j, pngName)).body;
      const summary = JSON.parse((await download(d, j, 'summary.json')).text);
      assert.deepEqual(pngSize(png), {width: W, height: H}, `${c.name}: PNG size`);
      const hdr = exrHeader(exr);
      assert.deepEqual({w: hdr.width, h: hdr.height}, {w: W, h: H}, `${c.name}: EXR data window`);
      assert.ok(hdr.channels.includes(primary.channels[0]), `${c.name}: EXR channels ${hdr.channels}`);
      // Bit for bit with the CLI.
      const cliExr = fs.readFileSync(path.join(c.dir, exrName));
      const cliPng = fs.readFileSync(path.join(c.dir, pngName));
      assert.ok(exr.equals(cliExr), `${c.name}: ${exrName} differs from the CLI's (${sha256(exr)} vs ${sha256(cliExr)})`);
      assert.ok(png.equals(cliPng), `${c.name}: ${pngName} differs from the CLI's`);
      // The summary agrees with the CLI's except for timings, and the job shows the same figures.
      const cliSum = JSON.parse(fs.readFileSync(path.join(c.dir, 'summary.json'), 'utf8'));
      // (timings and what derives from them, and the thread count, may differ)
      const strip = (s) => {
        const {timings_ms: _t, rays_per_second: _r, threads: _n, scene: _s, frames, built, ...rest} = s;
        // Embree's memory depends on how its build threads took their allocation blocks, and a
        // built thing's own time (an isosurface's extract_ms) differs like the others; the rest
        // of what was built agrees.
        if (built) {
          rest.built = built.map((b) => Object.fromEntries(
              Object.entries(b.name === 'bvh' ? {...b, bytes: 0, peak_bytes: 0} : b)
                  .filter(([k]) => !k.endsWith('_ms'))));
        }
        // A moving scene's per-frame timings differ like the others; the rest of each frame agrees.
        if (frames) {
          rest.frames = frames.map((f) => Object.fromEntries(
              Object.entries(f).filter(([k]) => !k.endsWith('_ms') && k !== 'speedup')));
        }
        return rest;
      };
      assert.deepEqual(strip(summary), strip(cliSum), `${c.name}: summary.json`);
      assert.equal(summary.scene, c.body.scene_file || 'inline');
      assert.equal(j.technique, cliSum.technique);
      assert.equal(j.rays, summary.rays);
      // What was built, with its memory: the job shows summary.json's (proximity fields here).
      assert.deepEqual(j.built, summary.built ?? null, `${c.name}: built`);
      if (j.technique === 'proximity_ao') {
        const fields = j.built.filter((b) => b.name === 'proximity_field');
        assert.ok(fields.length > 0, `${c.name}: built`);
        for (const b of fields) assert.equal(b.bytes, 5 * b.dims[0] * b.dims[1] * b.dims[2]);
      }
      assert.equal(j.stats.nan_count, 0);
      // The job's statistics are summary.json's: ao for the AO techniques, and every technique's
      // declared outputs (radiance, depth, ...).
      if (summary.ao) assert.equal(j.stats.ao.mean, summary.ao.mean);
      assert.equal(j.stats.primary_output, summary.primary_output);
      assert.deepEqual(j.stats.outputs, summary.outputs, `${c.name}: stats.outputs`);
      for (const k of ['load', 'build', 'render', 'write', 'total']) {
        assert.equal(typeof j.timings_ms[k], 'number', `${c.name}: timings_ms.${k}`);
      }
    }

    // Output serving rules, on one PNG.
    const j = jobs[0];
    const o = j.outputs.find((x) => x.name === 'ao.png');
    const full = (await download(d, j, 'ao.png'));
    assert.equal(full.headers.etag, `"${o.sha256}"`);
    assert.match(full.headers['cache-control'], /immutable/);
    assert.equal(full.headers['accept-ranges'], 'bytes');
    assert.equal(full.headers['x-content-type-options'], 'nosniff');
    let r = await request(d, 'GET', o.url, {headers: {range: 'bytes=0-7'}});
    assert.equal(r.status, 206);
    assert.equal(r.headers['content-range'], `bytes 0-7/${o.size}`);
    assert.ok(r.body.equals(full.body.subarray(0, 8)));
    r = await request(d, 'GET', o.url, {headers: {range: 'bytes=-5'}});
    assert.equal(r.status, 206);
    assert.ok(r.body.equals(full.body.subarray(o.size - 5)));
    r = await request(d, 'GET', o.url, {headers: {range: `bytes=10-`}});
    assert.equal(r.status, 206);
    assert.ok(r.body.equals(full.body.subarray(10)));
    r = await request(d, 'GET', o.url, {headers: {range: 'bytes=0-1,4-5'}});
    assert.equal(r.status, 200, 'multi-range answered with the whole file');
    assert.ok(r.body.equals(full.body));
    r = await request(d, 'GET', o.url, {headers: {'if-none-match': `"${o.sha256}"`}});
    assert.equal(r.status, 304);
    assert.equal(r.body.length, 0);
    r = await request(d, 'GET', o.url, {headers: {range: 'bytes=0-7', 'if-range': '"other"'}});
    assert.equal(r.status, 200, 'If-Range with another ETag ignores Range');
    r = await request(d, 'HEAD', o.url);
    assert.equal(r.status, 200);
    assert.equal(Number(r.headers['content-length']), o.size);
    assert.equal(r.body.length, 0);

    // Listings.
    const scenes = await getJSON(d, '/api/v1/scenes');
    assert.deepEqual(scenes.scenes.map((s) => s.name), sceneFiles);
    for (const s of scenes.scenes) {
      assert.equal(s.size, fs.statSync(path.join(SCENES_DIR, s.name)).size);
      const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, s.name), 'utf8'));
      assert.equal(s.technique, doc.technique.name);
    }
    const tech = await getJSON(d, '/api/v1/techniques');
    const cliTech = JSON.parse(spawnSync(OBSCURA, ['techniques'], {encoding: 'utf8'}).stdout);
    assert.deepEqual(tech.techniques.map((t) => t.name), cliTech.map((t) => t.name));
    // Every backend's guaranteed range, as the CLI prints it and the OpenAPI document describes it.
    assert.deepEqual(tech.techniques.map((t) => t.ranges), cliTech.map((t) => t.ranges));
    for (const t of tech.techniques) {
      assert.deepEqual(Object.keys(t.ranges).sort(), [...t.backends].sort());
      for (const r of Object.values(t.ranges)) validate('GuaranteedRange', r);
    }
    const health = await getJSON(d, '/api/v1/health');
    validate('Health', health);
    assert.equal(health.status, 'ok');
    assert.equal(health.queue_depth, 0);
    const m = await request(d, 'GET', '/metrics');
    assert.equal(m.status, 200);
    assert.match(m.headers['content-type'], /^text\/plain/);
    assert.match(m.text, new RegExp(`obscura_jobs\\{state="succeeded"\\} ${cs.length}\\b`));
    assert.match(m.text, /obscura_queue_depth 0\b/);
    assert.match(m.text, /obscura_render_seconds_count\{[^}]*technique="rt_ao"[^}]*\} \d+/);
    assert.match(m.text, /obscura_http_requests_total\{[^}]*route="\/api\/v1\/jobs\/\{id\}"[^}]*status="200"[^}]*\} \d+/);
    assert.equal((await getJob(d, j.id)).state, 'succeeded');
  });
  fs.rmSync(tmp, {recursive: true, force: true});
});
