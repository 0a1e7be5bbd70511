// The image viewer's canvas: the display images of decoded EXR outputs (the same mapping the
// renderer's PNG writer uses, so exposure 0 shows final.png's bytes and AO shows ao.png's), and a
// zoomable, pannable view of one image or of two (A/B toggle, or a split wipe with a draggable
// divider), pixels nearest-neighbour when magnified.

const DEPTH_PNG_FAR = 0.1; // renderer/registry/render.c: the far end of depth.png's ramp
const VIRIDIS = [[0.267, 0.005, 0.329], [0.128, 0.567, 0.551], [0.993, 0.906, 0.144]];
export const ZOOM_MIN = 1 / 32, ZOOM_MAX = 128;

const srgb = (v) => (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055);
/** renderer/core/png.c's png_quantize: NaN is 0, clamp to [0, 1], optional sRGB, round half up. */
export function quantize(f, gamma) {
  if (Number.isNaN(f)) return 0;
  let v = f < 0 ? 0 : f > 1 ? 1 : f;
  if (gamma) v = srgb(v);
  return Math.min(255, Math.max(0, Math.floor(v * 255 + 0.5)));
}

let steps = null;
/** For q = 1..255 the smallest float32 that quantize(v, true) maps to q or above (it is monotonic). */
function srgbSteps() {
  if (steps) return steps;
  const f = new Float32Array(1), bits = new Uint32Array(f.buffer);
  steps = new Float32Array(256);
  steps[0] = -Infinity;
  for (let q = 1; q < 256; q++) {
    let lo = 0, hi = 0x3f800000; // the bits of 0 and of 1, whose byte is 255; positive floats sort as their bits
    while (lo < hi) {
      const mid = (lo + hi) >>> 1;
      bits[0] = mid;
      if (quantize(f[0], true) >= q) hi = mid;
      else lo = mid + 1;
    }
    bits[0] = lo;
    steps[q] = f[0];
  }
  return steps;
}

/** quantize(v, true) of a float32 by a search of the 255 steps: no pow per pixel, the same byte. */
export function toneByte(v) {
  const t = srgbSteps();
  if (!(v > 0)) return 0;
  let lo = 0, hi = 255;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (t[mid] <= v) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

/** The views an output offers: its PNG's mapping first (the registry's `show`), then the others. */
export function viewsOf(output) {
  switch (output.kind) {
    case 'rgb': return ['tonemap'];
    case 'vector': return ['normal'];
    case 'depth': return ['depth', 'false_colour'];
    default: return output.show === 'false_colour' ? ['false_colour', 'grey'] : ['grey', 'false_colour'];
  }
}

/** Lowest and highest value of the covered pixels (alpha > 0 and a finite first channel). */
function coveredRange(src, alpha, positiveOnly) {
  let lo = Infinity, hi = -Infinity;
  for (let i = 0; i < src.length; i++) {
    const v = src[i];
    if ((alpha && !(alpha[i] > 0)) || !Number.isFinite(v) || (positiveOnly && !(v > 0))) continue;
    if (v < lo) lo = v;
    if (v > hi) hi = v;
  }
  return [lo, hi];
}

/**
 * RGBA bytes of one output of a decoded image: `view` is one of viewsOf(output); `stops` the
 * exposure of the tone map. Mirrors renderer/registry/render.c's display_image and the PNG writer:
 * tone map = linear x 2^stops, clamped, sRGB curve; grey = the value clamped, linear; normal =
 * n x 0.5 + 0.5; depth = near white to far dark over the covered range; false colour = a ramp over
 * the covered range. Pixels without geometry are black except in the tone map and grey views.
 */
export function displayBytes(img, output, view, stops) {
  const n = img.width * img.height;
  const plane = (name) => (img.channels.find((c) => c.name === name) || {}).data;
  const src = output.channels.map(plane);
  const alpha = plane('alpha');
  const out = new Uint8ClampedArray(n * 4);
  const covered = (i) => (!alpha || alpha[i] > 0) && Number.isFinite(src[0][i]);
  for (let i = 0; i < n; i++) out[4 * i + 3] = 255;
  const put = (i, r, g, b) => {
    out[4 * i] = r;
    out[4 * i + 1] = g;
    out[4 * i + 2] = b;
  };
  // One channel is grey (R = G = B); three are R, G, B.
  const planeOf = (k) => src[Math.min(k, src.length - 1)];
  if (view === 'tonemap' || view === 'grey') {
    const gamma = view === 'tonemap', scale = gamma ? 2 ** stops : 1;
    for (let k = 0; k < 3; k++) {
      const p = planeOf(k);
      if (gamma) for (let i = 0; i < n; i++) out[4 * i + k] = toneByte(Math.fround(p[i] * scale));
      else for (let i = 0; i < n; i++) out[4 * i + k] = quantize(p[i], false);
    }
  } else if (view === 'normal') {
    for (let k = 0; k < 3; k++) {
      const p = planeOf(k);
      for (let i = 0; i < n; i++) if (covered(i)) out[4 * i + k] = quantize(Math.fround(p[i] * 0.5 + 0.5), false);
    }
  } else {
    const depth = view === 'depth';
    const [lo, hi] = coveredRange(src[0], alpha, depth && output.kind === 'depth');
    for (let i = 0; i < n; i++) {
      const v = src[0][i];
      if (!covered(i) || (depth && !(v > 0))) continue;
      const t = hi > lo ? (v - lo) / (hi - lo) : 0;
      if (depth) {
        const q = quantize(1 - (1 - DEPTH_PNG_FAR) * t, false);
        put(i, q, q, q);
      } else {
        const u = t * 2, k = u >= 1 ? 1 : 0, f = u - k;
        const c = [0, 1, 2].map((j) => quantize(VIRIDIS[k][j] + (VIRIDIS[k + 1][j] - VIRIDIS[k][j]) * f, false));
        put(i, c[0], c[1], c[2]);
      }
    }
  }
  return new ImageData(out, img.width, img.height);
}

/** A canvas at the image's size holding `data` (ImageData): what the view draws from. */
export function toCanvas(data) {
  const c = document.createElement('canvas');
  c.width = data.width;
  c.height = data.height;
  c.getContext('2d').putImageData(data, 0, 0);
  return c;
}

/** Paints image A or B (toggle), or A and B either side of the divider (split), as `s` says. */
function paintView(ctx, s, imgs) {
  const {width, height} = ctx.canvas;
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = '#3a3d44';
  ctx.fillRect(0, 0, width, height);
  const first = imgs[s.showing], other = imgs[s.showing === 'A' ? 'B' : 'A'];
  if (!first) return;
  // Magnified pixels stay squares; a reduced image is filtered so it does not alias.
  ctx.imageSmoothingEnabled = s.zoom < 1;
  const paint = (img) => {
    ctx.setTransform(s.zoom, 0, 0, s.zoom, s.panX, s.panY);
    ctx.drawImage(img, 0, 0);
    ctx.setTransform(1, 0, 0, 1, 0, 0);
  };
  if (s.mode !== 'split' || !other) {
    paint(first);
    return;
  }
  const x = Math.round(s.split * width);
  for (const [img, x0, x1] of [[first, 0, x], [other, x, width]]) {
    ctx.save();
    ctx.beginPath();
    ctx.rect(x0, 0, x1 - x0, height);
    ctx.clip();
    paint(img);
    ctx.restore();
  }
  ctx.fillStyle = '#e07b00';
  ctx.fillRect(x - 1, 0, 2, height);
}

/**
 * The view on `canvas`. hooks.pixel(x, y, pinned) reports the image pixel under the pointer (null
 * when outside), hooks.change() any change of zoom, pan, split or which image shows. Returns the
 * controller: state (zoom, panX, panY, fitted, split, mode, showing), setImages, fit, oneToOne,
 * zoomBy, panBy, setSplit, setMode, flip, pixelAt, draw, destroy.
 */
export function createView(canvas, hooks) {
  const ctx = canvas.getContext('2d', {willReadFrequently: true});
  const s = {zoom: 1, panX: 0, panY: 0, fitted: true, split: 0.5, mode: 'toggle', showing: 'A', hasB: false, w: 0, h: 0};
  let imgs = {A: null, B: null};
  const changed = () => {
    draw();
    hooks.change();
  };

  const draw = () => paintView(ctx, s, imgs);

  function fit() {
    if (!s.w) return;
    s.zoom = Math.min(canvas.width / s.w, canvas.height / s.h);
    s.panX = (canvas.width - s.w * s.zoom) / 2;
    s.panY = (canvas.height - s.h * s.zoom) / 2;
    s.fitted = true;
    changed();
  }
  /** Zooms to `z` keeping the image point under canvas point (cx, cy) in place. */
  function zoomTo(zoom, cx = canvas.width / 2, cy = canvas.height / 2) {
    const z = Math.min(ZOOM_MAX, Math.max(ZOOM_MIN, zoom));
    s.panX = cx - ((cx - s.panX) * z) / s.zoom;
    s.panY = cy - ((cy - s.panY) * z) / s.zoom;
    s.zoom = z;
    s.fitted = false;
    changed();
  }
  const zoomBy = (f, cx, cy) => zoomTo(s.zoom * f, cx, cy);
  const oneToOne = () => zoomTo(1);
  function panBy(dx, dy) {
    s.panX += dx;
    s.panY += dy;
    s.fitted = false;
    changed();
  }
  const pixelAt = (cx, cy) => {
    const x = Math.floor((cx - s.panX) / s.zoom), y = Math.floor((cy - s.panY) / s.zoom);
    return x >= 0 && y >= 0 && x < s.w && y < s.h ? {x, y} : null;
  };

  const ctl = {state: s, draw, fit, zoomBy, oneToOne, panBy, pixelAt, setSplit: (f) => setSplit(f)};
  attachPointer(canvas, ctl, hooks);

  // The canvas's bitmap follows its laid-out size (the window, 800 px or wider, or narrower).
  const resize = () => {
    const w = Math.max(1, Math.round(canvas.clientWidth)), h = Math.max(1, Math.round(canvas.clientHeight));
    if (w === canvas.width && h === canvas.height) return;
    canvas.width = w;
    canvas.height = h;
    if (s.fitted) fit();
    else changed();
  };
  const observer = new ResizeObserver(resize);
  observer.observe(canvas);

  function setSplit(f) {
    s.split = Math.min(1, Math.max(0, f));
    changed();
  }
  return Object.assign(ctl, {
    /** Images A and B (canvases at the image size; B may be null); the first call fits. */
    setImages(a, b) {
      const first = !imgs.A;
      imgs = {A: a, B: b};
      s.hasB = !!b;
      if (!b) s.showing = 'A';
      s.w = a.width;
      s.h = a.height;
      resize();
      if (first) fit();
      else changed();
    },
    setMode(m) {
      s.mode = m;
      changed();
    },
    flip() {
      if (!imgs.B) return;
      s.showing = s.showing === 'A' ? 'B' : 'A';
      changed();
    },
    destroy: () => observer.disconnect(),
  });
}

/**
 * Pointer input on the view's canvas: dragging pans, or moves the divider when it starts on it; a
 * press without a drag pins the pixel; the wheel zooms about the pointer. `ctl` is the view.
 */
function attachPointer(canvas, ctl, hooks) {
  const s = ctl.state;
  const onDivider = (x) => s.mode === 'split' && s.hasB && Math.abs(x - s.split * canvas.width) <= 6;
  // Inside the border: the bitmap is as large as the content box.
  const local = (ev) => {
    const r = canvas.getBoundingClientRect();
    return [(ev.clientX - r.left - canvas.clientLeft) * (canvas.width / canvas.clientWidth),
            (ev.clientY - r.top - canvas.clientTop) * (canvas.height / canvas.clientHeight)];
  };
  let drag = null;
  canvas.addEventListener('pointerdown', (ev) => {
    const [x, y] = local(ev);
    drag = {x, y, x0: x, y0: y, divider: onDivider(x), moved: false};
    canvas.setPointerCapture(ev.pointerId);
  });
  canvas.addEventListener('pointermove', (ev) => {
    const [x, y] = local(ev);
    if (!drag) {
      canvas.classList.toggle('on-divider', onDivider(x));
      hooks.pixel(ctl.pixelAt(x, y), false);
      return;
    }
    drag.moved = drag.moved || Math.hypot(x - drag.x0, y - drag.y0) > 3;
    if (drag.divider) ctl.setSplit(x / canvas.width);
    else ctl.panBy(x - drag.x, y - drag.y);
    drag.x = x;
    drag.y = y;
  });
  canvas.addEventListener('pointerup', (ev) => {
    const d = drag;
    drag = null;
    if (d && !d.moved && !d.divider) hooks.pixel(ctl.pixelAt(...local(ev)), true);
  });
  canvas.addEventListener('pointerleave', () => {
    if (!drag) hooks.pixel(null, false);
  });
  canvas.addEventListener('wheel', (ev) => {
    ev.preventDefault();
    const [x, y] = local(ev);
    ctl.zoomBy(ev.deltaY < 0 ? 1.25 : 0.8, x, y);
  }, {passive: false});
}
