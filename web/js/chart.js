// The comparison's Pareto chart on uPlot (npm `uplot`, served at /vendor/uplot/): median time
// against RMSE (of AO, or of an RGB output's luminance), both log scales, one series per technique (colour), the backend as the point's
// shape, the Pareto front as a step line and the selected candidate as a ring. uPlot draws axes,
// grid, legend and cursor; the only drawing here is each point's marker path, which uPlot fills and
// strokes with the series' colours (its `paths` hook).

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
function logPad(u, min, max) {
  return min === max ? [min / 4, max * 4] : [min / 1.5, max * 1.5];
}

/**
 * What the error axis measures for these candidates: RMSE of AO, or of the luminance of an RGB
 * output (path_trace's radiance) when the metrics name one; both when a comparison mixes them.
 */
export function errorName(cands) {
  const names = new Set(cands.filter((c) => c.metrics).map((c) => (c.metrics.output
    ? `${c.metrics.output}${c.metrics.rgb ? ' luminance' : ''}` : 'AO')));
  if (names.size === 1) return `RMSE of ${[...names][0]}`;
  return names.size ? `RMSE (${[...names].sort().join('; ')})` : 'RMSE';
}

/** Whether a candidate has a finite median time and a finite RMSE (the API sends null otherwise). */
export const plottable = (c) => Boolean(c.metrics && Number.isFinite(c.metrics.rmse) && c.timings_ms &&
  c.timings_ms.median && Number.isFinite(c.timings_ms.median.total));

/**
 * Draws the chart into `box`. cands: candidates of the comparison JSON; colourOf(technique);
 * onSelect(candidateIndex). Returns {select(index), destroy(), info} or null when there is nothing
 * to plot. info: {points, series: [{label, points}], pareto} (also what the tests read).
 */
export function paretoChart(box, cands, {colourOf, onSelect, selected = null}) {
  const uPlot = window.uPlot;
  if (!uPlot) {
    box.append('The chart library is missing (run npm ci; the daemon serves it from --vendor-dir).');
    return null;
  }
  // Log axes: a zero time or RMSE (a candidate identical to its reference) is drawn at a floor;
  // a missing (null: not finite) one is not drawn at all, never at the floor.
  const pts = cands.filter(plottable)
    .map((c) => ({c, x: Math.max(c.timings_ms.median.total, 1e-3), y: Math.max(c.metrics.rmse, 1e-6)}))
    .sort((a, b) => a.x - b.x || a.c.index - b.c.index);
  if (!pts.length) return null;
  const xs = pts.map((p) => p.x);
  const techs = [...new Set(pts.map((p) => p.c.technique))];
  const ratio = window.devicePixelRatio || 1;
  let sel = selected;

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
  const markers = pathOf((path, i, cx, cy) => addShape(path, shapeOf(pts[i].c.backend), cx, cy, (pts[i].c.pareto ? 6 : 4.5) * ratio), true);
  const ring = pathOf((path, i, cx, cy) => {
    path.moveTo(cx + 10 * ratio, cy);
    path.arc(cx, cy, 10 * ratio, 0, 2 * Math.PI);
  }, false);

  const series = [{label: 'median time (ms)'}];
  const data = [xs];
  for (const t of techs) {
    const colour = colourOf(t);
    series.push({label: t, stroke: colour, fill: `${colour}66`, width: 1.5, paths: markers,
                 points: {show: false}, value: (u, v) => (v === null ? '–' : v.toPrecision(3))});
    data.push(pts.map((p) => (p.c.technique === t ? p.y : null)));
  }
  series.push({label: 'Pareto front', stroke: '#333', width: 1.5, dash: [6, 4], spanGaps: true,
               paths: uPlot.paths.stepped({align: 1}), points: {show: false}, value: (u, v) => (v === null ? '–' : v.toPrecision(3))});
  data.push(pts.map((p) => (p.c.pareto ? p.y : null)));
  const selData = () => pts.map((p) => (p.c.index === sel ? p.y : null));
  series.push({label: 'selected', stroke: '#000', width: 2.5, paths: ring, points: {show: false},
               value: (u, v) => (v === null ? '–' : v.toPrecision(3))});
  data.push(selData());

  // Short enough for the axis' height: "RMSE of radiance luminance (log scale)".
  const yLabel = `${errorName(pts.map((p) => p.c))} (log scale)`;
  const width = Math.max(320, Math.min(box.clientWidth || 720, 960));
  const u = new uPlot({
    width, height: 340,
    // Padded by a factor on both sides so no marker sits on (and is clipped by) the plot's edge.
    scales: {x: {time: false, distr: 3, log: 10, range: logPad}, y: {distr: 3, log: 10, range: logPad}},
    axes: [{label: 'median total time per run (ms, log scale)'}, {label: yLabel, size: 70}],
    series,
    cursor: {drag: {x: false, y: false}},
    legend: {live: true},
  }, data, box);

  // A click picks the nearest point on screen (both axes), not just the nearest time.
  u.over.addEventListener('click', () => {
    const {left, top} = u.cursor;
    if (left === undefined || left < 0) return;
    let best = -1, bestD = 20 * 20;
    pts.forEach((p, i) => {
      const dx = u.valToPos(p.x, 'x') - left, dy = u.valToPos(p.y, 'y') - top;
      if (dx * dx + dy * dy < bestD) { bestD = dx * dx + dy * dy; best = i; }
    });
    if (best >= 0) onSelect(pts[best].c.index);
  });

  const info = {points: pts.length, series: techs.map((t, k) => ({label: t, points: data[k + 1].filter((v) => v !== null).length})),
                pareto: data[techs.length + 1].filter((v) => v !== null).length, order: pts.map((p) => p.c.index), yLabel};
  return {
    info,
    uplot: u,
    /** Marks candidate `index` (or none) with the ring. */
    select(index) {
      sel = index;
      data[data.length - 1] = selData();
      // Same scales (the ring adds no new extent): keep them, and repaint.
      u.setData(data, false);
      u.redraw();
    },
    /** Next or previous point in time order from the selected one (keyboard on the chart). */
    step(dir) {
      const i = info.order.indexOf(sel);
      const j = i < 0 ? 0 : Math.max(0, Math.min(info.order.length - 1, i + dir));
      return info.order[j];
    },
    resize(w) {
      const width = Math.max(320, Math.min(w, 960));
      if (width !== u.width) u.setSize({width, height: 340});
    },
    destroy: () => u.destroy(),
  };
}
