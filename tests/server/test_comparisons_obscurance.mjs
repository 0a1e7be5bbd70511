// A comparison of obscurance (per-pixel obscurances with colour bleeding) against its reference,
// path_trace, end to end: the reference hook names path_trace with the candidate's exposure, and
// the candidate's primary output `final` is compared with the reference's `radiance` (the server
// reads the reference's primary output under the candidate's name, its standard error too).
import assert from 'node:assert/strict';
import {test} from 'node:test';

import {SLOW, getJSON, request, sleep, validate, withDaemon} from './lib.mjs';

async function waitComparison(d, id, timeoutMs = 240000 * SLOW) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const c = await getJSON(d, `/api/v1/comparisons/${id}`);
    validate('Comparison', c);
    if (c.state !== 'running') return c;
    if (Date.now() > deadline) throw new Error(`comparison ${id} still running`);
    await sleep(50);
  }
}

/** Posts a comparison, waits for it and asserts every candidate succeeded. */
async function compareOk(d, body) {
  const r = await request(d, 'POST', '/api/v1/comparisons', {body});
  assert.equal(r.status, 201, r.text);
  const c = await waitComparison(d, r.json.id);
  assert.equal(c.state, 'succeeded', JSON.stringify(c.candidates.map((x) => [x.state, x.error])));
  return c;
}

test('obscurance against path_trace: final compared with radiance, RGB metrics', async () => {
  await withDaemon({}, async (d) => {
    const body = {
      scene_file: 'cornell_box.json',
      set: {'/image/width': 32, '/image/height': 24},
      repeats: 1,
      reference: {samples: 256},
      candidates: [{technique: 'obscurance', backend: 'cpu',
                    params: {samples: [4, 64], light_samples: 16, d_max: 300, exposure: 1}}],
    };
    const c = await compareOk(d, body);
    const ref = c.references[0];
    assert.equal(ref.technique, 'path_trace');
    assert.equal(ref.params.samples, 256);
    assert.equal(ref.params.exposure, 1, 'the reference keeps the exposure');
    for (const x of c.candidates) {
      const m = x.metrics;
      assert.equal(m.output, 'final');
      for (const v of m.rgb.rmse) assert.ok(Number.isFinite(v) && v > 0, `per-channel RMSE ${m.rgb.rmse}`);
      assert.ok(m.rgb.ssim_luminance > 0 && m.rgb.ssim_luminance <= 1);
      assert.ok(m.ref_noise > 0, 'the reference noise comes from radiance_stderr');
      assert.equal(x.links.image, `/api/v1/jobs/${x.job_id}/outputs/final.png`);
    }
    // The model's error does not vanish with samples (it is a model of the reference, not a
    // sampler of it), but more rays do not make it worse by more than the noise.
    const lum = c.candidates.map((x) => x.metrics.rgb.rmse_luminance);
    assert.ok(lum[1] <= lum[0] * 1.05, `luminance RMSE ${lum}`);
  });
});

test('obscurance_map against its rays reference: per-patch RMSE falls with more samples', async () => {
  await withDaemon({}, async (d) => {
    const body = {
      scene_file: 'cornell_box.json',
      set: {'/image/width': 32, '/image/height': 24},
      repeats: 1,
      reference: {samples: 512},
      candidates: [{technique: 'obscurance_map', backend: 'cpu',
                    params: {method: ['rays', 'bundles'], samples: [8, 128], directions: 32,
                             bundle_resolution: 64, d_max: 300}}],
    };
    const c = await compareOk(d, body);
    // One reference for all four: the same map by rays at the reference's samples.
    assert.equal(c.references.length, 1);
    const ref = c.references[0];
    assert.equal(ref.technique, 'obscurance_map');
    assert.equal(ref.params.method, 'rays');
    assert.equal(ref.params.samples, 512);
    for (const x of c.candidates) {
      assert.ok(Number.isFinite(x.metrics.rmse) && x.metrics.rmse > 0, JSON.stringify(x.metrics));
      assert.ok(Number.isFinite(x.metrics.patch_rmse) && x.metrics.patch_rmse > 0, JSON.stringify(x.metrics));
    }
    const rays = c.candidates.filter((x) => x.params.method === 'rays').sort((a, b) => a.params.samples - b.params.samples);
    assert.ok(rays[1].metrics.patch_rmse < rays[0].metrics.patch_rmse / 2,
              `rays 8 -> 128 per patch: ${rays.map((x) => x.metrics.patch_rmse)}`);
  });
});

// A moving box: the jobs render every frame, report each one (frames in the job), the per-patch
// file holds them all, and the comparison's per-patch RMSE is over every frame.
test('obscurance_map with a moving object: frames reported, exact update, RMSE over all frames', async () => {
  await withDaemon({}, async (d) => {
    const quad = (y, s, refl) => ({shape: {type: 'quad', vertices: [[-s, y, -s], [-s, y, s], [s, y, s], [s, y, -s]]},
                                   material: {reflectivity: refl}});
    const scene = {
      camera: {type: 'perspective', position: [0, 2, 4], look_at: [0, 0.3, 0], fov_y: 50},
      image: {width: 24, height: 18},
      objects: [quad(0, 2, [0.7, 0.7, 0.7]),
        {name: 'box', shape: {type: 'box', min: [-0.3, 0, -0.3], max: [0.3, 0.6, 0.3]},
         material: {reflectivity: [0.3, 0.8, 0.3]}, transform: {translate: [-1, 0, 0]},
         motion: [{translate: [0, 0, 0], rotate: [0, 30, 0]}, {translate: [1, 0, 0.3], rotate: [0, 60, 0]}]}],
      technique: {name: 'obscurance_map', params: {patch_size: 0.4, d_max: 0.8}},
    };
    const body = {
      scene, repeats: 1, reference: {samples: 256},
      candidates: [{technique: 'obscurance_map', backend: 'cpu',
                    params: {method: 'rays', samples: [4, 64], update: ['exact', 'article']}}],
    };
    const c = await compareOk(d, body);
    assert.equal(c.references[0].params.measure_full, false, 'the reference measures nothing');
    for (const x of c.candidates) {
      assert.ok(Number.isFinite(x.metrics.patch_rmse) && x.metrics.patch_rmse > 0, JSON.stringify(x.metrics));
      const j = await getJSON(d, `/api/v1/jobs/${x.job_id}`);
      validate('Job', j);
      assert.equal(j.frames.length, 3);
      assert.deepEqual(j.frames.map((f) => f.frame), [0, 1, 2]);
      for (const f of j.frames.slice(1)) {
        assert.ok(f.update_ms >= 0 && f.full_ms >= 0 && f.patches_updated > 0, JSON.stringify(f));
        if (x.params.update === 'exact') assert.equal(f.patches_differing, 0, JSON.stringify(f));
      }
      const p = await request(d, 'GET', `/api/v1/jobs/${x.job_id}/outputs/obscurance.patches`);
      assert.equal(p.status, 200);
      const header = JSON.parse(p.body.subarray(0, p.body.indexOf(10)).toString());
      assert.equal(header.frames, 3);
      assert.equal(p.body.length, p.body.indexOf(10) + 1 + 4 * header.count * (3 * 3 + 1));
    }
    const exact = c.candidates.filter((x) => x.params.update === 'exact').sort((a, b) => a.params.samples - b.params.samples);
    assert.ok(exact[1].metrics.patch_rmse < exact[0].metrics.patch_rmse / 2,
      `exact: ${exact.map((x) => x.metrics.patch_rmse)}`);
    // A technique that renders one frame refuses the scene, naming the moving object.
    const bad = await request(d, 'POST', '/api/v1/jobs', {body: {...scene, technique: {name: 'rt_ao'}}});
    assert.equal(bad.status, 422, bad.text);
    assert.match(bad.text, /\/objects\/1\/motion: technique \\?"rt_ao\\?" renders one frame/);
  });
});

// W without colour bleeding against rt_ao with the same falloff: the per-pixel technique's
// `obscurance` output and the map's per-pixel W, each against the same rt_ao reference.
test('obscurance and obscurance_map against rt_ao: W without colour bleeding', async () => {
  await withDaemon({}, async (d) => {
    const reg = await getJSON(d, '/api/v1/techniques');
    for (const name of ['obscurance', 'obscurance_map']) {
      const t = reg.techniques.find((x) => x.name === name);
      assert.deepEqual(t.against, [{technique: 'rt_ao', output: 'obscurance', needs_false: 'color_bleeding'}]);
    }
    const model = {d_max: 300, falloff: 'sqrt', color_bleeding: false};
    const body = {
      scene_file: 'cornell_box.json',
      set: {'/image/width': 32, '/image/height': 24},
      repeats: 1,
      reference: {samples: 1024},
      candidates: [{technique: 'obscurance', backend: 'cpu', against: 'rt_ao',
                    params: {...model, samples: [4, 64], light_samples: 1}},
                   {technique: 'obscurance_map', backend: 'cpu', against: 'rt_ao',
                    params: {...model, method: 'rays', samples: 64, patch_size: 30}}],
    };
    const c = await compareOk(d, body);
    // One reference for all: rt_ao with the candidates' falloff and d_max.
    assert.equal(c.references.length, 1);
    const ref = c.references[0];
    assert.equal(ref.technique, 'rt_ao');
    assert.equal(ref.params.falloff, 'sqrt');
    assert.equal(ref.params.max_distance, 300);
    for (const x of c.candidates) {
      assert.equal(x.metrics.output, 'obscurance', JSON.stringify(x.metrics));
      assert.ok(Number.isFinite(x.metrics.rmse) && x.metrics.rmse > 0, JSON.stringify(x.metrics));
      assert.equal(x.metrics.patch_rmse, undefined, 'rt_ao is not per patch');
    }
    console.log(c.candidates.map((x) => `${x.technique} ${x.params.samples}: rmse ${x.metrics.rmse} ssim ${x.metrics.ssim} ref_noise ${x.metrics.ref_noise}`).join('\n'));
    const px = c.candidates.filter((x) => x.technique === 'obscurance').sort((a, b) => a.params.samples - b.params.samples);
    // The same quantity: the error falls as the samples grow (4 -> 64: a quarter, less the
    // reference's noise), to the level of the reference's noise.
    assert.ok(px[1].metrics.rmse < px[0].metrics.rmse / 2, `obscurance vs rt_ao: ${px.map((x) => x.metrics.rmse)}`);
    // Refused: colour bleeding on (W is then RGB), and a reference the technique does not offer.
    for (const [cand, re] of [
      [{technique: 'obscurance', against: 'rt_ao', params: {color_bleeding: true}}, /\/candidates\/0\/against: .*color_bleeding: comparing obscurance's "obscurance" against "rt_ao" needs color_bleeding false/],
      [{technique: 'obscurance', against: 'hbao', params: {color_bleeding: false}}, /\/candidates\/0\/against: .*cannot be compared against "hbao" \(it can be: null, its own reference, "rt_ao"\)/]]) {
      const bad = await request(d, 'POST', '/api/v1/comparisons', {body: {...body, candidates: [cand]}});
      assert.equal(bad.status, 422, bad.text);
      assert.match(bad.json.problems.join('\n'), re);
    }
  });
});

// A job's work counts every frame of a moving scene, and the full recompute of each that
// measure_full adds: one frame fits the limit, three do not.
test('max-work counts the frames of a moving scene', async () => {
  await withDaemon({args: ['--max-work', '50000']}, async (d) => {
    const scene = {
      camera: {type: 'perspective', position: [0, 2, 4], look_at: [0, 0.3, 0], fov_y: 50},
      image: {width: 24, height: 18},
      objects: [{shape: {type: 'quad', vertices: [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]}, material: {reflectivity: [0.7, 0.7, 0.7]}},
        {shape: {type: 'box', min: [-0.3, 0, -0.3], max: [0.3, 0.6, 0.3]}, material: {reflectivity: [0.3, 0.8, 0.3]}}],
      technique: {name: 'obscurance_map', params: {method: 'rays', samples: 64, patch_size: 0.5}},
    };
    const still = await request(d, 'POST', '/api/v1/jobs', {body: scene});
    assert.equal(still.status, 201, still.text);
    scene.objects[1].motion = [{translate: [0.5, 0, 0]}, {translate: [1, 0, 0]}];
    const moving = await request(d, 'POST', '/api/v1/jobs', {body: scene});
    assert.equal(moving.status, 422, moving.text);
    assert.match(moving.json.problems.join('\n'),
      /\/technique\/params: work = width x height x spp x samples x frames = 432 x 1 x 64 x 5 \(3 frames\) = 1\.382e\+05 exceeds the server's limit max-work = 5e\+04/);
    // Without the full recompute of every frame to measure against, three frames cost three maps.
    scene.technique.params.measure_full = false;
    const cheaper = await request(d, 'POST', '/api/v1/jobs', {body: scene});
    assert.equal(cheaper.status, 422, cheaper.text);
    assert.match(cheaper.json.problems.join('\n'), / = 432 x 1 x 64 x 3 \(3 frames\) = 8\.294e\+04 exceeds/);
  });
});
