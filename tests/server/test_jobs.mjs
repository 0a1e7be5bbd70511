// Job life cycle through the API: cancellation (queued and running), deletion, pagination,
// filtering and priorities, each on its own daemon with one CPU worker.
//
//   node tests/server/test_jobs.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {test} from 'node:test';

import {SLOW, exrHeader, getJSON, getJob, listAll, listFiles, request, sleep, sql, submit, validate, waitAll, waitJob,
        withDaemon} from './lib.mjs';
import {decodeExr} from '../../web/js/exr.js';

// A tiny job (about a millisecond of rendering in the release build).
const small = (extra = {}) => ({
  scene_file: 'sphere_on_plane.json',
  set: {'/image/width': 24, '/image/height': 24, '/technique/params/samples': 8},
  ...extra,
});
// A long job made of many short tiles (1024 tiles of 32x32): it runs for many seconds on two cores
// (still over a second on sixteen) but sees a cancel flag quickly. Every test cancels it.
const LONG = {
  scene_file: 'sphere_on_plane.json',
  technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 256}},
  set: {'/image/width': 1024, '/image/height': 1024},
  label: 'blocker',
};
const CANCEL_MS = 2000 * (SLOW > 1 ? 1.5 : 1);

// Submits the long job and waits until the worker runs it.
async function blocker(d) {
  const id = await submit(d, LONG);
  await waitJob(d, id, (j) => j.state === 'running' || j.state === 'succeeded');
  return id;
}

async function cancel(d, id, expectStatus = 202) {
  const r = await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
  assert.equal(r.status, expectStatus, `cancel ${id}: ${r.status} ${r.text}`);
  if (expectStatus === 202) validate('Job', r.json);
  else validate('Error', r.json);
  return r.json;
}

// The running job's preview (GET /api/v1/jobs/{id}/preview.exr): an EXR of the primary output and
// alpha at the job's size, some 32x32 tiles rendered and others still empty, not cached; a later
// one holds at least the tiles of the first, with the same values; gone once the job ends, a
// finished job's being its EXR output (303). Eight workers: the render runs on one or two threads
// whatever the machine, so it lasts several seconds (the first tiles come after the standard
// errors' pilot pixels, an eighth of the work) and is cancelled once its previews are seen.
test('preview of a running job', async () => {
  await withDaemon({workers: 8}, async (d) => {
    const W = 256, id = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 384}},
      set: {'/image/width': W, '/image/height': W}});
    const small = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}},
      set: {'/image/width': 16, '/image/height': 16}});
    const get = async () => {
      const deadline = Date.now() + 10000 * SLOW;
      for (;;) {
        const r = await request(d, 'GET', `/api/v1/jobs/${id}/preview.exr`);
        if (r.status === 200) return r;
        assert.equal(r.status, 404, r.text);
        assert.match(r.json.error, new RegExp(`job ${id} is (queued: a preview exists only while a job runs|running and has no preview yet)`));
        assert.ok(Date.now() < deadline, 'a preview within 10 s');
        await sleep(50);
      }
    };
    const img = async (r) => {
      const x = await decodeExr(r.body.buffer.slice(r.body.byteOffset, r.body.byteOffset + r.body.length));
      return Object.fromEntries(x.channels.map((c) => [c.name, c.data]));
    };
    // A tile is rendered when any of its pixels has alpha or AO above 0 (AO is above 0 on the
    // covered pixels of this scene, 1 on the open sky).
    const done = (p) => {
      const tiles = new Set();
      for (let i = 0; i < W * W; i++) if (p.alpha[i] > 0 || p.ao[i] > 0) tiles.add(Math.floor(i / W / 32) * (W / 32) + Math.floor((i % W) / 32));
      return tiles;
    };
    const r1 = await get();
    assert.equal(r1.headers['content-type'], 'image/x-exr');
    assert.equal(r1.headers['cache-control'], 'no-store');
    assert.deepEqual(exrHeader(r1.body), {channels: ['alpha', 'ao'], width: W, height: W});
    const p1 = await img(r1), t1 = done(p1);
    assert.ok(t1.size > 0 && t1.size < (W / 32) ** 2, `some tiles rendered, not all: ${t1.size} of ${(W / 32) ** 2}`);
    await sleep(700);
    const r2 = await request(d, 'GET', `/api/v1/jobs/${id}/preview.exr`);
    assert.equal(r2.status, 200, 'still running after 0.7 s (make the job longer)');
    const p2 = await img(r2), t2 = done(p2);
    assert.ok([...t1].every((t) => t2.has(t)) && t2.size > t1.size, `a later preview adds tiles: ${t1.size} then ${t2.size}`);
    for (let i = 0; i < W * W; i++) {
      if (p1.alpha[i] > 0 || p1.ao[i] > 0) assert.ok(p2.ao[i] === p1.ao[i] && p2.alpha[i] === p1.alpha[i], `pixel ${i} is final once shown`);
    }
    assert.equal((await request(d, 'POST', `/api/v1/jobs/${id}/preview.exr`)).status, 405);
    const busy = await request(d, 'GET', `/api/v1/diff?a=${id}/ao.exr&b=${small}/ao.exr&channel=ao`);
    assert.equal(busy.status, 409, busy.text);
    assert.match(busy.json.error, new RegExp(`^a=${id}/ao.exr: job ${id} is running; only a succeeded job's outputs can be compared`));
    const none = await request(d, 'GET', '/api/v1/jobs/999999/preview.exr');
    assert.equal(none.status, 404);
    assert.match(none.json.error, /no job 999999/);
    await cancel(d, id);
    await waitJob(d, id, (j) => j.state === 'cancelled');
    const gone = await request(d, 'GET', `/api/v1/jobs/${id}/preview.exr`);
    assert.equal(gone.status, 404);
    assert.match(gone.json.error, new RegExp(`job ${id} is cancelled: a preview exists only while a job runs`));
    assert.deepEqual(listFiles(d.resultsDir).filter((f) => f.includes('preview')), [], 'the preview file is removed');
    await waitJob(d, small, (j) => j.state === 'succeeded');
    const fin = await request(d, 'GET', `/api/v1/jobs/${small}/preview.exr`);
    assert.equal(fin.status, 303);
    assert.equal(fin.headers.location, `/api/v1/jobs/${small}/outputs/ao.exr`);
  });
});

// GET /api/v1/diff: the renderer's FLIP of one output against another as an EXR of channel
// "flip" with its mean in a header; an image against itself is 0 everywhere; every bad input is
// named in a 4xx answer.
test('FLIP maps between outputs (GET /api/v1/diff)', async () => {
  await withDaemon({workers: 2}, async (d) => {
    const size = {'/image/width': 32, '/image/height': 24};
    const rt = (samples, set = size) => submit(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples}}, set});
    const [a, b, pt, tiny] = [await rt(8), await rt(2),
      await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'path_trace', backend: 'cpu', params: {samples: 4}}, set: size}),
      await rt(2, {'/image/width': 16, '/image/height': 12})];
    await waitAll(d, [a, b, pt, tiny]);
    const flip = async (q) => {
      const r = await request(d, 'GET', `/api/v1/diff?${q}`);
      assert.equal(r.status, 200, `${q}: ${r.text}`);
      assert.equal(r.headers['content-type'], 'image/x-exr');
      const img = await decodeExr(r.body.buffer.slice(r.body.byteOffset, r.body.byteOffset + r.body.length));
      assert.deepEqual([img.width, img.height, img.channels.map((c) => c.name)], [32, 24, ['flip']]);
      return {map: img.channels[0].data, mean: Number(r.headers['x-obscura-flip-mean'])};
    };
    const self = await flip(`a=${a}/ao.exr&b=${a}/ao.exr&channel=ao`);
    assert.ok(self.map.every((v) => v === 0) && self.mean === 0, 'an image against itself');
    const hdrSelf = await flip(`a=${pt}/radiance.exr&b=${pt}/radiance.exr&channel=radiance&hdr=1`);
    assert.ok(hdrSelf.map.every((v) => v === 0) && hdrSelf.mean === 0, 'HDR-FLIP of radiance against itself');
    const ab = await flip(`a=${a}/ao.exr&b=${b}/ao.exr&channel=ao`);
    assert.ok(ab.map.every((v) => v >= 0 && v <= 1) && ab.map.some((v) => v > 0.05), '8 against 2 samples differ, within [0, 1]');
    const mean = ab.map.reduce((x, v) => x + v, 0) / ab.map.length;
    assert.ok(Math.abs(ab.mean - mean) <= 1e-6 * mean, `the header's mean is the map's: ${ab.mean} vs ${mean}`);
    // A mask of the reference: the same map, the mean over its selected pixels.
    const ref = await decodeExr((await request(d, 'GET', `/api/v1/jobs/${b}/outputs/ao.exr`)).body.buffer);
    const alpha = ref.channels.find((c) => c.name === 'alpha').data;
    const masked = await flip(`a=${a}/ao.exr&b=${b}/ao.exr&channel=ao&mask=alpha`);
    assert.deepEqual(masked.map, ab.map);
    let sum = 0, n = 0;
    alpha.forEach((v, i) => { if (v > 0) { sum += ab.map[i]; n++; } });
    assert.ok(n > 0 && n < alpha.length && Math.abs(masked.mean - sum / n) <= 1e-6 * masked.mean, `masked mean ${masked.mean} vs ${sum / n}`);
    for (const [q, status, msg] of [
      [`b=${b}/ao.exr&channel=ao`, 400, /query parameter a is missing/],
      [`a=${a}/ao.exr&b=${b}/ao.exr`, 400, /query parameter channel is missing/],
      [`a=${a}/ao.exr&b=${b}/ao.exr&channel=ao&gamma=2`, 400, /unknown query parameter "gamma"/],
      [`a=${a}&b=${b}/ao.exr&channel=ao`, 400, new RegExp(`^a=${a}: not <job>/<file>.exr`)],
      [`a=${a}/ao.png&b=${b}/ao.exr&channel=ao`, 400, new RegExp(`^a=${a}/ao.png: not <job>/<file>.exr`)],
      [`a=${a}/ao.exr&b=${b}/ao.exr&channel=ao&hdr=yes`, 400, /hdr must be 0/],
      [`a=${a}/ao.exr&b=999999/ao.exr&channel=ao`, 404, /^b=999999\/ao.exr: no job 999999/],
      [`a=${a}/radiance.exr&b=${b}/ao.exr&channel=ao`, 404, new RegExp(`^a=${a}/radiance.exr: job ${a} has no output radiance.exr`)],
      [`a=${a}/ao.exr&b=${b}/ao.exr&channel=nope`, 422, /cannot compute FLIP of a \(the test image\) against b/],
      [`a=${a}/ao.exr&b=${tiny}/ao.exr&channel=ao`, 422, /a is 32x24, b 16x12/],
    ]) {
      const r = await request(d, 'GET', `/api/v1/diff?${q}`);
      assert.equal(r.status, status, `${q}: ${r.text}`);
      validate('Error', r.json);
      assert.match(`${r.json.error} ${r.json.problems.join(' ')}`, msg, q);
    }
    assert.equal((await request(d, 'POST', `/api/v1/diff?a=${a}/ao.exr&b=${b}/ao.exr&channel=ao`)).status, 405);
    const metrics = (await request(d, 'GET', '/metrics')).text;
    assert.match(metrics, /obscura_http_requests_total\{route="\/api\/v1\/diff",status="200"\} [1-9]/, 'the route has its metrics label');
  });
});

test('cancellation of queued and running jobs', async () => {
  await withDaemon({}, async (d) => {
    const a = await blocker(d);
    const b = await submit(d, small());
    assert.equal((await getJob(d, b)).state, 'queued');
    // Queued: cancelled at once.
    const cb = await cancel(d, b);
    assert.equal(cb.state, 'cancelled');
    const jb = await getJob(d, b);
    assert.equal(jb.state, 'cancelled');
    assert.match(jb.error, /cancel/i);
    assert.ok(jb.finished_at);
    assert.equal(jb.attempts, 0);
    assert.deepEqual(jb.outputs, []);
    await cancel(d, b, 409);
    const bPreview = await request(d, 'GET', `/api/v1/jobs/${b}/preview.exr`);
    assert.equal(bPreview.status, 404);
    assert.match(bPreview.json.error, new RegExp(`job ${b} is cancelled: a preview exists only while a job runs`));
    // Running, some tiles done (live progress): stops between tiles.
    const running = await waitJob(d, a, (j) => j.state !== 'running' || j.progress > 0);
    assert.equal(running.state, 'running', 'the blocker must still run (make it longer)');
    assert.ok(running.progress > 0 && running.progress < 1, `progress ${running.progress}`);
    const t0 = Date.now();
    const ca = await cancel(d, a);
    assert.ok(ca.state === 'cancelled' || (ca.state === 'running' && ca.cancel_requested === true), JSON.stringify(ca));
    const ja = await waitJob(d, a, (j) => j.state !== 'running', 30000 * SLOW);
    const ms = Date.now() - t0;
    assert.equal(ja.state, 'cancelled', JSON.stringify(ja));
    assert.ok(ms <= CANCEL_MS, `running job took ${ms} ms to stop (limit ${CANCEL_MS})`);
    console.log(`# running job cancelled in ${ms} ms at progress ${ja.progress}`);
    assert.match(ja.error, /cancel/i);
    assert.deepEqual(ja.outputs, []);
    assert.equal(ja.cancel_requested, true);
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${a}/outputs/ao.exr`)).status, 404);
    await cancel(d, a, 409);
    // Nothing of either job on disk; the worker is free again.
    assert.deepEqual(listFiles(d.resultsDir).filter((f) => f.startsWith(`${a}/`) || f.startsWith(`${b}/`)), []);
    const c = await submit(d, small());
    assert.equal((await waitJob(d, c)).state, 'succeeded');
    // The worker frees its slot just after it commits the job's state: allow it that moment.
    let health = await getJSON(d, '/api/v1/health');
    for (let i = 0; i < 100 && health.running !== 0; i++) {
      await new Promise((r) => setTimeout(r, 50));
      health = await getJSON(d, '/api/v1/health');
    }
    assert.equal(health.running, 0);
    assert.equal(health.queue_depth, 0);
    // A cancelled job keeps the last progress seen (openapi.yaml, Job.progress).
    assert.ok(ja.progress >= running.progress && ja.progress < 1,
              `job ${a}: progress ${ja.progress} once cancelled; ${running.progress} was seen while it ran`);
  });
});

test('deletion of finished jobs only', async () => {
  await withDaemon({}, async (d) => {
    const done = await submit(d, small());
    assert.equal((await waitJob(d, done)).state, 'succeeded');
    assert.ok(listFiles(d.resultsDir).some((f) => f.startsWith(`${done}/ao.exr `)), listFiles(d.resultsDir).join());
    const run = await blocker(d);
    const queued = await submit(d, small());
    for (const id of [run, queued]) {
      const r = await request(d, 'DELETE', `/api/v1/jobs/${id}`);
      assert.equal(r.status, 409, `DELETE ${id}: ${r.status} ${r.text}`);
      validate('Error', r.json);
      assert.notEqual((await getJob(d, id)).state, 'cancelled');
    }
    // Finished: succeeded, and cancelled (queued and running before).
    await cancel(d, queued);
    await cancel(d, run);
    await waitJob(d, run, (j) => j.state === 'cancelled');
    for (const id of [done, queued, run]) {
      const r = await request(d, 'DELETE', `/api/v1/jobs/${id}`);
      assert.equal(r.status, 204, `DELETE ${id}: ${r.status} ${r.text}`);
      assert.equal(r.body.length, 0);
      assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 404);
      assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}/outputs/ao.png`)).status, 404);
      assert.equal((await request(d, 'DELETE', `/api/v1/jobs/${id}`)).status, 404);
      assert.equal((await request(d, 'POST', `/api/v1/jobs/${id}/cancel`)).status, 404);
      assert.deepEqual(sql(d.db, `SELECT id FROM jobs WHERE id = ${id}`), []);
      assert.deepEqual(sql(d.db, `SELECT name FROM outputs WHERE job_id = ${id}`), []);
    }
    assert.deepEqual(listFiles(d.resultsDir), [], 'results directory not empty after deleting every job');
    assert.deepEqual((await getJSON(d, '/api/v1/jobs')).jobs, []);
    // Ids are never reused.
    const next = await submit(d, small());
    assert.ok(next > run, `new id ${next} after deleting ${run}`);
    await waitJob(d, next);
  });
});

test('pagination and filtering', async () => {
  await withDaemon({}, async (d) => {
    const x = await blocker(d);
    const specs = [
      small(), small({technique: {name: 'ssao', backend: 'cpu'}}), small(), small(),
      small({technique: {name: 'rt_ao', params: {samples: 4}}}), // backend auto, cancelled while queued
      small({technique: {name: 'hbao', backend: 'cpu'}, set: {'/image/width': 24, '/image/height': 24}}), small({technique: {name: 'rt_ao', params: {samples: 4}}}), // auto, runs
      small({technique: {name: 'ssao', backend: 'cpu'}}), small(),
    ];
    const ids = [];
    for (const s of specs) ids.push(await submit(d, s));
    const cancelled = [ids[2], ids[4], x];
    await cancel(d, ids[2]);
    await cancel(d, ids[4]);
    await cancel(d, x);
    const jobs = await waitAll(d, ids);
    for (const j of jobs) assert.equal(j.state, cancelled.includes(j.id) ? 'cancelled' : 'succeeded', JSON.stringify(j));
    const all = [x, ...ids].sort((a, b) => b - a); // newest first

    // Pages of 3, newest first, following `next`.
    const seen = [];
    let after = null;
    for (let page = 0; page < 10; page++) {
      const p = await getJSON(d, `/api/v1/jobs?limit=3${after ? `&after=${after}` : ''}`);
      validate('JobList', p);
      assert.ok(p.jobs.length >= 1 && p.jobs.length <= 3);
      seen.push(...p.jobs.map((j) => j.id));
      if (p.next === null) break;
      assert.equal(p.next, String(p.jobs[p.jobs.length - 1].id));
      after = p.next;
    }
    assert.deepEqual(seen, all);
    // A last page that is full has next null (no empty page after it).
    const p5 = await getJSON(d, '/api/v1/jobs?limit=5');
    assert.equal(p5.jobs.length, 5);
    const p5b = await getJSON(d, `/api/v1/jobs?limit=5&after=${p5.next}`);
    assert.deepEqual(p5b.jobs.map((j) => j.id), all.slice(5));
    assert.equal(p5b.next, null);
    // Ascending, and a cursor in the middle.
    assert.deepEqual((await listAll(d, 'order=asc', 4)).map((j) => j.id), [...all].reverse());
    const mid = all[4];
    assert.deepEqual((await getJSON(d, `/api/v1/jobs?after=${mid}`)).jobs.map((j) => j.id), all.filter((i) => i < mid));
    assert.deepEqual((await getJSON(d, `/api/v1/jobs?after=${mid}&order=asc`)).jobs.map((j) => j.id),
                     all.filter((i) => i > mid).reverse());
    assert.deepEqual((await getJSON(d, `/api/v1/jobs?after=${Math.min(...all)}`)).jobs, []);
    // Default page: everything, newest first.
    const def = await getJSON(d, '/api/v1/jobs');
    assert.deepEqual(def.jobs.map((j) => j.id), all);
    assert.equal(def.next, null);

    // Filters, alone and together, also through pages.
    const byId = new Map([x, ...ids].map((id, i) => [id, i === 0 ? LONG : specs[i - 1]]));
    const tech = (id) => (byId.get(id).technique || {name: 'rt_ao'}).name;
    const want = {
      'state=cancelled': cancelled,
      'state=succeeded': all.filter((i) => !cancelled.includes(i)),
      'state=running': [],
      'state=queued': [],
      'technique=ssao': [ids[1], ids[7]],
      'technique=hbao': [ids[5]],
      'technique=rt_ao': all.filter((i) => tech(i) === 'rt_ao'),
      // The backend that ran, else the requested one: ids[4] never ran and asked for auto.
      'backend=auto': [ids[4]],
      'backend=cpu': all.filter((i) => i !== ids[4]),
      'backend=vulkan': [],
      'state=succeeded&technique=ssao': [ids[1], ids[7]],
      'state=cancelled&technique=rt_ao&backend=cpu': [ids[2], x],
      'state=failed&technique=hbao': [],
    };
    for (const [q, expected] of Object.entries(want)) {
      const got = (await listAll(d, q, 2)).map((j) => j.id);
      assert.deepEqual(got, [...expected].sort((a, b) => b - a), q);
      const page = await getJSON(d, `/api/v1/jobs?${q}`);
      for (const j of page.jobs) {
        for (const [k, v] of new URLSearchParams(q)) {
          if (k === 'state') assert.equal(j.state, v);
          if (k === 'technique') assert.equal(j.technique, v);
          if (k === 'backend') assert.equal(j.backend.actual ?? j.backend.requested, v);
        }
      }
    }
  });
});

test('priorities: higher first, FIFO within a priority', async () => {
  await withDaemon({}, async (d) => {
    const x = await blocker(d);
    const job = (priority) => ({
      scene_file: 'sphere_on_plane.json', priority,
      set: {'/image/width': 32, '/image/height': 32, '/technique/params/samples': 32},
    });
    const low = [];
    for (let i = 0; i < 4; i++) low.push(await submit(d, job(10)));
    const mid = [await submit(d, job(50)), await submit(d, {...job(50), priority: undefined})];
    const high = await submit(d, job(90));
    const top = await submit(d, job(100));
    const bottom = await submit(d, job(0));
    for (const id of [...low, ...mid, high, top, bottom]) assert.equal((await getJob(d, id)).state, 'queued');
    await cancel(d, x);
    const expected = [top, high, ...mid, ...low, bottom];
    const jobs = await waitAll(d, expected);
    for (const j of jobs) assert.equal(j.state, 'succeeded');
    assert.equal(jobs[3].priority, 50, 'default priority');
    // One worker: each starts after the previous one finished, in priority order.
    for (let i = 1; i < jobs.length; i++) {
      const prev = jobs[i - 1], cur = jobs[i];
      assert.ok(Date.parse(cur.started_at) >= Date.parse(prev.finished_at),
                `job ${cur.id} (priority ${cur.priority}) started ${cur.started_at} before job ${prev.id} ` +
                `(priority ${prev.priority}) finished ${prev.finished_at}`);
    }
    const order = sql(d.db, `SELECT id FROM jobs WHERE id IN (${expected.join(',')}) ORDER BY started_ms, finished_ms`)
      .map((r) => Number(r[0]));
    assert.deepEqual(order, expected);
  });
});

test('render time limit', async () => {
  // The estimate would refuse this job at submission; the limit is what is tested here.
  await withDaemon({args: ['--max-render-seconds', '1', '--no-estimate-render-time']}, async (d) => {
    const t0 = Date.now();
    const id = await submit(d, LONG);
    const j = await waitJob(d, id, undefined, 30000 * SLOW);
    const ms = Date.now() - t0;
    assert.equal(j.state, 'failed', JSON.stringify(j));
    assert.match(j.error, /time limit/);
    assert.deepEqual(j.outputs, []);
    assert.ok(ms < 1000 + CANCEL_MS + 1000, `stopped after ${ms} ms`);
    assert.deepEqual(listFiles(d.resultsDir), []);
  });
});

test('auto backend on a daemon without a Vulkan lane runs on the CPU', async () => {
  await withDaemon({}, async (d) => {
    const health = await getJSON(d, '/api/v1/health');
    assert.equal(health.vulkan_available, false, 'started with --no-vulkan: no Vulkan jobs accepted');
    const cat = await getJSON(d, '/api/v1/techniques');
    assert.equal(cat.vulkan_available, false);
    // ssao's static rule prefers Vulkan when a device exists; here it must fall back to the CPU.
    const id = await submit(d, small({technique: {name: 'ssao', backend: 'auto', params: {samples: 8}}}));
    const j = await waitJob(d, id);
    assert.equal(j.state, 'succeeded', JSON.stringify(j));
    assert.equal(j.backend.requested, 'auto');
    assert.equal(j.backend.actual, 'cpu');
    // An explicit Vulkan request is refused with a message naming the flag.
    const r = await request(d, 'POST', '/api/v1/jobs',
                            {body: small({technique: {name: 'ssao', backend: 'vulkan', params: {samples: 8}}})});
    assert.equal(r.status, 422, r.text);
    assert.match(r.text, /--no-vulkan/);
  });
});
