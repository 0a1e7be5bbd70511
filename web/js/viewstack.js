// The images of the viewer's stack: each entry one EXR of one job (its primary EXR, or a file it
// names: "<job>/<file>"), decoded, with the outputs its channels hold; a running job's entry shows
// the server's preview of the tiles rendered so far (GET /api/v1/jobs/{id}/preview.exr) and is
// refreshed until the job ends, when its final EXR replaces it.
import {api, token, techniques} from './api.js';
import {decodeExr} from './exr.js';

const SPEC = /^(\d+)(?:\/([\w.-]+\.exr))?$/;

/** {id, file} of "<job>" or "<job>/<file>.exr", or null. */
export function parseSpec(text) {
  const m = SPEC.exec(String(text || '').trim());
  return m ? {id: Number(m[1]), file: m[2] || null} : null;
}
/** The spec that loads `e` again: the file only when it was named (not the job's primary EXR). */
export const specOf = (e) => (e.given ? `${e.id}/${e.file}` : String(e.id));

/** The bytes at `url` with the API's credentials; 404 answers null when `missingOk`. */
export async function fetchBytes(url, missingOk = false) {
  const res = await fetch(url, {headers: token ? {Authorization: 'Bearer ' + token} : {}});
  if (missingOk && res.status === 404) return null;
  if (!res.ok) {
    let why = `HTTP ${res.status}`;
    try {
      why = (await res.json()).error || why;
    } catch {}
    throw new Error(`${url}: ${why}`);
  }
  return res.arrayBuffer();
}

/**
 * The outputs whose channels `img` has (the registry's typed_outputs); channels no output claims
 * become outputs of their own, so every channel can be looked at.
 */
function outputsOf(img, tech) {
  const have = new Set(img.channels.map((c) => c.name));
  const outputs = (tech.typed_outputs || []).filter((o) => o.channels && o.channels.length && o.channels.every((c) => have.has(c)));
  const claimed = new Set(outputs.flatMap((o) => o.channels));
  for (const c of img.channels) {
    if (!claimed.has(c.name)) outputs.push({name: c.name, kind: 'scalar', show: 'grey', channels: [c.name]});
  }
  return outputs;
}

function setImage(e, img) {
  e.img = img;
  e.outputs = img ? outputsOf(img, e.tech) : [];
  e.version = (e.version || 0) + 1;
}

/** Loads the finished job's EXR (the named file, else the technique's, else the first). */
async function loadFinal(e) {
  const exrs = (e.job.outputs || []).filter((o) => o.name.endsWith('.exr'));
  const file = e.given ? exrs.find((o) => o.name === e.file) : exrs.find((o) => o.name === e.tech.exr) || exrs[0];
  if (!file) throw new Error(e.given ? `job ${e.id} has no output ${e.file}` : `job ${e.id} has no EXR output`);
  e.file = file.name;
  const summaryUrl = e.job.links.outputs['summary.json'];
  const [img, summary] = await Promise.all([fetchBytes(file.url).then(decodeExr),
    summaryUrl ? api(summaryUrl).catch(() => null) : null]);
  e.summary = summary;
  e.compression = img.compression;
  e.live = false;
  setImage(e, img);
}

/** Loads the preview of the running (or queued) job: null image until its first tiles. */
async function loadPreview(e) {
  const buf = await fetchBytes(`/api/v1/jobs/${e.id}/preview.exr`, true);
  if (buf) {
    const img = await decodeExr(buf);
    e.compression = img.compression;
    setImage(e, img);
  }
}

/** One stack entry from its spec: {id, file, given, job, tech, img, outputs, summary, live}. */
export async function loadEntry(spec) {
  const s = typeof spec === 'string' ? parseSpec(spec) : spec;
  if (!s) throw new Error(`"${spec}" is not an image of the stack ("<job>" or "<job>/<file>.exr")`);
  const [job, reg] = await Promise.all([api(`/api/v1/jobs/${s.id}`), techniques().catch(() => ({techniques: []}))]);
  const e = {id: s.id, file: s.file, given: !!s.file, job, tech: reg.techniques.find((t) => t.name === job.technique) || {},
             img: null, outputs: [], summary: null, live: false};
  if (job.state === 'succeeded') await loadFinal(e);
  else if (job.state === 'running' || job.state === 'queued') {
    if (e.given) throw new Error(`job ${s.id} is ${job.state}: its file ${s.file} exists once it has finished`);
    e.live = true;
    await loadPreview(e);
  } else throw new Error(`job ${s.id} is ${job.state}: only a finished or running job has images`);
  return e;
}

/** Brings a live entry up to date: its preview again, or its final EXR once it succeeded. */
export async function refreshEntry(e) {
  const job = await api(`/api/v1/jobs/${e.id}`);
  e.job = job;
  if (job.state === 'succeeded') return loadFinal(e);
  if (job.state === 'running' || job.state === 'queued') return loadPreview(e);
  e.live = false;
  throw new Error(`job ${e.id} ended ${job.state}${job.error ? `: ${job.error}` : ''}`);
}

/** The entry's output for `name`: the same name when it has it, else its primary, else its first. */
export const outputFor = (e, name) => e.outputs.find((o) => o.name === name) || e.outputs.find((o) => o.primary) || e.outputs[0];
