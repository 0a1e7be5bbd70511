// What the dashboard's image viewer costs in the browser: fetching and decoding a job's EXR
// (web/js/exr.js) and making one display image of it (web/js/viewcanvas.js, the work of every
// exposure step), measured in Debian's chromium on real renders of a real obscurad:
//
//   cmake -S . -B build -DCMAKE_BUILD_TYPE=Release && make -C build -j2 obscurad obscura_cli && npm ci
//   [RUNS=5] [SIZE=1280x720] node bench/bench_viewer.mjs [build/obscurad build/obscura]
//
// (tests/browser/lib.mjs takes the binaries as arguments, so the settings are variables.)
// Prints, per job (path_trace: 14 channels; rt_ao: 10), the EXR's size, the median and fastest of
// the timed runs of the fetch, the decode and one display image.
import {getJSON, openBrowser, startDashboard, submit, waitAll} from '../tests/browser/lib.mjs';

function settings() {
  const o = {runs: Number(process.env.RUNS || 5), size: process.env.SIZE || '1280x720'};
  const [w, h] = o.size.split('x').map(Number);
  if (!(o.runs >= 1 && w > 0 && h > 0)) throw new Error('RUNS must be >= 1 and SIZE WxH');
  return {...o, w, h};
}

const o = settings();
const d = await startDashboard({workers: 2});
const {browser, page} = await openBrowser();
try {
  const set = {'/image/width': o.w, '/image/height': o.h};
  const jobs = [
    await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'path_trace', backend: 'cpu', params: {samples: 1}}, set}),
    await submit(d, {scene_file: 'cornell_box.json', technique: {name: 'rt_ao', backend: 'cpu', params: {samples: 1}}, set}),
  ];
  await waitAll(d, jobs, 600000);
  await page.goto(`${d.url}/#/jobs`);
  const reg = await getJSON(d, '/api/v1/techniques');
  console.log(`bench_viewer: ${o.w}x${o.h}, ${o.runs} runs, chromium headless; ms median (fastest)`);
  console.log('job technique   channels EXR bytes   fetch          decode         display');
  for (const id of jobs) {
    const job = await getJSON(d, `/api/v1/jobs/${id}`);
    const tech = reg.techniques.find((t) => t.name === job.technique);
    const file = job.outputs.find((x) => x.name === tech.exr);
    const output = tech.typed_outputs.find((x) => x.primary);
    const r = await page.evaluate(async ([url, out, runs]) => {
      const {decodeExr} = await import('/js/exr.js');
      const {displayBytes, viewsOf} = await import('/js/viewcanvas.js');
      const t = {fetch: [], decode: [], display: []};
      let img = null, buf = null;
      for (let k = 0; k < runs; k++) {
        let t0 = performance.now();
        buf = await (await fetch(url, {cache: 'no-store'})).arrayBuffer();
        t.fetch.push(performance.now() - t0);
        t0 = performance.now();
        img = await decodeExr(buf);
        t.decode.push(performance.now() - t0);
        t0 = performance.now();
        displayBytes(img, out, viewsOf(out)[0], k % 2);
        t.display.push(performance.now() - t0);
      }
      return {t, channels: img.channels.length, bytes: buf.byteLength};
    }, [file.url, output, o.runs]);
    const med = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];
    const cell = (a) => `${med(a).toFixed(1)} (${Math.min(...a).toFixed(1)})`.padEnd(15);
    console.log(`${String(id).padEnd(4)}${job.technique.padEnd(12)}${String(r.channels).padEnd(9)}${String(r.bytes).padEnd(12)}` +
      `${cell(r.t.fetch)}${cell(r.t.decode)}${cell(r.t.display)}`);
  }
} finally {
  await browser.close();
  await d.stopClean();
}
