// Produces docs/comparison-cornell.md: measured comparisons of every technique on the Cornell box
// (a real obscurad with its CPU and Vulkan lanes, POST /api/v1/comparisons, the stored tables),
// one per quantity the techniques estimate (their primary output's kind: AO, RGB radiance,
// per-patch values), since errors of different quantities do not share a scale, plus a
// screenshot of the dashboard's Pareto chart of each, taken in Debian's chromium. Anyone can
// rerun it:
//
//   cmake -S . -B build -DCMAKE_BUILD_TYPE=Release && make -C build -j2 && npm ci
//   node bench/bench_comparison.mjs [--size 320x240] [--repeats 5] [--reference-samples N]
//                                   [--no-vulkan] [--no-screenshot] [--out docs]
//
// The techniques come from GET /api/v1/techniques, so a new technique joins the comparison of its
// quantity when it is given a parameter grid in GRIDS below (one without a grid runs with its
// defaults on every backend).
import {spawn, spawnSync} from 'node:child_process';
import fs from 'node:fs';
import {createRequire} from 'node:module';
import os from 'node:os';
import path from 'node:path';
import {fileURLToPath} from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const require = createRequire(path.join(ROOT, 'package.json'));

// Parameter grids per technique: the trade each one offers. hbao's radius is set to the Cornell
// box's scale (a 550-unit room) as in docs/accuracy.md; rt_ao's distance is the scene file's. A
// list holds candidate entries of their own (a method that runs on one backend only).
const GRIDS = {
  rt_ao: {samples: [4, 16, 64, 256], max_distance: 200},
  ssao: {samples: [8, 16, 24], normal_oriented: [false, true]},
  hbao: {directions: [4, 8, 16], steps: [4, 8], radius: 100},
  path_trace: {samples: [1, 4, 16]},
  obscurance: {samples: [4, 16, 64], light_samples: 16, d_max: 300, color_bleeding: [false, true]},
  ss_obscurance: {samples: [8, 16, 32], radius: 150},
  ssao_variance: {method: ['variance', 'depth_unsharp'], radius: 100},
  disc_ao: {influence_scale: [4, 16], side: ['front', 'back']},
  // strength 0 is the direct pass alone: what the bounce adds is read against it.
  ss_radiosity: {strength: [0, 1, 4]},
  // extent null: no cutoff (the reference's unlimited range); half: the article's low resolution.
  analytic_ao: {extent: [16, null], resolution: ['full', 'half']},
  obscurance_map: [{backend: 'cpu', params: {method: ['rays', 'global_lines', 'bundles'], d_max: 300, patch_size: 50}},
                   {backend: 'vulkan', params: {method: 'depth_peeling', d_max: 300, patch_size: 50}}],
  // clamp_distance 19.2: 0.02 of the box's diagonal, the size default; exact runs on the CPU only.
  instant_radiosity: [{backend: 'cpu', params: {vpls: [128, 512, 2048], visibility: ['none', 'approximate', 'exact'], clamp_distance: 19.2}},
                      {backend: 'vulkan', params: {vpls: [128, 512, 2048], visibility: ['none', 'approximate'], clamp_distance: 19.2}}],
};

// The quantities, by the kind of a technique's primary output, with the reference samples each
// comparison uses unless --reference-samples sets them all.
// The AO comparison also scores every candidate against one common reference (rt_ao, binary,
// cosine, the scene file's distance), the one scale on which techniques of different AO
// definitions may be ranked together.
const QUANTITIES = [
  {kind: 'scalar', title: 'Ambient occlusion', refSamples: 1024,
   common: {technique: 'rt_ao', params: {falloff: 'binary', weighting: 'cosine', max_distance: 200}}},
  {kind: 'rgb', title: 'RGB radiance', refSamples: 256},
  {kind: 'patch', title: 'Per-patch obscurances', refSamples: 1024},
];

function parseArgs(argv) {
  const o = {size: '320x240', repeats: 5, refSamples: null, vulkan: true, screenshot: true,
             out: path.join(ROOT, 'docs'), obscurad: path.join(ROOT, 'build/obscurad'),
             chromium: '/usr/bin/chromium'};
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i], v = () => argv[++i];
    if (a === '--size') o.size = v();
    else if (a === '--repeats') o.repeats = Number(v());
    else if (a === '--reference-samples') o.refSamples = Number(v());
    else if (a === '--no-vulkan') o.vulkan = false;
    else if (a === '--no-screenshot') o.screenshot = false;
    else if (a === '--out') o.out = path.resolve(v());
    else if (a === '--obscurad') o.obscurad = path.resolve(v());
    else if (a === '--chromium') o.chromium = v();
    else {
      console.error(`bench_comparison: unknown option ${a} (see the comment at the top of the file)`);
      process.exit(64);
    }
  }
  const m = /^(\d+)x(\d+)$/.exec(o.size);
  if (!m) throw new Error(`--size must be WxH (got ${o.size})`);
  o.width = Number(m[1]);
  o.height = Number(m[2]);
  return o;
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function startDaemon(o, dir) {
  const argv = ['--listen', '127.0.0.1', '--port', '0', '--db', path.join(dir, 'obscura.db'),
                '--data-dir', path.join(dir, 'data'), '--scenes-dir', path.join(ROOT, 'scenes'),
                '--web-dir', path.join(ROOT, 'web'), '--workers', '1', '--quiet'];
  // The dashboard's chart library comes from npm (node_modules/uplot), served by --vendor-dir.
  const help = spawnSync(o.obscurad, ['--help'], {encoding: 'utf8'});
  if (`${help.stdout}${help.stderr}`.includes('--vendor-dir')) argv.push('--vendor-dir', path.join(ROOT, 'node_modules'));
  if (!o.vulkan) argv.push('--no-vulkan');
  const proc = spawn(o.obscurad, argv, {stdio: ['ignore', 'pipe', 'pipe']});
  let log = '';
  proc.stdout.on('data', (b) => (log += b));
  proc.stderr.on('data', (b) => (log += b));
  for (let t = 0; t < 3000; t++) {
    const m = log.match(/listening on http:\/\/127\.0\.0\.1:(\d+)/);
    if (m) return {proc, url: `http://127.0.0.1:${m[1]}`, log: () => log};
    if (proc.exitCode !== null) throw new Error(`obscurad exited:\n${log}`);
    await sleep(10);
  }
  proc.kill('SIGKILL');
  throw new Error(`obscurad did not start:\n${log}`);
}

async function api(d, method, p, body) {
  const r = await fetch(d.url + p, {method, headers: {'content-type': 'application/json'},
                                    body: body === undefined ? undefined : JSON.stringify(body)});
  const text = await r.text();
  if (!r.ok) throw new Error(`${method} ${p}: ${r.status} ${text}`);
  return p.endsWith('.csv') ? text : JSON.parse(text);
}

function machineFacts() {
  const cpu = (fs.readFileSync('/proc/cpuinfo', 'utf8').match(/^model name\s*:\s*(.*)$/m) || [])[1];
  return {cpu: cpu || os.arch(), cores: os.cpus().length, kernel: os.release()};
}

const fmt = (x, d = 3) => (x === null || x === undefined || !Number.isFinite(x) ? '-' : x.toFixed(d));
// The parameters a grid varies (those given as lists), as text.
function paramText(t, p) {
  const entries = [GRIDS[t] || {}].flat().map((e) => (e.params ? e.params : e));
  const varied = new Set(entries.flatMap((e) => Object.entries(e).filter(([, v]) => Array.isArray(v)).map(([k]) => k)));
  return Object.entries(p).filter(([k]) => varied.has(k)).map(([k, v]) => `${k} ${v}`).join(', ');
}

async function screenshot(o, d, id, file) {
  let chromium;
  try {
    ({chromium} = require('playwright-core'));
  } catch {
    console.error('bench_comparison: playwright-core is not installed (npm ci): no screenshot');
    return false;
  }
  const browser = await chromium.launch({
    executablePath: o.chromium, headless: true,
    args: ['--no-sandbox', '--disable-background-networking', '--disable-component-update',
           '--no-first-run', '--disable-sync', '--proxy-server=direct://',
           '--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1']});
  try {
    const page = await browser.newPage({viewport: {width: 1280, height: 900}});
    await page.goto(`${d.url}/#/comparisons/${id}`);
    const chart = page.locator('.uplot').first();
    await chart.waitFor({state: 'visible', timeout: 30000});
    await sleep(500);
    // The chart with its legend: the nearest section around the uPlot element.
    const box = page.locator('section:has(.uplot)').first();
    await ((await box.count()) ? box : chart).screenshot({path: file});
    return true;
  } finally {
    await browser.close();
  }
}

const SLUG = {scalar: 'ao', rgb: 'rgb', patch: 'patch'};

// The backend with the device its time came from, the server's label (a Vulkan time measured on
// a software rasteriser is a CPU time, and the label says so).
const deviceText = (x) => (x.device && x.device.label ? x.device.label : x.backend);

// The candidate entries of technique t: its grid's (one entry or several), on the backends this
// server runs.
function entriesOf(t, health) {
  const backends = t.backends.filter((b) => b !== 'vulkan' || health.vulkan_available);
  const grid = GRIDS[t.name];
  if (Array.isArray(grid)) {
    return grid.filter((e) => backends.includes(e.backend))
      .map((e) => ({technique: t.name, backend: e.backend, params: e.params}));
  }
  return [{technique: t.name, backend: backends, params: grid || {}}];
}

// Runs one comparison to its end; returns it with its CSV and wall time.
async function runComparison(d, o, q, candidates) {
  const t0 = Date.now();
  const made = await api(d, 'POST', '/api/v1/comparisons', {
    scene_file: 'cornell_box.json', label: `${q.title} on the Cornell box`,
    set: {'/image/width': o.width, '/image/height': o.height}, repeats: o.repeats,
    reference: {samples: o.refSamples ?? q.refSamples}, candidates,
    ...(q.common ? {common_reference: {...q.common, samples: o.refSamples ?? q.refSamples}} : {})});
  console.error(`${q.title}: comparison ${made.id}, ${made.candidates} candidates, ${made.references} references`);
  let c;
  for (;;) {
    c = await api(d, 'GET', `/api/v1/comparisons/${made.id}`);
    const done = c.candidates.filter((x) => x.metrics || ['failed', 'cancelled'].includes(x.state)).length;
    process.stderr.write(`\r${done}/${c.candidates.length} candidates measured`);
    if (c.state !== 'running') break;
    await sleep(1000);
  }
  process.stderr.write('\n');
  return {c, csv: await api(d, 'GET', `/api/v1/comparisons/${made.id}.csv`), wallS: (Date.now() - t0) / 1e3};
}

async function main() {
  const o = parseArgs(process.argv.slice(2));
  if (!fs.existsSync(o.obscurad)) throw new Error(`no obscurad at ${o.obscurad} (build first)`);
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obscura-bench-cmp-'));
  const d = await startDaemon(o, dir);
  try {
    const health = await api(d, 'GET', '/api/v1/health');
    const {techniques} = await api(d, 'GET', '/api/v1/techniques');
    o.metrics = (await api(d, 'GET', '/api/v1/metrics')).metrics;
    const kindOf = (t) => (t.typed_outputs.find((x) => x.primary) || {}).kind;
    fs.mkdirSync(path.join(o.out, 'img'), {recursive: true});
    const sections = [];
    for (const q of QUANTITIES) {
      // The Cornell box has no volume or environment map: techniques needing one are not run.
      const ts = techniques.filter((t) => kindOf(t) === q.kind &&
                                          !t.needs.some((n) => ['volume', 'environment_map'].includes(n)));
      if (!ts.length) continue;
      const run = await runComparison(d, o, q, ts.flatMap((t) => entriesOf(t, health)));
      const slug = SLUG[q.kind];
      const shot = path.join(o.out, 'img', `comparison-cornell-${slug}.png`);
      run.haveShot = o.screenshot && (await screenshot(o, d, run.c.id, shot));
      fs.writeFileSync(path.join(o.out, `comparison-cornell-${slug}.csv`), run.csv);
      sections.push({q, slug, ...run});
    }
    const md = page(o, sections, health);
    fs.writeFileSync(path.join(o.out, 'comparison-cornell.md'), md);
    console.log(md);
  } finally {
    d.proc.kill('SIGTERM');
    await sleep(300);
    fs.rmSync(dir, {recursive: true, force: true});
  }
}

// One comparison's section: its table (by technique, backend, time), its references and chart.
function section(o, {q, slug, c, wallS, haveShot}) {
  const rows = [...c.candidates].sort((a, b) => a.technique.localeCompare(b.technique) ||
    a.backend.localeCompare(b.backend) || (a.timings_ms?.median?.total ?? 0) - (b.timings_ms?.median?.total ?? 0));
  const measure = c.candidates.find((x) => x.metrics && x.metrics.output)?.metrics.output;
  const lines = [`## ${q.title}`, ''];
  const refs = c.references.map((r) => `**${r.id}** ${r.label}${(r.roles || []).includes('common') ? ' (the common reference)' : ''}`);
  lines.push(`References (${c.references.length}, ${o.refSamples ?? q.refSamples} samples each; each candidate's ` +
             'Pareto mark is within its own reference\'s group, since errors against different references do ' +
             `not share a scale):`, '', ...refs.map((r) => `- ${r}`), '',
             `${c.note ? `Note: ${c.note.replace(/\.?$/, '.')} ` : ''}Error measure: RMSE of ${measure ? `${measure}${q.kind === 'rgb' ? ' luminance' : ''}` : 'AO'}` +
             `${q.kind === 'patch' ? ' (the image of the patches; per-patch RMSE in the CSV)' : ''}. ` +
             `The comparison took ${wallS.toFixed(0)} s of wall time.`, '');
  // The metric columns: the metric table's top-level figures the candidates have (GET
  // /api/v1/metrics), in its order, each to its digits; the reference's noise is information.
  const cols = o.metrics.filter((m) => !m.json_group && m.direction !== 'none' &&
                                       rows.some((x) => x.metrics && x.metrics[m.json_key] !== undefined));
  const common = c.common && c.common.reference;
  const commonHead = common ? ` RMSE vs ${common.id} | Pareto (${common.id}) |` : '';
  lines.push(`| technique | backend | parameters | reference | ms (median) | ${cols.map((m) => (m.unit ? `${m.label} ${m.unit}` : m.label)
    .replace(/\|/g, '\\|')).join(' | ')} | Pareto |${commonHead}`,
             `| --- | --- | --- | --- | ---: | ${cols.map(() => '---:').join(' | ')} | :---: |${common ? ' ---: | :---: |' : ''}`);
  for (const x of rows) {
    const mm = x.metrics || {};
    const acc = mm.at_reference_accuracy ? ' (at reference accuracy)' : '';
    const err = x.metrics ? '' : ` (${x.error || x.state})`;
    const cells = cols.map((m) => {
      const v = mm[m.json_key];
      const t = v === null || v === undefined || !Number.isFinite(v) ? '-' : Number(v.toPrecision(m.digits)).toString();
      return m.name === 'rmse' ? t + acc : t;
    });
    const cm = x.common && x.common.metrics;
    const commonCells = common ? ` ${cm ? fmt(cm.rmse, 4) : '-'} | ${x.common && x.common.pareto ? 'yes' : ''} |` : '';
    lines.push(`| ${x.technique} | ${deviceText(x)} | ${paramText(x.technique, x.params) || 'defaults'}${err} | ` +
               `${x.reference ? x.reference.id : '-'} | ` +
               `${fmt(x.timings_ms?.median?.total, 1)} | ${cells.join(' | ')} | ${x.pareto ? 'yes' : ''} |${commonCells}`);
  }
  lines.push('');
  if (haveShot) {
    lines.push(`The dashboard's Pareto chart of this comparison (time against RMSE, log axes; one colour and ` +
               'Pareto front per reference when the candidates have several, else per technique; CPU and Vulkan ' +
               'told apart by marker shape):', '',
               `![Pareto chart: ${q.title}](img/comparison-cornell-${slug}.png)`, '');
  }
  lines.push(`The same table as CSV: [\`comparison-cornell-${slug}.csv\`](comparison-cornell-${slug}.csv).`, '');
  return lines;
}

function page(o, sections, health) {
  const m = machineFacts();
  const vk = sections.flatMap((x) => x.c.candidates).find((x) => x.machine && x.machine.vulkan_device);
  const lines = [];
  lines.push('# Measured comparisons: every technique on the Cornell box', '');
  lines.push('Produced by `node bench/bench_comparison.mjs` (see the top of that file); do not edit by hand.',
             'What the columns mean: [`comparisons.md`](comparisons.md) and [`metrics.md`](metrics.md). One ' +
             'comparison per quantity the techniques estimate, each against its own reference: errors of ' +
             'different quantities do not share a scale.', '');
  lines.push(`**Machine**: ${m.cpu}, ${m.cores} cores, Linux ${m.kernel}; Vulkan device: ` +
             `${vk ? vk.machine.vulkan_device : health.vulkan_available ? 'available' : 'none (CPU only)'}. ` +
             `One CPU worker (renders use every core), the Vulkan lane beside it; Release build.`, '');
  lines.push(`**Setup**: \`scenes/cornell_box.json\` at ${o.width}x${o.height}, spp 1; each candidate ` +
             `renders once to warm up, then ${o.repeats} timed times (median shown).`, '');
  for (const x of sections) lines.push(...section(o, x));
  return lines.join('\n');
}

main().catch((e) => {
  console.error(e.stack || String(e));
  process.exit(1);
});
