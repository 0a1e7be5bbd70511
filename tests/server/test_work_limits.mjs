// Work limits: queued work (width x height x spp x samples, times the renders of each job) is
// capped per client (--max-queued-work; client = remote address, here distinct 127.0.0.x source
// addresses) and in total (--max-queued-work-total), for jobs and for all jobs of a comparison at
// once: over a cap is 429 with Retry-After and nothing queued. The same holds for queued jobs
// (--max-queued-jobs) and the bytes they store (--max-queued-bytes), and for a retry, which
// queues a job again. A comparison creates at most --max-comparison-jobs jobs (422 naming
// /candidates). A job whose estimated render time exceeds --max-render-seconds is refused with
// 422 naming /image, estimated from the built-in rate while nothing is stored and from this
// machine's stored runs once there are some.
//
//   node tests/server/test_work_limits.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import http from 'node:http';
import {test} from 'node:test';

import {getJSON, listAll, request, sql, submit, validate, waitJob, withDaemon} from './lib.mjs';

// POST from a given loopback source address (Linux routes all of 127.0.0.0/8 to lo).
function postFrom(d, from, p, body) {
  return new Promise((resolve, reject) => {
    const data = JSON.stringify(body);
    const req = http.request({host: '127.0.0.1', port: d.port, method: 'POST', path: p, localAddress: from, agent: false,
                              headers: {...d.auth, 'content-type': 'application/json', 'content-length': Buffer.byteLength(data)}},
                             (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('end', () => {
        const text = Buffer.concat(chunks).toString('utf8');
        let json;
        try {
          json = JSON.parse(text);
        } catch {}
        resolve({status: res.statusCode, headers: res.headers, text, json});
      });
    });
    req.on('error', reject);
    req.end(data);
  });
}

const job = (w, h, samples) => ({scene_file: 'cornell_box.json',
                                 set: {'/image/width': w, '/image/height': h, '/image/spp': 1, '/technique/params/samples': samples}});

function assertBusy(r, limit) {
  assert.equal(r.status, 429, `${r.status} ${r.text}`);
  validate('Error', r.json);
  assert.match(r.headers['retry-after'] || '', /^[1-9]\d*$/, `Retry-After: ${r.headers['retry-after']}`);
  assert.ok(r.json.problems.some((p) => p.includes(limit)), `no problem names ${limit}: ${r.text}`);
}

test('queued work is capped per client and in total, comparisons counted whole', async () => {
  // The blocker keeps the only worker busy for seconds (4.2e8 work), so what is queued stays.
  const args = ['--max-queued-work', '5e8', '--max-queued-work-total', '8e8'];
  await withDaemon({args}, async (d) => {
    const blocker = await postFrom(d, '127.0.0.1', '/api/v1/jobs', job(512, 512, 1600));
    assert.equal(blocker.status, 201, blocker.text);
    // 4.19e8 + 1.05e8 > 5e8 for the same client ...
    assertBusy(await postFrom(d, '127.0.0.1', '/api/v1/jobs', job(256, 256, 1600)), 'max-queued-work = 5e+08 per client');
    // ... but fits for another one,
    const other = await postFrom(d, '127.0.0.2', '/api/v1/jobs', job(256, 256, 1600));
    assert.equal(other.status, 201, other.text);
    // and a third client's 4.19e8 overflows the total (5.24e8 queued or running).
    assertBusy(await postFrom(d, '127.0.0.3', '/api/v1/jobs', job(512, 512, 1600)), 'max-queued-work-total = 8e+08');
    const jobsBefore = (await listAll(d)).length;
    assert.equal(jobsBefore, 2);

    // A comparison is counted whole: reference 6.7e7 + candidates (512 + 1024 + 2048) x 65536 x
    // (3 repeats + warm-up) = 9.4e8, over this client's cap although every job fits on its own.
    const cmp = {scene_file: 'cornell_box.json', set: {'/image/width': 256, '/image/height': 256}, repeats: 3,
                 candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: [512, 1024, 2048]}}]};
    const big = await postFrom(d, '127.0.0.4', '/api/v1/comparisons', cmp);
    assertBusy(big, 'max-queued-work = 5e+08 per client');
    assert.ok(big.json.problems.some((p) => /\+ 1\.00[0-9]e\+09 in this request|\+ 9\.[0-9]+e\+08 in this request/.test(p)), big.text);
    assert.equal((await listAll(d)).length, jobsBefore, 'a refused comparison queued jobs');
    assert.equal((await getJSON(d, '/api/v1/comparisons')).comparisons.length, 0);
    // A small one fits.
    const small = await postFrom(d, '127.0.0.4', '/api/v1/comparisons',
                                 {...cmp, set: {'/image/width': 32, '/image/height': 32}, candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: 4}}]});
    assert.equal(small.status, 201, small.text);
    // Once work is cancelled it no longer counts.
    for (const id of [blocker.json.id, other.json.id]) await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
    await waitJob(d, blocker.json.id);
    const after = await postFrom(d, '127.0.0.1', '/api/v1/jobs', job(256, 256, 16));
    assert.equal(after.status, 201, after.text);
    await waitJob(d, after.json.id);
  });
});

test('a job estimated to outlast --max-render-seconds is refused at submission', async () => {
  await withDaemon({args: ['--max-render-seconds', '1']}, async (d) => {
    // Nothing stored yet: the built-in rate of rt_ao (4.2e8 work is minutes, not 1 s).
    let r = await request(d, 'POST', '/api/v1/jobs', {body: job(512, 512, 1600)});
    assert.equal(r.status, 422, r.text);
    validate('Error', r.json);
    const line = r.json.problems.find((p) => p.includes('/image'));
    assert.ok(line, r.text);
    assert.match(line, /estimated render time \d+ s .*built-in rate of rt_ao.*max-render-seconds = 1 s/);
    assert.equal((await listAll(d)).length, 0);

    // Three small jobs store runs of this machine ...
    for (let i = 0; i < 3; i++) {
      const id = await submit(d, job(64, 64, 200));
      assert.equal((await waitJob(d, id)).state, 'succeeded');
    }
    // ... which then estimate a job of 8.2e7 work (within 100x of theirs): at any rate this
    // renderer reaches per unit of work, well over a second.
    r = await request(d, 'POST', '/api/v1/jobs', {body: job(640, 640, 200)});
    assert.equal(r.status, 422, r.text);
    assert.ok(r.json.problems.some((p) => /\/image: estimated render time .*median of 3 stored runs of rt_ao on cpu/.test(p)), r.text);
    // A small job still goes through.
    const id = await submit(d, job(32, 32, 16));
    assert.equal((await waitJob(d, id)).state, 'succeeded');
  });
});

// Keeps the only worker busy for many seconds (a cancel stops it within a tile).
const BLOCKER = job(1024, 1024, 2048);

test('a retry passes the same admission as a submission', async () => {
  // Each BLOCKER is 1024 x 1024 x 2048 = 2.1e9 work: one fits 3e9, two do not.
  await withDaemon({args: ['--max-queued-work', '3e9']}, async (d) => {
    const again = await submit(d, BLOCKER);
    await request(d, 'POST', `/api/v1/jobs/${again}/cancel`);
    assert.equal((await waitJob(d, again)).state, 'cancelled');
    const blocker = await submit(d, BLOCKER);
    await waitJob(d, blocker, (j) => j.state === 'running');
    // Queued again, the cancelled job would make this client's work 4.3e9.
    const r = await request(d, 'POST', `/api/v1/jobs/${again}/retry`);
    assertBusy(r, 'max-queued-work = 3e+09 per client');
    assert.ok(r.json.problems.some((p) => p.includes('would be 4.295e+09 (2.147e+09 queued or running + 2.147e+09 in this request)')), r.text);
    assert.equal((await getJSON(d, `/api/v1/jobs/${again}`)).state, 'cancelled', 'a refused retry requeued the job');
    assert.doesNotMatch((await getJSON(d, `/api/v1/jobs/${again}/log`)).lines.join('\n'), /retried by request/);
    // A job that is neither failed nor cancelled is a 409, whatever the queue holds.
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${blocker}/retry`)).status, 409);
    // Room again: the retry goes through.
    await request(d, 'POST', `/api/v1/jobs/${blocker}/cancel`);
    assert.equal((await waitJob(d, blocker)).state, 'cancelled');
    const ok = await request(d, 'POST', `/api/v1/jobs/${again}/retry`);
    assert.equal(ok.status, 202, ok.text);
    // The idle worker may take it before the reply is written.
    assert.ok(['queued', 'running'].includes(ok.json.state), ok.text);
    await request(d, 'POST', `/api/v1/jobs/${again}/cancel`);
    await waitJob(d, again);
  });
});

test('queued jobs and stored bytes are capped; a comparison creates at most max-comparison-jobs', async () => {
  // cornell_box's stored document is about 4 KB: two fit 10 KiB, three do not.
  await withDaemon({args: ['--max-queued-bytes', '10K', '--max-queued-jobs-total', '4']}, async (d) => {
    const blocker = await postFrom(d, '127.0.0.1', '/api/v1/jobs', BLOCKER);
    assert.equal(blocker.status, 201, blocker.text);
    await waitJob(d, blocker.json.id, (j) => j.state === 'running');
    const second = await postFrom(d, '127.0.0.1', '/api/v1/jobs', job(32, 32, 4));
    assert.equal(second.status, 201, second.text);
    const third = await postFrom(d, '127.0.0.1', '/api/v1/jobs', job(32, 32, 4));
    assertBusy(third, 'max-queued-bytes = 10240 per client');
    assert.ok(third.json.problems.some((p) => /^bytes stored by queued jobs of client 127\.0\.0\.1 would be \d+ bytes/.test(p)), third.text);
    // Another client has room for bytes, but the server's job count is full at 4.
    for (let i = 0; i < 2; i++) assert.equal((await postFrom(d, '127.0.0.2', '/api/v1/jobs', job(32, 32, 4))).status, 201);
    assertBusy(await postFrom(d, '127.0.0.3', '/api/v1/jobs', job(32, 32, 4)), 'max-queued-jobs-total = 4');
    const health = await getJSON(d, '/api/v1/health');
    validate('Health', health);
    assert.equal(health.status, 'degraded', 'refusing for the server-wide job cap');
    assert.deepEqual(health.capacity.refusing, ['max-queued-jobs-total']);
    const count = (limit) => health.capacity.refused.find((x) => x.limit === limit).count;
    assert.equal(count('max-queued-bytes'), 1);
    assert.equal(count('max-queued-jobs-total'), 1);
    assert.equal((await listAll(d)).length, 4);
    for (const j of await listAll(d)) await request(d, 'POST', `/api/v1/jobs/${j.id}/cancel`);
  });
  await withDaemon({args: ['--max-comparison-jobs', '4']}, async (d) => {
    // 4 candidates and their reference: 5 jobs, refused before anything is stored.
    const cmp = {scene_file: 'cornell_box.json', set: {'/image/width': 16, '/image/height': 16}, repeats: 1,
                 candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: [1, 2, 3, 4]}}]};
    const big = await postFrom(d, '127.0.0.4', '/api/v1/comparisons', cmp);
    assert.equal(big.status, 422, big.text);
    validate('Error', big.json);
    assert.ok(big.json.problems.some((p) => p.startsWith('request: /candidates: 4 candidates and their references make at least 5 jobs; this server takes at most max-comparison-jobs = 4 per comparison')), big.text);
    assert.equal((await getJSON(d, '/api/v1/comparisons')).comparisons.length, 0);
    assert.equal((await listAll(d)).length, 0);
    // Three candidates and their reference fit; their documents and the comparison's request
    // count as stored bytes.
    const ok = await postFrom(d, '127.0.0.4', '/api/v1/comparisons', {...cmp, candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: [1, 2, 3]}}]});
    assert.equal(ok.status, 201, ok.text);
    const stored = Number(sql(d.db, "SELECT sum(stored_bytes) FROM jobs WHERE client = '127.0.0.4'")[0][0]);
    const docs = Number(sql(d.db, "SELECT sum(length(doc)) FROM jobs WHERE client = '127.0.0.4'")[0][0]);
    const req = Number(sql(d.db, 'SELECT length(request) FROM comparisons')[0][0]);
    assert.ok(stored >= docs + req, `stored ${stored} < documents ${docs} + request ${req}`);
    const c = await getJSON(d, `/api/v1/comparisons/${ok.json.id}`);
    for (const x of c.candidates) await request(d, 'POST', `/api/v1/jobs/${x.job_id}/cancel`);
    for (const x of c.candidates) await waitJob(d, x.job_id);
  });
});
