// The API contract against the daemon: a typical client run (health, techniques, scenes, a scene
// file job and an inline one followed to their end, the job list and its cursor, outputs, a small
// comparison, the comparison list and CSV, cancel, delete, refused requests), every answer checked
// against the operation of schema/openapi.yaml it belongs to: the status must be documented, the
// content type listed, and a JSON body must match that response's schema (ajv, JSON Schema 2020-12).
import assert from 'node:assert/strict';
import fs from 'node:fs';
import {createRequire} from 'node:module';
import path from 'node:path';
import {test} from 'node:test';

import {ROOT, SCENES_DIR, SLOW, TERMINAL, request, sleep, withDaemon} from './lib.mjs';

const require = createRequire(import.meta.url);
const YAML = require('yaml');
const Ajv2020 = require('ajv/dist/2020').default;

const spec = YAML.parse(fs.readFileSync(path.join(ROOT, 'schema', 'openapi.yaml'), 'utf8'));
const ajv = new Ajv2020({strict: false, allErrors: true, validateFormats: false});
ajv.addSchema({$id: 'openapi', paths: spec.paths, components: spec.components});

const escape = (s) => s.replace(/~/g, '~0').replace(/\//g, '~1');
// Path templates, most literal first, so /api/v1/jobs/{id}/cancel wins over /{path}.
const templates = Object.keys(spec.paths)
  .map((t) => ({t, re: new RegExp(`^${t.replace(/[.]/g, '\\.').replace(/\{[^}]+\}/g, '[^/]+')}$`)}))
  .sort((a, b) => (a.t.match(/\{/g) || []).length - (b.t.match(/\{/g) || []).length ||
                  b.t.length - a.t.length);

function deref(obj) {
  while (obj && obj.$ref) {
    obj = obj.$ref.slice(2).split('/').reduce((o, k) => o[k.replace(/~1/g, '/').replace(/~0/g, '~')], spec);
  }
  return obj;
}

const covered = new Set();

/** The request, with its answer checked against the spec; returns lib's response object. */
async function call(d, method, url, opts = {}) {
  const r = await request(d, method, url, opts);
  const p = url.split('?')[0];
  const tpl = templates.find(({re}) => re.test(p));
  assert.ok(tpl, `${method} ${p}: no path of openapi.yaml matches`);
  const op = spec.paths[tpl.t][method.toLowerCase()];
  assert.ok(op, `${method} ${tpl.t}: not in openapi.yaml`);
  const resp = deref(op.responses[String(r.status)]);
  assert.ok(resp, `${method} ${url} answered ${r.status}, which openapi.yaml does not list: ${r.text.slice(0, 300)}`);
  covered.add(`${method} ${tpl.t} ${r.status}`);
  const type = (r.headers['content-type'] || '').split(';')[0].trim();
  if (!resp.content) {
    assert.equal(r.body.length, 0, `${method} ${url} ${r.status}: a body where openapi.yaml lists none`);
    return r;
  }
  const media = Object.keys(resp.content).find((m) => m.split(';')[0].trim() === type);
  assert.ok(media, `${method} ${url} ${r.status}: content type "${type}" is not one of ${Object.keys(resp.content)}`);
  if (type === 'application/json' && r.status !== 206) {
    assert.notEqual(r.json, undefined, `${method} ${url} ${r.status}: not JSON`);
    const schema = resp.content[media].schema;
    if (schema) {
      // Through the spec's own pointer, so $refs resolve as they are written.
      const where = op.responses[String(r.status)].$ref
        ? `${op.responses[String(r.status)].$ref.slice(1)}`
        : `/paths/${escape(tpl.t)}/${method.toLowerCase()}/responses/${r.status}`;
      const v = ajv.getSchema(`openapi#${where}/content/${escape(media)}/schema`);
      assert.ok(v, `no schema at ${where}`);
      if (!v(r.json)) {
        assert.fail(`${method} ${url} ${r.status} does not match openapi.yaml: ${ajv.errorsText(v.errors)}\n` +
                    JSON.stringify(r.json).slice(0, 2000));
      }
    }
  }
  return r;
}

async function follow(d, url, done) {
  const until = Date.now() + 120000 * SLOW;
  for (;;) {
    const r = await call(d, 'GET', url);
    assert.equal(r.status, 200);
    if (done(r.json)) return r.json;
    assert.ok(Date.now() < until, `${url} did not finish: ${r.text.slice(0, 500)}`);
    await sleep(50);
  }
}

const SMALL = {'/image/width': 24, '/image/height': 18, '/technique/params/samples': 4};

test('a typical client run matches openapi.yaml', async () => {
  await withDaemon({}, async (d) => {
    assert.equal((await call(d, 'GET', '/api/v1/health')).status, 200);
    assert.equal((await call(d, 'GET', '/api/v1/techniques')).status, 200);
    assert.equal((await call(d, 'GET', '/api/v1/scenes')).status, 200);

    // A bundled scene file and an inline document, both followed through every state they pass.
    const a = await call(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: SMALL, label: 'contract'}});
    assert.equal(a.status, 201);
    const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, 'sphere_on_plane.json'), 'utf8'));
    doc.image = {...doc.image, width: 16, height: 12};
    doc.technique = {name: 'ssao'};
    const b = await call(d, 'POST', '/api/v1/jobs', {body: doc});
    assert.equal(b.status, 201);
    const ja = await follow(d, a.json.links.self, (j) => TERMINAL.has(j.state));
    const jb = await follow(d, b.json.links.self, (j) => TERMINAL.has(j.state));
    assert.equal(ja.state, 'succeeded');
    assert.equal(jb.state, 'succeeded');

    // The list, a filtered page and its cursor.
    assert.equal((await call(d, 'GET', '/api/v1/jobs')).status, 200);
    const page = await call(d, 'GET', '/api/v1/jobs?limit=1&state=succeeded');
    assert.equal(page.json.jobs.length, 1);
    assert.equal(typeof page.json.next, 'string');
    assert.equal((await call(d, 'GET', `/api/v1/jobs?limit=1&after=${encodeURIComponent(page.json.next)}`)).status, 200);

    // Every output the job links, and a ranged read.
    for (const ref of Object.values(ja.links.outputs)) assert.equal((await call(d, 'GET', ref)).status, 200);
    const ranged = await call(d, 'GET', Object.values(ja.links.outputs)[0], {headers: {range: 'bytes=0-7'}});
    assert.equal(ranged.status, 206);
    assert.equal((await call(d, 'GET', `/api/v1/jobs/${ja.id}/outputs/nope.exr`)).status, 404);
    // A finished job's preview is its EXR; the FLIP map of the job against itself, and a refusal.
    assert.equal((await call(d, 'GET', `/api/v1/jobs/${ja.id}/preview.exr`)).status, 303);
    assert.equal((await call(d, 'GET', `/api/v1/diff?a=${ja.id}/ao.exr&b=${ja.id}/ao.exr&channel=ao`)).status, 200);
    assert.equal((await call(d, 'GET', `/api/v1/diff?a=${ja.id}/ao.exr&channel=ao`)).status, 400);

    // A small comparison, followed to its end; the list and the CSV.
    const c = await call(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'sphere_on_plane.json', repeats: 1, reference: {samples: 8},
      set: {'/image/width': 16, '/image/height': 12},
      candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: [1, 4]}},
                   {technique: 'ssao', backend: 'cpu'}]}});
    assert.equal(c.status, 201);
    const cmp = await follow(d, c.json.links.self, (x) => x.state !== 'running');
    assert.equal(cmp.state, 'succeeded');
    assert.equal((await call(d, 'GET', '/api/v1/comparisons')).status, 200);
    assert.equal((await call(d, 'GET', c.json.links.csv)).status, 200);

    // Refusals: each documented with the Error body.
    assert.equal((await call(d, 'POST', `/api/v1/jobs/${ja.id}/cancel`)).status, 409);
    assert.equal((await call(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: {'/technique/params/samples': 0}}})).status, 422);
    assert.equal((await call(d, 'POST', '/api/v1/jobs', {body: '{"scene_file": '})).status, 400);
    assert.equal((await call(d, 'POST', '/api/v1/comparisons', {body: {scene_file: 'sphere_on_plane.json', candidates: [{technique: 'nope'}]}})).status, 422);
    assert.equal((await call(d, 'GET', '/api/v1/jobs?state=bogus')).status, 400);
    assert.equal((await call(d, 'GET', '/api/v1/comparisons/999999')).status, 404);

    // Delete, then the job is gone.
    assert.equal((await call(d, 'DELETE', `/api/v1/jobs/${jb.id}`)).status, 204);
    assert.equal((await call(d, 'GET', `/api/v1/jobs/${jb.id}`)).status, 404);
    assert.equal((await call(d, 'GET', '/metrics')).status, 200);
  });
  // The run reached the operations a client uses.
  for (const k of ['GET /api/v1/jobs/{id} 200', 'POST /api/v1/jobs 201', 'GET /api/v1/comparisons/{id} 200',
                   'POST /api/v1/comparisons 201', 'GET /api/v1/jobs/{id}/outputs/{name} 200'])
    assert.ok(covered.has(k), `not exercised: ${k}`);
});

test('with a token: the 401 answers match openapi.yaml too', async () => {
  await withDaemon({token: 'contract-token'}, async (d) => {
    for (const p of ['/api/v1/jobs', '/api/v1/comparisons', '/api/v1/techniques', '/api/v1/health'])
      assert.equal((await call(d, 'GET', p, {auth: false})).status, 401);
    assert.equal((await call(d, 'GET', '/api/v1/health')).status, 200);
  });
});

// A flow mapping such as {type: string, description: a, b} makes "b" a key: in a schema, a
// property or keyword whose value is null. The spec has none.
test('openapi.yaml declares no property without a schema', () => {
  const bad = [];
  (function walk(o, at) {
    if (!o || typeof o !== 'object') return;
    if (o.properties && typeof o.properties === 'object' && !Array.isArray(o.properties))
      for (const [k, v] of Object.entries(o.properties))
        if (v === null || typeof v !== 'object') bad.push(`${at}/properties/${k}`);
    for (const [k, v] of Object.entries(o)) {
      if (v === null && k !== 'default' && k !== 'const' && !Array.isArray(o)) bad.push(`${at}/${k}`);
      walk(v, `${at}/${k}`);
    }
  })(spec, '');
  assert.deepEqual(bad, []);
});
