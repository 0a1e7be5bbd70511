// Mesh import is contained: a scenes directory holding a PLY that makes assimp abort (a face with
// no indices trips its triangulation assertion), one that makes it loop forever (a header without
// end_header) and one that makes it crash on a bad read (binary header ending in "\r") next to a
// good mesh. Jobs naming the bad files get 422 naming /objects/N/shape/file with "crashed" or
// "timed out", the daemon stays up, the good one renders, and a bad file named again is answered
// from the cache: the metrics show no further worker started.
//
//   node tests/server/test_mesh_import.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {ROOT, SLOW, getJSON, request, submit, waitJob, withDaemon} from './lib.mjs';

const DATA = path.join(ROOT, 'tests', 'data');
// Short, so the hang costs little; generous against a loaded machine for the good imports.
const IMPORT_SECONDS = 3 * SLOW;

function scenesDir() {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-meshes-'));
  fs.mkdirSync(path.join(dir, 'models'));
  for (const f of ['crash_triangulate.ply', 'hang_no_end_header.ply', 'crash_binary_header.ply'])
    fs.copyFileSync(path.join(DATA, 'mesh', f), path.join(dir, 'models', f));
  fs.copyFileSync(path.join(DATA, 'tetra.obj'), path.join(dir, 'models', 'tetra.obj'));
  return dir;
}

function doc(file) {
  return {
    camera: {type: 'perspective', position: [2, 2, 3], look_at: [0.3, 0.3, 0.3], up: [0, 1, 0], fov_y: 40},
    image: {width: 16, height: 16, spp: 1},
    objects: [
      {name: 'ground', shape: {type: 'quad', vertices: [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]}},
      {name: 'mesh', shape: {type: 'mesh', file}},
    ],
    technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}},
  };
}

async function metric(d, name) {
  const r = await request(d, 'GET', '/metrics');
  assert.equal(r.status, 200);
  const m = r.text.match(new RegExp(`^${name} (\\d+)$`, 'm'));
  assert.ok(m, `no ${name} in /metrics:\n${r.text}`);
  return Number(m[1]);
}

async function refused(d, file, what) {
  const t0 = Date.now();
  const r = await request(d, 'POST', '/api/v1/jobs', {body: doc(file)});
  assert.equal(r.status, 422, `${file}: ${r.status} ${r.text}`);
  const line = r.json.problems.find((p) => p.includes('/objects/1/shape/file'));
  assert.ok(line, `${file}: no problem names /objects/1/shape/file: ${r.text}`);
  assert.match(line, what, `${file}: ${line}`);
  assert.ok(line.includes(file), `${file}: the problem does not name the file: ${line}`);
  return Date.now() - t0;
}

test('crashing and hanging meshes cost a worker each, not the daemon', async () => {
  const dir = scenesDir();
  try {
    await withDaemon({scenesDir: dir, args: ['--mesh-import-seconds', String(IMPORT_SECONDS)]}, async (d) => {
      await refused(d, 'models/crash_triangulate.ply', /crashed \(signal 6\)/);
      assert.equal(await metric(d, 'obscura_mesh_importer_spawns_total'), 1);
      await refused(d, 'models/crash_binary_header.ply', /crashed \(signal \d+\)/);
      assert.equal(await metric(d, 'obscura_mesh_importer_spawns_total'), 2);
      const ms = await refused(d, 'models/hang_no_end_header.ply', new RegExp(`timed out after ${IMPORT_SECONDS} s`));
      assert.ok(ms >= IMPORT_SECONDS * 1000 - 100, `the hang was answered after only ${ms} ms`);
      assert.equal(await metric(d, 'obscura_mesh_importer_spawns_total'), 3);
      assert.equal((await getJSON(d, '/api/v1/health')).status, 'ok');

      // Named again: answered from the cache (no worker started, no time limit waited out).
      await refused(d, 'models/crash_triangulate.ply', /crashed \(signal 6\)/);
      const again = await refused(d, 'models/hang_no_end_header.ply', /timed out/);
      assert.ok(again < IMPORT_SECONDS * 1000, `the cached hang took ${again} ms`);
      assert.equal(await metric(d, 'obscura_mesh_importer_spawns_total'), 3);
      assert.equal(await metric(d, 'obscura_mesh_imports_total'), 3);

      // The good mesh: validated by a fresh worker and rendered from the cache.
      const id = await submit(d, doc('models/tetra.obj'));
      const j = await waitJob(d, id);
      assert.equal(j.state, 'succeeded', JSON.stringify(j));
      assert.equal(await metric(d, 'obscura_mesh_importer_spawns_total'), 4);
      assert.equal(await metric(d, 'obscura_mesh_imports_total'), 4);
      assert.ok(await metric(d, 'obscura_mesh_cache_hits_total') >= 3);
      assert.match(d.log(), /mesh importer: models\/crash_triangulate\.ply: .*crashed \(signal 6\)/);

      // A changed file is a different file: imported again, now fine.
      fs.copyFileSync(path.join(DATA, 'tetra.obj'), path.join(dir, 'models', 'fixed.obj'));
      fs.renameSync(path.join(dir, 'models', 'fixed.obj'), path.join(dir, 'models', 'crash_triangulate.ply'));
      const r = await request(d, 'POST', '/api/v1/jobs', {body: doc('models/crash_triangulate.ply')});
      // An OBJ behind a .ply name: assimp reads it by content or refuses it; either way no crash.
      assert.ok(r.status === 201 || (r.status === 422 && !/crashed/.test(r.text)), `${r.status} ${r.text}`);
      assert.equal(await metric(d, 'obscura_mesh_imports_total'), 5);
    });
  } finally {
    fs.rmSync(dir, {recursive: true, force: true});
  }
});
