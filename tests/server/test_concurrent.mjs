// 50 submissions at once (both forms, mixed priorities) while clients poll: every one gets its own
// id, every job completes, the daemon logs no database error, and the counts agree everywhere.
//
//   node tests/server/test_concurrent.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {test} from 'node:test';

import {SCENES_DIR, download, getJSON, listAll, request, sql, submit, validate, waitAll, withDaemon} from './lib.mjs';

const N = 50;

test(`${N} concurrent submissions`, async () => {
  await withDaemon({workers: 2}, async (d) => {
    const inline = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, 'sphere_on_plane.json'), 'utf8'));
    inline.image = {width: 16, height: 16};
    inline.technique.params.samples = 4;
    const bodies = Array.from({length: N}, (_, i) =>
      i % 2 ? {...inline, priority: i % 101, label: `inline ${i}`}
            : {scene_file: 'cornell_box.json', priority: (i * 7) % 101, label: `file ${i}`,
               set: {'/image/width': 16, '/image/height': 16, '/technique/params/samples': 4}});
    // Readers hammer the list while the submissions land.
    let stop = false;
    const reader = (async () => {
      let n = 0;
      while (!stop) {
        const r = await request(d, 'GET', '/api/v1/jobs?limit=500');
        assert.equal(r.status, 200, r.text);
        n++;
      }
      return n;
    })();
    const ids = await Promise.all(bodies.map((b) => submit(d, b)));
    assert.equal(new Set(ids).size, N, 'ids are unique');
    const jobs = await waitAll(d, ids);
    stop = true;
    const reads = await reader;
    for (const [i, j] of jobs.entries()) {
      assert.equal(j.state, 'succeeded', `job ${j.id}: ${j.state} ${j.error}`);
      assert.equal(j.label, bodies[i].label);
      assert.equal(j.priority, bodies[i].priority);
      assert.equal(j.attempts, 1);
    }
    // Outputs of a few, byte-checked against their records.
    for (const j of jobs.slice(0, 5)) await download(d, j, 'ao.png');
    const listed = await listAll(d);
    assert.equal(listed.length, N);
    assert.deepEqual(listed.map((j) => j.id).sort((a, b) => a - b), [...ids].sort((a, b) => a - b));
    assert.equal((await listAll(d, 'state=succeeded', 7)).length, N);
    assert.deepEqual(sql(d.db, "SELECT count(*), sum(state = 'succeeded') FROM jobs"), [[String(N), String(N)]]);
    // ao.exr, ao.png, bent_normal.png, depth.png, summary.json per rt_ao job.
    assert.deepEqual(sql(d.db, 'SELECT count(*) FROM outputs'), [[String(5 * N)]]);
    const health = await getJSON(d, '/api/v1/health');
    validate('Health', health);
    assert.equal(health.status, 'ok');
    assert.equal(health.queue_depth, 0);
    const m = await request(d, 'GET', '/metrics');
    assert.match(m.text, new RegExp(`obscura_jobs\\{state="succeeded"\\} ${N}\\b`));
    assert.match(m.text, new RegExp(`obscura_http_requests_total\\{[^}]*route="/api/v1/jobs"[^}]*status="201"[^}]*\\} ${N}\\b`));
    assert.doesNotMatch(m.text, /status="5\d\d"/, 'a 5xx was answered');
    console.log(`# ${N} jobs done; ${reads} list reads meanwhile`);
  });
});
