// The viewer's error maps of an image A against a reference B: per-pixel signed, absolute,
// relative and squared error computed here from the two decoded EXRs (FLIP comes from the server,
// which runs the C implementation the metrics use), the colour ramps they are shown through, the
// ramp's legend with its scale and the histogram of the error over the covered pixels.

/** A DOM element (no import of api.js: the pure functions here load in node for the tests). */
function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'className') e.className = v;
    else e.setAttribute(k, v);
  }
  e.append(...children);
  return e;
}

/** ε of the relative error |A − B| / (|B| + ε): keeps black reference pixels from dividing by 0. */
export const RELATIVE_EPS = 0.01;
export const HIST_BINS = 64;

// Per channel: the error of value a against reference b.
const PER_CHANNEL = {
  signed: (a, b) => a - b,
  absolute: (a, b) => Math.abs(a - b),
  relative: (a, b) => Math.abs(a - b) / (Math.abs(b) + RELATIVE_EPS),
  squared: (a, b) => (a - b) * (a - b),
};

/** The modes of the View → Error select: what each shows, and its ramp. */
export const ERROR_MODES = {
  signed: {label: 'signed error A − B', ramp: 'coolwarm'},
  absolute: {label: 'absolute error |A − B|', ramp: 'viridis'},
  relative: {label: `relative error |A − B| / (|B| + ${RELATIVE_EPS})`, ramp: 'viridis'},
  squared: {label: 'squared error (A − B)²', ramp: 'viridis'},
  flip: {label: 'FLIP (LDR; HDR for radiance)', ramp: 'magma'},
};

// Ramps as evenly spaced stops (matplotlib's viridis and magma, Moreland's cool-warm).
const RAMPS = {
  viridis: [[0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530], [0.207, 0.372, 0.553],
    [0.164, 0.471, 0.558], [0.128, 0.567, 0.551], [0.135, 0.659, 0.518], [0.267, 0.749, 0.441],
    [0.478, 0.821, 0.318], [0.741, 0.873, 0.150], [0.993, 0.906, 0.144]],
  magma: [[0.001, 0.000, 0.014], [0.078, 0.054, 0.212], [0.232, 0.060, 0.438], [0.390, 0.100, 0.502],
    [0.550, 0.161, 0.506], [0.716, 0.215, 0.475], [0.868, 0.288, 0.409], [0.967, 0.439, 0.360],
    [0.994, 0.624, 0.427], [0.997, 0.800, 0.535], [0.987, 0.991, 0.750]],
  coolwarm: [[0.230, 0.299, 0.754], [0.552, 0.690, 0.996], [0.865, 0.865, 0.865], [0.958, 0.603, 0.482],
    [0.706, 0.016, 0.150]],
};
const UNCOVERED = [40, 40, 40];

/** The ramp's colour at t in [0, 1] as bytes (linear between stops). */
export function rampColour(name, t) {
  const s = RAMPS[name], u = Math.min(1, Math.max(0, t)) * (s.length - 1);
  const k = Math.min(s.length - 2, Math.floor(u)), f = u - k;
  return [0, 1, 2].map((j) => Math.round(255 * (s[k][j] + (s[k + 1][j] - s[k][j]) * f)));
}

const plane = (img, name) => (img.channels.find((c) => c.name === name) || {}).data;

/**
 * The covered pixels: the reference's alpha > 0 (else A's, else every pixel). 1 = covered.
 */
export function coveredMask(a, b) {
  const n = a.width * a.height, alpha = plane(b, 'alpha') || plane(a, 'alpha');
  const m = new Uint8Array(n);
  for (let i = 0; i < n; i++) m[i] = !alpha || alpha[i] > 0 ? 1 : 0;
  return m;
}

/**
 * The per-pixel error of A against reference B over `channels` (the output's channels, present in
 * both): the mean over those channels of the mode's per-channel error. Returns {data, covered}:
 * a pixel is covered when coveredMask says so and its error is finite.
 */
export function errorMap(a, b, channels, mode) {
  const f = PER_CHANNEL[mode], n = a.width * a.height;
  const pa = channels.map((c) => plane(a, c)), pb = channels.map((c) => plane(b, c));
  const data = new Float32Array(n), covered = coveredMask(a, b);
  for (let i = 0; i < n; i++) {
    let s = 0;
    for (let k = 0; k < channels.length; k++) s += f(pa[k][i], pb[k][i]);
    data[i] = s / channels.length;
    if (!Number.isFinite(data[i])) covered[i] = 0;
  }
  return {data, covered};
}

/** A server-made map (FLIP's channel "flip") with the covered pixels of A and B. */
export function mapFromChannel(img, name, a, b) {
  const data = Float32Array.from(plane(img, name)), covered = coveredMask(a, b);
  for (let i = 0; i < data.length; i++) if (!Number.isFinite(data[i])) covered[i] = 0;
  return {data, covered};
}

/**
 * The ramp's range: signed [−s, s] with s the largest |error| covered, FLIP [0, 1], the others
 * [0, largest covered]; `max` (> 0) replaces the automatic end.
 */
export function rampRange(map, mode, max) {
  if (mode === 'flip') return [0, max > 0 ? max : 1];
  let hi = 0;
  for (let i = 0; i < map.data.length; i++) if (map.covered[i]) hi = Math.max(hi, mode === 'signed' ? Math.abs(map.data[i]) : map.data[i]);
  if (max > 0) hi = max;
  if (!(hi > 0)) hi = 1; // identical images: any scale shows them as zero
  return mode === 'signed' ? [-hi, hi] : [0, hi];
}

/** Counts of the covered errors in HIST_BINS equal bins over [lo, hi]; outside values go to the end bins. */
export function histogram(map, lo, hi) {
  const counts = new Array(HIST_BINS).fill(0);
  let total = 0;
  for (let i = 0; i < map.data.length; i++) {
    if (!map.covered[i]) continue;
    const k = Math.floor(((map.data[i] - lo) / (hi - lo)) * HIST_BINS);
    counts[Math.min(HIST_BINS - 1, Math.max(0, k))]++;
    total++;
  }
  return {lo, hi, counts, total};
}

/** RGBA bytes of the map through the mode's ramp over [lo, hi]; uncovered pixels dark grey. */
export function errorBytes(map, mode, lo, hi, width, height) {
  const ramp = ERROR_MODES[mode].ramp, out = new Uint8ClampedArray(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const c = map.covered[i] ? rampColour(ramp, (map.data[i] - lo) / (hi - lo)) : UNCOVERED;
    out.set(c, 4 * i);
    out[4 * i + 3] = 255;
  }
  return new ImageData(out, width, height);
}

const tick = (v) => (v === 0 ? '0' : Math.abs(v) >= 1e4 || Math.abs(v) < 1e-3 ? v.toExponential(2) : String(Number(v.toPrecision(3))));

/** The legend: the ramp as a bar with its scale (both ends and the middle) and what it shows. */
export function legend(mode, lo, hi) {
  const bar = el('canvas', {className: 'ramp', width: 256, height: 1, 'aria-hidden': 'true'});
  const g = bar.getContext('2d'), row = g.createImageData(256, 1);
  for (let x = 0; x < 256; x++) {
    row.data.set(rampColour(ERROR_MODES[mode].ramp, x / 255), 4 * x);
    row.data[4 * x + 3] = 255;
  }
  g.putImageData(row, 0, 0);
  const ticks = [lo, (lo + hi) / 2, hi].map(tick);
  return el('figure', {className: 'legend', 'aria-label': `Colour ramp of the ${ERROR_MODES[mode].label}: ${ticks[0]} to ${ticks[2]}`},
    bar, el('div', {className: 'ticks'}, ...ticks.map((t) => el('span', {}, t))),
    el('figcaption', {}, `${ERROR_MODES[mode].label}; uncovered pixels dark grey`));
}

/** The histogram as bars on a canvas (counts on a square-root axis, so small bins still show). */
export function histogramFigure(h, mode) {
  const c = el('canvas', {className: 'histogram', width: 256, height: 64, role: 'img'});
  const g = c.getContext('2d'), top = Math.sqrt(Math.max(1, ...h.counts)), w = 256 / HIST_BINS;
  g.fillStyle = '#202226';
  g.fillRect(0, 0, 256, 64);
  h.counts.forEach((n, k) => {
    const bh = Math.round((Math.sqrt(n) / top) * 62);
    g.fillStyle = `rgb(${rampColour(ERROR_MODES[mode].ramp, (k + 0.5) / HIST_BINS).join(',')})`;
    g.fillRect(k * w, 64 - bh, w - 0.5, bh);
  });
  const peak = h.counts.indexOf(Math.max(...h.counts));
  const at = (k) => tick(h.lo + ((h.hi - h.lo) * k) / HIST_BINS);
  c.setAttribute('aria-label', `Histogram of the ${ERROR_MODES[mode].label} over ${h.total} covered pixels, ${HIST_BINS} bins ` +
    `from ${tick(h.lo)} to ${tick(h.hi)}; the fullest bin, ${at(peak)} to ${at(peak + 1)}, holds ${h.counts[peak]}`);
  return el('figure', {className: 'histogram'}, c,
    el('figcaption', {}, `${h.total} covered pixels in ${HIST_BINS} bins, ${tick(h.lo)} to ${tick(h.hi)} (bar height: √count)`));
}
