// The comparison's Pareto chart on uPlot (npm `uplot`, served at /vendor/uplot/): median time
// against RMSE (of AO, or of an RGB output's luminance), both log scales, one series per technique
// (colour), the backend as the point's shape, the Pareto front as a step line and the selected
// candidate as a ring. uPlot draws axes, grid, legend and cursor; drawn here: each point's marker
// path (uPlot fills and strokes it with the series' colours, its `paths` hook), and in its `draw`
// hook the run-to-run spread of each point's time (a horizontal bar from the fastest to the
// slowest timed run) and the reference's noise floor. Each point also gets a button over the
// plot, so the keyboard reaches the points and a screen reader hears which candidate it is; the
// pointer gets the candidate's name in a tooltip.

// Okabe-Ito: distinguishable with the common colour-vision deficiencies.
export const PALETTE = ['#0072B2', '#D55E00', '#009E73', '#CC79A7', '#E69F00', '#56B4E9', '#000000', '#F0E442'];

/** Backend -> marker shape; anything unknown gets a triangle, and a legend entry says so. */
export const SHAPES = {cpu: 'circle', vulkan: 'square'};
export const SHAPE_GLYPH = {circle: '●', square: '■', triangle: '▲'};
export const shapeOf = (backend) => SHAPES[backend] || 'triangle';

function addShape(path, shape, x, y, r) {
  if (shape === 'circle') {
    path.moveTo(x + r, y);
    path.arc(x, y, r, 0, 2 * Math.PI);
  } else if (shape === 'square') {
    const s = r * 0.9;
    path.rect(x - s, y - s, 2 * s, 2 * s);
  } else {
    path.moveTo(x, y - r * 1.2);
    path.lineTo(x + r * 1.1, y + r * 0.8);
    path.lineTo(x - r * 1.1, y + r * 0.8);
    path.closePath();
  }
}

// Log-scale range: the data's extent widened by a factor of 1.5 each way (4 for a single value).
// Ticks of a log axis: at least four (two ticks cannot be read as a scale). The powers of ten in
// [min, max] when they are four or more, else with their 2 and 5 multiples, then 3 too, then every
// multiple; within a factor of about two, evenly spaced round values. uPlot's own log splits step
// from the scale's minimum in increments of its decade and never end on a degenerate scale (a
// minimum of 0 or a non-finite end), which throws "Invalid array length" from inside the chart.
const MIN_TICKS = 4;
function logSplits(u, axis, min, max) {
  if (!(min > 0) || !(max >= min) || !Number.isFinite(max)) return [];
  const k0 = Math.floor(Math.log10(min)), k1 = Math.ceil(Math.log10(max));
  let out = [];
  for (const mults of [[1], [1, 2, 5], [1, 2, 3, 5], [1, 2, 3, 4, 5, 6, 7, 8, 9]]) {
    out = [];
    for (let k = k0; k <= k1 && out.length < 64; k++) {
      for (const m of mults) {
        const v = Number((m * 10 ** k).toPrecision(12));
        if (v >= min && v <= max) out.push(v);
      }
    }
    if (out.length >= MIN_TICKS) return out;
  }
  // The largest step of 1, 2 or 5 times a power of ten that gives MIN_TICKS values or more.
  const raw = (max - min) / MIN_TICKS;
  if (!(raw > 0)) return out;
  const p = 10 ** Math.floor(Math.log10(raw));
  const step = [5, 2, 1].map((m) => m * p).find((x) => x <= raw) || p;
  const lin = [];
  for (let v = Math.ceil(min / step) * step; v <= max && lin.length < 64; v += step) lin.push(Number(v.toPrecision(12)));
  return lin.length > out.length ? lin : out;
}

// A tick's label: plain below 1e5 and from 1e-3 (uPlot's default rounds to three decimals, so
// 0.0002 would read 0), else as a power of ten. Every split logSplits chose is labelled (uPlot's
// own log filter would blank all but the 1-2-5 ones, leaving two labels).
const tickLabels = (u, splits) => splits.map((v) => (v === null ? null : v >= 1e-3 && v < 1e5 ? String(Number(v.toPrecision(6)))
  : v.toExponential().replace(/\.?0+e/, 'e').replace('e+', 'e')));
const keepSplits = (u, splits) => splits;

// A log axis' range over the positive finite values among `vals` (uPlot passes null for a scale
// it has no data for yet, and Math.min would turn that into 0, whose log breaks the axis).
function logPad(vals) {
  const ok = vals.filter((v) => Number.isFinite(v) && v > 0);
  if (!ok.length) return [1e-3, 1];
  const min = Math.min(...ok), max = Math.max(...ok);
  return min === max ? [min / 4, max * 4] : [min / 1.5, max * 1.5];
}

/**
 * What the error axis measures for these candidates: RMSE of AO, or of the luminance of an RGB
 * output (path_trace's radiance) when the metrics name one; both when a comparison mixes them.
 */
export function errorName(cands) {
  const ms = cands.filter((c) => c.metrics).map((c) => c.metrics);
  const rgb = [...new Set(ms.filter((m) => m.output && m.rgb).map((m) => m.output))].sort();
  const other = [...new Set(ms.filter((m) => !(m.output && m.rgb)).map((m) => m.output || 'AO'))].sort();
  // RGB outputs of several names (obscurance's final against path_trace's radiance) are all
  // compared by their luminance: one measure.
  if (!other.length && rgb.length > 1) return `RMSE of luminance (${rgb.join(', ')})`;
  const names = [...other, ...rgb.map((r) => `${r} luminance`)];
  if (names.length === 1) return `RMSE of ${names[0]}`;
  return names.length ? `RMSE (${names.sort().join('; ')})` : 'RMSE';
}

/** Whether a candidate has a finite median time and a finite RMSE (the API sends null otherwise). */
export const plottable = (c) => Boolean(c.metrics && Number.isFinite(c.metrics.rmse) && c.timings_ms &&
  c.timings_ms.median && Number.isFinite(c.timings_ms.median.total));

/** The run-to-run spread of a candidate's total time: [fastest, slowest] run, or null. */
export function spreadOf(c) {
  const t = c.timings_ms || {};
  const lo = t.min && t.min.total, hi = t.max && t.max.total;
  return Number.isFinite(lo) && Number.isFinite(hi) ? [lo, hi] : null;
}

// The default name of a candidate (the page passes one with its varying parameters).
const defaultName = (c) => `Candidate ${c.index}: ${c.technique} on ${c.backend}`;

/**
 * Draws the chart into `box`. cands: candidates of the comparison JSON; colourOf(technique);
 * onSelect(candidateIndex); nameOf(candidate): how the tooltip and the point's button name it;
 * noise: the reference's noise (RMSE units) drawn as the noise floor, or null. Returns
 * {select(index), focus(index), destroy(), info} or null when there is nothing to plot. info:
 * {points, series: [{label, points}], pareto, order, noiseFloor, spreads} (also what the tests
 * read).
 */
// uPlot `paths` builders: one Path2D holding a shape at every non-null point of the series, in
// canvas pixels; `filled` says whether uPlot should fill it as well as stroke it.
const pathOf = (shape, filled) => (u, si) => {
  const ys = u.data[si];
  const path = new Path2D();
  for (let i = 0; i < ys.length; i++) {
    if (ys[i] !== null) shape(path, i, u.valToPos(u.data[0][i], 'x', true), u.valToPos(ys[i], 'y', true));
  }
  return {stroke: path, fill: filled ? path : null, clip: null, band: null, gaps: null, flags: 0};
};

const valueText = (u, v) => (v === null ? '–' : v.toPrecision(3));

// The series and data: one series per technique (markers shaped by backend), the Pareto front as
// a step line, and the ring around the selected point (last; `ringData` recomputes its data).
function chartSeries(uPlot, pts, techs, colourOf, ratio, ringData) {
  const markers = pathOf((path, i, cx, cy) => addShape(path, shapeOf(pts[i].c.backend), cx, cy, (pts[i].c.pareto ? 6 : 4.5) * ratio), true);
  const ring = pathOf((path, i, cx, cy) => {
    path.moveTo(cx + 10 * ratio, cy);
    path.arc(cx, cy, 10 * ratio, 0, 2 * Math.PI);
  }, false);
  const series = [{label: 'median time (ms)'}];
  const data = [pts.map((p) => p.x)];
  for (const t of techs) {
    const colour = colourOf(t);
    series.push({label: t, stroke: colour, fill: `${colour}66`, width: 1.5, paths: markers,
                 points: {show: false}, value: valueText});
    data.push(pts.map((p) => (p.c.technique === t ? p.y : null)));
  }
  series.push({label: 'Pareto front', stroke: '#333', width: 1.5, dash: [6, 4], spanGaps: true,
               paths: uPlot.paths.stepped({align: 1}), points: {show: false}, value: valueText});
  data.push(pts.map((p) => (p.c.pareto ? p.y : null)));
  // The ring takes no legend row: it is no data series of its own (the page's list explains it).
  series.push({label: 'selected', stroke: '#000', width: 2.5, paths: ring, points: {show: false}, value: valueText});
  data.push(ringData());
  return {series, data};
}

// The reference's noise floor (a dotted line, shaded below twice it: "at reference accuracy").
function drawNoise(u, floor, ratio) {
  const ctx = u.ctx, {left, top, width: w, height: h} = u.bbox;
  const y = u.valToPos(floor, 'y', true), y2 = u.valToPos(2 * floor, 'y', true);
  ctx.fillStyle = 'rgba(120, 120, 120, 0.12)';
  ctx.fillRect(left, Math.max(top, y2), w, top + h - Math.max(top, y2));
  ctx.strokeStyle = '#777';
  ctx.lineWidth = 1.5 * ratio;
  ctx.setLineDash([2 * ratio, 3 * ratio]);
  ctx.beginPath();
  ctx.moveTo(left, y);
  ctx.lineTo(left + w, y);
  ctx.stroke();
  ctx.setLineDash([]);
  ctx.fillStyle = '#555';
  ctx.font = `${11 * ratio}px sans-serif`;
  ctx.fillText('reference noise', left + 4 * ratio, y - 4 * ratio);
  return y / ratio;
}

// Spreads and the noise floor, on the canvas under uPlot's series (its `drawClear` hook runs
// before the series are drawn, after the axes and grid). `drawn` records what was drawn.
function decorate(u, pts, floor, colourOf, ratio, drawn) {
  const ctx = u.ctx, {left, top, width: w, height: h} = u.bbox;
  ctx.save();
  ctx.beginPath();
  ctx.rect(left, top, w, h);
  ctx.clip();
  drawn.noiseY = floor ? drawNoise(u, floor, ratio) : null;
  drawn.spreads = 0;
  ctx.lineWidth = 1.5 * ratio;
  for (const p of pts) {
    if (!p.spread) continue;
    const y = u.valToPos(p.y, 'y', true), x0 = u.valToPos(p.spread[0], 'x', true), x1 = u.valToPos(p.spread[1], 'x', true);
    const cap = 4 * ratio;
    ctx.strokeStyle = colourOf(p.c.technique);
    ctx.beginPath();
    ctx.moveTo(x0, y);
    ctx.lineTo(x1, y);
    ctx.moveTo(x0, y - cap);
    ctx.lineTo(x0, y + cap);
    ctx.moveTo(x1, y - cap);
    ctx.lineTo(x1, y + cap);
    ctx.stroke();
    drawn.spreads++;
  }
  ctx.restore();
}

// One button per point over the plot, named for screen readers; a click selects, focus and hover
// show the tooltip (`tip.show`).
function pointButtons(pts, nameOf, onSelect, tip) {
  return pts.map((p) => {
    const b = document.createElement('button');
    b.type = 'button';
    b.className = 'pt';
    b.tabIndex = -1;
    b.dataset.index = String(p.c.index);
    const sp = p.spread ? `, runs ${p.spread[0].toPrecision(3)} to ${p.spread[1].toPrecision(3)} ms` : '';
    b.setAttribute('aria-label', `${nameOf(p.c)}: median ${p.c.timings_ms.median.total.toPrecision(3)} ms${sp}, ` +
      `RMSE ${p.c.metrics.rmse.toPrecision(3)}${p.c.pareto ? ', Pareto-optimal' : ''}`);
    b.addEventListener('click', (ev) => {
      ev.stopPropagation();
      onSelect(p.c.index);
    });
    b.addEventListener('focus', () => tip.show(p));
    b.addEventListener('mouseenter', () => tip.show(p));
    b.addEventListener('blur', () => tip.show(null));
    return b;
  });
}

// The hover tooltip naming a point; `plot()` gives the uPlot instance (made after the tooltip).
function chartTip(nameOf, plot) {
  const el = document.createElement('div');
  el.className = 'chart-tip';
  el.setAttribute('aria-hidden', 'true'); // the buttons' names say the same to a screen reader
  el.hidden = true;
  const tip = {el, of: null};
  tip.show = (p) => {
    tip.of = p;
    el.hidden = !p;
    if (!p) return;
    const u = plot();
    el.textContent = nameOf(p.c);
    const x = u.valToPos(p.x, 'x'), y = u.valToPos(p.y, 'y');
    el.style.left = `${x}px`;
    el.style.top = `${y}px`;
    // Near the right edge the tooltip opens to the left of the point.
    el.classList.toggle('left', x > u.over.clientWidth / 2);
  };
  return tip;
}

// The nearest point to (left, top) on screen within 20 px, or null.
function nearestPoint(u, pts, left, top) {
  let best = null, bestD = 20 * 20;
  for (const p of pts) {
    const dx = u.valToPos(p.x, 'x') - left, dy = u.valToPos(p.y, 'y') - top;
    if (dx * dx + dy * dy < bestD) { bestD = dx * dx + dy * dy; best = p; }
  }
  return best;
}

// The chart's points: log axes, so a zero time or RMSE (a candidate identical to its reference)
// is drawn at a floor; a missing (null: not finite) one is not drawn at all, never at the floor.
function chartPoints(cands) {
  return cands.filter(plottable)
    .map((c) => ({c, x: Math.max(c.timings_ms.median.total, 1e-3), y: Math.max(c.metrics.rmse, 1e-6),
                  spread: spreadOf(c) && spreadOf(c).map((v) => Math.max(v, 1e-3))}))
    .sort((a, b) => a.x - b.x || a.c.index - b.c.index);
}

export function paretoChart(box, cands, {colourOf, onSelect, selected = null, nameOf = defaultName, noise = null}) {
  const uPlot = window.uPlot;
  if (!uPlot) {
    box.append('The chart library is missing (run npm ci; the daemon serves it from --vendor-dir).');
    return null;
  }
  const pts = chartPoints(cands);
  if (!pts.length) return null;
  const floor = Number.isFinite(noise) && noise > 0 ? noise : null;
  // The scales take in the spreads' ends and the noise floor, so neither is cut off.
  const xExt = pts.flatMap((p) => (p.spread ? p.spread : [p.x]));
  const xRange = (uu, min, max) => logPad([min, max, ...xExt]);
  const yRange = (uu, min, max) => logPad(floor ? [min, max, floor] : [min, max]);
  const techs = [...new Set(pts.map((p) => p.c.technique))];
  const ratio = window.devicePixelRatio || 1;
  let sel = selected;
  const selData = () => pts.map((p) => (p.c.index === sel ? p.y : null));
  const {series, data} = chartSeries(uPlot, pts, techs, colourOf, ratio, selData);
  const drawn = {spreads: 0, noiseY: null};
  let u = null;
  const tip = chartTip(nameOf, () => u);
  // A roving tab stop (the selected point, else the fastest); arrow keys move between points in
  // time order (the page's handler), Enter or a click selects.
  const buttons = pointButtons(pts, nameOf, onSelect, tip);
  const placeButtons = (uu) => {
    pts.forEach((p, i) => {
      buttons[i].style.left = `${uu.valToPos(p.x, 'x')}px`;
      buttons[i].style.top = `${uu.valToPos(p.y, 'y')}px`;
    });
    if (tip.of) tip.show(tip.of);
  };
  const roving = () => {
    const k = Math.max(0, pts.findIndex((p) => p.c.index === sel));
    buttons.forEach((b, i) => { b.tabIndex = i === k ? 0 : -1; });
  };

  // Short enough for the axis' height: "RMSE of radiance luminance (log scale)".
  const yLabel = `${errorName(pts.map((p) => p.c))} (log scale)`;
  const width = Math.max(320, Math.min(box.clientWidth || 720, 960));
  u = new uPlot({
    width, height: 340,
    // Padded by a factor on both sides so no marker sits on (and is clipped by) the plot's edge.
    scales: {x: {time: false, distr: 3, log: 10, range: xRange}, y: {distr: 3, log: 10, range: yRange}},
    axes: [{label: 'median total time per run (ms, log scale; bars: fastest to slowest run)', splits: logSplits, values: tickLabels, filter: keepSplits},
           {label: yLabel, size: 70, splits: logSplits, values: tickLabels, filter: keepSplits}],
    series,
    cursor: {drag: {x: false, y: false}},
    // Not live: a live legend is a row of "–" values until the cursor sits exactly on a point's
    // time (one series at a time has a value there); the tooltip names the point instead.
    legend: {live: false},
    hooks: {
      drawClear: [(uu) => decorate(uu, pts, floor, colourOf, ratio, drawn)],
      draw: [placeButtons],
      setCursor: [(uu) => {
        const {left, top} = uu.cursor;
        if (document.activeElement && buttons.includes(document.activeElement)) return;
        tip.show(left === undefined || left < 0 ? null : nearestPoint(uu, pts, left, top));
      }],
    },
  }, data, box);
  // The ring series gets no legend entry (uPlot has no per-series switch; its CSS would override
  // a `hidden` attribute, so the style hides it). The page's list explains the ring.
  for (const row of u.root.querySelectorAll('.u-legend .u-series')) {
    if (row.querySelector('.u-label') && row.querySelector('.u-label').textContent === 'selected') row.style.display = 'none';
  }
  u.over.append(...buttons, tip.el);
  roving();
  placeButtons(u);

  // A click picks the nearest point on screen (both axes), not just the nearest time.
  u.over.addEventListener('click', () => {
    const {left, top} = u.cursor;
    if (left === undefined || left < 0) return;
    const p = nearestPoint(u, pts, left, top);
    if (p) onSelect(p.c.index);
  });
  u.over.addEventListener('mouseleave', () => tip.show(null));

  const info = {points: pts.length, series: techs.map((t, k) => ({label: t, points: data[k + 1].filter((v) => v !== null).length})),
                pareto: data[techs.length + 1].filter((v) => v !== null).length, order: pts.map((p) => p.c.index), yLabel,
                noiseFloor: floor, drawn, spreads: pts.filter((p) => p.spread).map((p) => ({index: p.c.index, min: p.spread[0], max: p.spread[1]}))};
  return chartHandle(u, info, buttons, data, () => {
    roving();
    return selData();
  }, (index) => { sel = index; }, () => sel);
}

// What the page holds of a chart: select, step and focus points, resize, destroy.
function chartHandle(u, info, buttons, data, ringData, setSel, getSel) {
  return {
    info,
    uplot: u,
    /** Marks candidate `index` (or none) with the ring. */
    select(index) {
      setSel(index);
      data[data.length - 1] = ringData();
      // Same scales (the ring adds no new extent): keep them, and repaint.
      u.setData(data, false);
      u.redraw();
    },
    /** Next or previous point in time order from the selected one (keyboard on the chart). */
    step(dir) {
      const i = info.order.indexOf(getSel());
      const j = i < 0 ? 0 : Math.max(0, Math.min(info.order.length - 1, i + dir));
      return info.order[j];
    },
    /** Moves the keyboard to candidate `index`'s point. */
    focus(index) {
      const b = buttons.find((x) => Number(x.dataset.index) === index);
      if (b) b.focus();
    },
    /** Whether the keyboard is on one of the points. */
    hasFocus: () => buttons.includes(document.activeElement),
    resize(w) {
      const width = Math.max(320, Math.min(w, 960));
      if (width !== u.width) u.setSize({width, height: 340});
    },
    destroy: () => u.destroy(),
  };
}
