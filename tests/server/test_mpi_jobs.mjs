// Jobs split over Open MPI ranks ("ranks" > 1, docs/server.md "Jobs on Open MPI ranks"): obscurad
// --mpirun runs `mpirun -np N obscura render` per job; the outputs are bit-identical to a
// one-process render (a volume file too); progress moves while the ranks render; a cancel leaves
// no process behind; without --mpirun, or out of range, ranks is refused naming /ranks; every rank
// counts as a renderer process against the per-job limits and the queued-jobs cap.
//
//   node tests/server/test_mpi_jobs.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {SCENES_DIR, SLOW, cliRender, download, getJob, request, sleep, startDaemon, submit, validate,
        waitJob, withDaemon} from './lib.mjs';

const MPIRUN = spawnSync('sh', ['-c', 'command -v mpirun'], {encoding: 'utf8'}).stdout.trim();

// Tests run as root in containers, where single copy through CMA needs ptrace rights they often
// lack (tests/cli/mpi.sh). Under ASan the ranks are ASan builds that leak inside Open MPI: they
// get cli.mpi's suppressions (tests/CMakeLists.txt). The daemon passes its environment on to
// mpirun; neither setting changes anything for the daemon itself, which links no MPI.
process.env.OMPI_MCA_btl_vader_single_copy_mechanism = 'none';
if (SLOW > 1) {
  const root = path.resolve(SCENES_DIR, '..');
  process.env.LSAN_OPTIONS = `suppressions=${root}/tests/lsan_mpi.supp:print_suppressions=0:fast_unwind_on_malloc=0`;
  process.env.OMPI_MCA_mca_base_component_disable_dlclose = '1';
  process.env.PMIX_MCA_mca_base_component_disable_dlclose = '1';
}

const SETS = {'/image/width': 48, '/image/height': 32, '/technique/params/samples': 8};
const job = (ranks) => ({
  scene_file: 'sphere_on_plane.json',
  technique: {name: 'rt_ao', backend: 'cpu'},
  set: SETS,
  ranks,
});

test('ranks 2 renders the same bytes as ranks 1 and the CLI', {skip: !MPIRUN && 'no mpirun'}, async () => {
  await withDaemon({args: ['--mpirun', MPIRUN, '--max-voxels', '2800000']}, async (d) => {
    const two = await submit(d, job(2));
    const one = await submit(d, job(1));
    const j2 = await waitJob(d, two);
    const j1 = await waitJob(d, one);
    assert.equal(j2.state, 'succeeded', `ranks 2: ${j2.error}\n${d.log().slice(-3000)}`);
    assert.equal(j1.state, 'succeeded', `ranks 1: ${j1.error}`);
    validate('Job', j2);
    assert.equal(j2.ranks, 2);
    assert.equal(j1.ranks, 1);
    assert.equal(j2.backend.actual, 'cpu');
    const ao2 = (await download(d, j2, 'ao.exr')).body;
    const ao1 = (await download(d, j1, 'ao.exr')).body;
    assert.ok(ao2.equals(ao1), 'ao.exr of ranks 2 differs from ranks 1');
    const sum = JSON.parse((await download(d, j2, 'summary.json')).body.toString());
    assert.equal(sum.ranks, 2, 'summary.json of the ranks 2 job says ranks 2');
    const out = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-mpi-cli-'));
    try {
      cliRender(path.join(SCENES_DIR, 'sphere_on_plane.json'), out,
                {technique: 'rt_ao', backend: 'cpu', sets: SETS});
      assert.ok(fs.readFileSync(path.join(out, 'ao.exr')).equals(ao2), 'ao.exr differs from obscura render');
    } finally {
      fs.rmSync(out, {recursive: true, force: true});
    }
    const log = await request(d, 'GET', `/api/v1/jobs/${two}/log`);
    assert.match(log.text, /mpirun started/);
    // The ranks read the document from the job's work directory: a scene that reads files is
    // refused rather than failing there.
    const mesh = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'teapot.json', ranks: 2,
                                                                  technique: {name: 'rt_ao', backend: 'cpu'}}});
    assert.equal(mesh.status, 422, mesh.text);
    assert.ok(mesh.json.problems.some((p) => /\/ranks: .*mesh file/.test(p)), mesh.text);
    // A volume file resolves against the daemon's scenes directory on every rank, as in a local
    // job: volume_head reads models/brainsmall.den.
    const head = (ranks) => ({scene_file: 'volume_head.json', ranks,
                              technique: {name: 'volume_ao', backend: 'cpu', params: {samples: 4}},
                              set: {'/image/width': 24, '/image/height': 16}});
    const h2 = await waitJob(d, await submit(d, head(2)));
    const h1 = await waitJob(d, await submit(d, head(1)));
    assert.equal(h2.state, 'succeeded', `volume_head ranks 2: ${h2.error}\n${d.log().slice(-3000)}`);
    assert.equal(h1.state, 'succeeded', `volume_head ranks 1: ${h1.error}`);
    assert.equal(h2.progress, 1);
    const v2 = (await download(d, h2, 'final.exr')).body;
    assert.ok(v2.equals((await download(d, h1, 'final.exr')).body), 'final.exr of ranks 2 differs from ranks 1');
    // Every local rank reads the whole volume: volume_torus's 96^3 + 48^3 = 995328 samples fit
    // --max-voxels twice, not three times.
    const vol = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'volume_torus.json', ranks: 3,
                                                                 technique: {name: 'volume_ao', backend: 'cpu'}}});
    assert.equal(vol.status, 422, vol.text);
    assert.ok(vol.json.problems.some((p) => /\/ranks: 3 ranks on this machine each hold the scene's 995328 volume samples, 2985984 in all, beyond the server's limit max-voxels = 2800000/.test(p)), vol.text);
  });
});

test('a cancelled ranks 2 job leaves no mpirun or obscura behind', {skip: !MPIRUN && 'no mpirun'}, async () => {
  await withDaemon({args: ['--mpirun', MPIRUN]}, async (d) => {
    // Many seconds on two cores, in 16x16 tiles: it is still running when cancelled.
    const id = await submit(d, {
      scene_file: 'sphere_on_plane.json',
      technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 256}},
      set: {'/image/width': 1024, '/image/height': 1024},
      ranks: 2,
    });
    await waitJob(d, id, (j) => j.state !== 'queued');
    // The ranks are up once mpirun's log line is there; give them a moment to start rendering.
    const deadline = Date.now() + 20000 * SLOW;
    while (!/mpirun started/.test(d.log()) && Date.now() < deadline) await sleep(50);
    // Rank 0's progress reaches the job while the ranks render (read every 200 ms).
    let progress = 0, state = 'running';
    while (Date.now() < deadline && state === 'running' && !(progress > 0)) {
      ({progress, state} = await getJob(d, id));
      await sleep(50);
    }
    const pattern = `\\.tmp-${id}-[0-9]+-mpi/`;
    const before = spawnSync('pgrep', ['-f', pattern], {encoding: 'utf8'});
    assert.equal(before.status, 0, 'mpirun runs the job before the cancel');
    const r = await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
    assert.equal(r.status, 202, `cancel: ${r.status} ${r.text}`);
    const j = await waitJob(d, id, undefined, 30000 * SLOW);
    assert.equal(j.state, 'cancelled', `state ${j.state}: ${j.error}`);
    // Checked once the job is over, so a failure leaves no ranks running.
    assert.ok(state === 'running' && progress > 0 && progress < 1,
              `progress ${progress} (${state}) while the ranks render`);
    const after = spawnSync('pgrep', ['-af', pattern], {encoding: 'utf8'});
    assert.notEqual(after.status, 0, `left behind:\n${after.stdout}`);
    assert.deepEqual(fs.readdirSync(d.resultsDir).filter((n) => n.startsWith(`.tmp-${id}-`)), []);
  });
});

test('a restarted daemon ends the ranks its killed predecessor left running', {skip: !MPIRUN && 'no mpirun'}, async () => {
  const first = await startDaemon({args: ['--mpirun', MPIRUN]});
  const id = await submit(first, {
    scene_file: 'sphere_on_plane.json',
    technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 256}},
    set: {'/image/width': 1024, '/image/height': 1024},
    ranks: 2,
  });
  const deadline = Date.now() + 20000 * SLOW;
  while (!/mpirun started/.test(first.log()) && Date.now() < deadline) await sleep(50);
  await sleep(500 * SLOW);
  const pattern = `\\.tmp-${id}-[0-9]+-mpi/`;
  assert.equal(spawnSync('pgrep', ['-f', pattern]).status, 0, 'mpirun runs the job');
  // The daemon dies without a word (OOM, SIGKILL): its mpirun and ranks go on.
  first.proc.kill('SIGKILL');
  await first.exited;
  assert.equal(spawnSync('pgrep', ['-f', pattern]).status, 0, 'the orphans outlive the daemon');
  // The next daemon on the same directory kills them before it sweeps their staging names; the
  // job is requeued and runs again (to the end: left alone here, it is cancelled).
  await withDaemon({dir: first.dir, args: ['--mpirun', MPIRUN]}, async (d) => {
    const j = await getJob(d, id);
    assert.ok(['queued', 'running'].includes(j.state), `requeued: ${j.state}`);
    await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
    await waitJob(d, id, undefined, 30000 * SLOW);
  });
  const left = spawnSync('pgrep', ['-af', pattern], {encoding: 'utf8'});
  assert.notEqual(left.status, 0, `left behind:\n${left.stdout}`);
});

test('ranks is refused without --mpirun and out of range', async () => {
  await withDaemon({}, async (d) => {
    for (const [ranks, re] of [[2, /\/ranks: ranks > 1 needs the daemon started with --mpirun/],
                               [0, /\/ranks: must be >= 1/], [300, /\/ranks: must be <= 256/],
                               ['2', /\/ranks/]]) {
      const r = await request(d, 'POST', '/api/v1/jobs', {body: job(ranks)});
      assert.equal(r.status, 422, `ranks ${ranks}: ${r.status} ${r.text}`);
      validate('Error', r.json);
      assert.ok(r.json.problems.some((p) => re.test(p)), `ranks ${ranks}: ${r.text}`);
    }
    // Inline documents take it as a wrapper key too.
    const doc = JSON.parse(fs.readFileSync(path.join(SCENES_DIR, 'sphere_on_plane.json'), 'utf8'));
    const r = await request(d, 'POST', '/api/v1/jobs', {body: {...doc, ranks: 2}});
    assert.equal(r.status, 422, r.text);
    assert.ok(r.json.problems.some((p) => /\/ranks:/.test(p)), r.text);
    const id = await submit(d, job(1));
    assert.equal((await waitJob(d, id)).state, 'succeeded');
    assert.equal((await getJob(d, id)).ranks, 1);
  });
});

// Every rank is a full renderer process on this machine (it loads the scene, builds its BVH and
// holds a whole image), so the per-job limits count each: 48 x 32 = 1536 pixels fit
// --max-pixels 5000 three times, not four; sphere_on_plane's 2 triangles fit --max-triangles 5
// twice, not three times. Both answers also say the daemon has no --mpirun.
test('per-job limits count every rank on this machine', async () => {
  await withDaemon({args: ['--max-pixels', '5000', '--max-triangles', '5']}, async (d) => {
    let r = await request(d, 'POST', '/api/v1/jobs', {body: job(4)});
    assert.equal(r.status, 422, r.text);
    validate('Error', r.json);
    const has = (re) => r.json.problems.some((p) => re.test(p));
    assert.ok(has(/^request: \/ranks: 4 ranks on this machine each hold the scene's 1536 pixels, 6144 in all, beyond the server's limit max-pixels = 5000$/), r.text);
    assert.ok(has(/^request: \/ranks: 4 ranks on this machine each hold the scene's 2 triangles, 8 in all, beyond the server's limit max-triangles = 5$/), r.text);
    assert.ok(has(/\/ranks: ranks > 1 needs the daemon started with --mpirun/), r.text);
    r = await request(d, 'POST', '/api/v1/jobs', {body: job(2)});
    assert.equal(r.status, 422, r.text);
    assert.deepEqual(r.json.problems, ['request: /ranks: ranks > 1 needs the daemon started with --mpirun (got 2)']);
    assert.equal((await waitJob(d, await submit(d, job(1)))).state, 'succeeded');
  });
});

// The queue counts renderer processes too: a job on N ranks is N of --max-queued-jobs.
test('a job on N ranks counts N against the queued-jobs cap', {skip: !MPIRUN && 'no mpirun'}, async () => {
  await withDaemon({args: ['--mpirun', MPIRUN, '--max-queued-jobs', '5']}, async (d) => {
    // A local render keeps the only worker busy, so what is submitted next stays queued.
    const blocker = await submit(d, {scene_file: 'sphere_on_plane.json', technique: {name: 'rt_ao', backend: 'cpu'},
                                     set: {'/image/width': 1024, '/image/height': 1024, '/technique/params/samples': 512}});
    await waitJob(d, blocker, (j) => j.state === 'running');
    const three = await submit(d, job(3));
    const r = await request(d, 'POST', '/api/v1/jobs', {body: job(2)});
    assert.equal(r.status, 429, r.text);
    validate('Error', r.json);
    assert.match(r.headers['retry-after'] || '', /^[1-9]\d*$/);
    assert.ok(r.json.problems.some((p) => p.startsWith('queued jobs (a job on N MPI ranks counts N) of client 127.0.0.1 would be 6 (4 queued or running + 2 in this request), over the server\'s limit max-queued-jobs = 5 per client')), r.text);
    // One process more fits exactly.
    const one = await submit(d, job(1));
    // The queued jobs are cancelled before the blocker: cancelled first, the blocker would free the
    // worker for a small job that can finish before its own cancel arrives.
    for (const id of [one, three, blocker]) await request(d, 'POST', `/api/v1/jobs/${id}/cancel`);
    for (const id of [one, three, blocker]) assert.equal((await waitJob(d, id)).state, 'cancelled');
  });
});
