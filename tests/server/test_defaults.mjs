// A job of a bundled scene that names only a technique: the scene's own params stay for its own
// technique; another technique's lengths follow the scene's size, and the answer says so; the
// defaults endpoint shows the same params; a length far off the scene's size warns in the job.
//
//   node tests/server/test_defaults.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {test} from 'node:test';

import {getJSON, request, sql, validate, waitJob, withDaemon} from './lib.mjs';

const SMALL = {'/image/width': 40, '/image/height': 40};

async function post(d, body) {
  const r = await request(d, 'POST', '/api/v1/jobs', {body});
  assert.equal(r.status, 201, `submit: ${r.status} ${r.text}`);
  validate('Submitted', r.json);
  return r.json;
}

const storedParams = (d, id) =>
  JSON.parse(sql(d.db, `SELECT doc FROM jobs WHERE id = ${id}`)[0][0]).technique;

async function finished(d, id) {
  const j = await waitJob(d, id);
  assert.equal(j.state, 'succeeded', JSON.stringify(j));
  return j;
}

test('the scene\'s technique keeps the scene\'s params', async () => {
  await withDaemon({}, async (d) => {
    const own = await post(d, {scene_file: 'cornell_box.json', set: {...SMALL, '/technique/params/samples': 16}});
    const named = await post(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao'},
                                 set: {...SMALL, '/technique/params/samples': 16}});
    assert.deepEqual(named.notes, []);
    const t = storedParams(d, named.id);
    assert.equal(t.params.max_distance, 200);
    assert.equal(t.backend, undefined); // the request's: none given, so auto
    const a = await finished(d, own.id), b = await finished(d, named.id);
    assert.deepEqual(b.notes, []);
    // The same params: the same image (the unbounded default made it nearly black).
    assert.equal(b.stats.ao.mean, a.stats.ao.mean);
    assert.ok(b.stats.ao.mean > 0.5, `ao mean ${b.stats.ao.mean}`);
    // A given param is set over the scene's, the rest stays.
    const over = await post(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao', params: {samples: 4}}, set: SMALL});
    const o = storedParams(d, over.id);
    assert.equal(o.params.samples, 4);
    assert.equal(o.params.max_distance, 200);
    await finished(d, over.id);
  });
});

test('another technique derives its lengths from the scene\'s size and says so', async () => {
  await withDaemon({}, async (d) => {
    const r = await post(d, {scene_file: 'cornell_box.json', technique: {name: 'hbao'}, set: SMALL});
    assert.equal(r.notes.length, 1);
    assert.match(r.notes[0], /hbao radius = [0-9.]+ derived from the scene's size/);
    const radius = storedParams(d, r.id).params.radius;
    assert.ok(radius > 200 && radius < 400, `radius ${radius}`);
    const j = await finished(d, r.id);
    // The job keeps the note: its JSON and its log say what was derived.
    assert.deepEqual(j.notes, r.notes);
    const log = await request(d, 'GET', `/api/v1/jobs/${r.id}/log`);
    assert.equal(log.status, 200);
    assert.ok(log.json.lines.some((l) => l.includes(`note: ${r.notes[0]}`)), JSON.stringify(log.json));
    // Neither the white of a 1-unit radius nor black.
    assert.ok(j.stats.ao.mean > 0.2 && j.stats.ao.mean < 0.95, `ao mean ${j.stats.ao.mean}`);
    assert.deepEqual(j.warnings.filter((w) => /scene sizes \(scene size/.test(w)), []);
    // The endpoint answers what the job ran with.
    const def = await getJSON(d, '/api/v1/scenes/cornell_box.json/defaults?technique=hbao');
    assert.equal(def.params.radius, radius);
    assert.equal(def.scene_technique, 'rt_ao');
    assert.equal(def.backend, null);
    assert.deepEqual(def.notes, r.notes);
    const mine = await getJSON(d, '/api/v1/scenes/cornell_box.json/defaults');
    assert.equal(mine.technique, 'rt_ao');
    assert.equal(mine.params.max_distance, 200);
    assert.equal(mine.params.samples, 64);
    assert.equal(mine.backend, 'cpu');
    assert.deepEqual(mine.notes, []);
    const rt = await getJSON(d, '/api/v1/scenes/cornell_box.json/defaults?technique=path_trace');
    assert.deepEqual(rt.notes, []);
    for (const bad of ['/api/v1/scenes/nope.json/defaults', '/api/v1/scenes/cornell_box.json/defaults?technique=nope']) {
      const x = await request(d, 'GET', bad);
      assert.equal(x.status, 404, bad);
      validate('Error', x.json);
    }
  });
});

test('a radius far below the scene\'s size warns in the job', async () => {
  await withDaemon({}, async (d) => {
    const r = await post(d, {scene_file: 'cornell_box.json', technique: {name: 'hbao', params: {radius: 0.5}}, set: SMALL});
    assert.deepEqual(r.notes, []);
    const j = await finished(d, r.id);
    assert.ok(j.warnings.some((w) => /radius = 0\.5 is .* scene sizes .*less than 0\.001 scene sizes/.test(w)),
              JSON.stringify(j.warnings));
  });
});

test('comparison candidates start from the scene\'s params, or lengths fitted to it', async () => {
  await withDaemon({}, async (d) => {
    const r = await request(d, 'POST', '/api/v1/comparisons', {body: {
      scene_file: 'cornell_box.json', set: SMALL, repeats: 1, reference: {samples: 16},
      candidates: [{technique: 'hbao', backend: 'cpu', params: {directions: [4, 8]}},
                   {technique: 'rt_ao', params: {samples: 4}}]}});
    assert.equal(r.status, 201, r.text);
    validate('ComparisonCreated', r.json);
    // One note for hbao's radius, though two hbao candidates derived it.
    assert.equal(r.json.notes.length, 1);
    assert.match(r.json.notes[0], /hbao radius = [0-9.]+ derived from the scene's size/);
    const c = await getJSON(d, `/api/v1/comparisons/${r.json.id}`);
    validate('Comparison', c);
    assert.deepEqual(c.notes, r.json.notes);
    const hbao = c.candidates.filter((x) => x.technique === 'hbao');
    assert.equal(hbao.length, 2);
    for (const x of hbao) assert.ok(x.params.radius > 200 && x.params.radius < 400, `radius ${x.params.radius}`);
    const rt = c.candidates.find((x) => x.technique === 'rt_ao');
    assert.equal(rt.params.max_distance, 200);
    assert.equal(rt.params.samples, 4);
  });
});
