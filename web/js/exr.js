// An OpenEXR decoder for the image viewer: exactly what obscura writes (renderer/core/exr.c:
// single-part scanline files, FLOAT channels, RLE by default and NONE, ZIPS or ZIP on request),
// plus HALF channels. Anything else (tiles, deep data, several parts, PIZ and the lossy
// compressions, UINT or subsampled channels) is refused with an ExrError saying what it is.

/** A file this decoder does not read, with the reason in words. */
export class ExrError extends Error {}

const COMPRESSIONS = ['NONE', 'RLE', 'ZIPS', 'ZIP', 'PIZ', 'PXR24', 'B44', 'B44A', 'DWAA', 'DWAB', 'HTJ2K'];
// Scanlines per chunk of the compressions read here (the others are refused before this matters).
const LINES = {NONE: 1, RLE: 1, ZIPS: 1, ZIP: 16};
const PIXEL_TYPES = ['UINT', 'HALF', 'FLOAT'];
const LITTLE_ENDIAN = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;

/** A cursor over the file's bytes (little-endian, as the format is). */
class Reader {
  constructor(buf) {
    this.bytes = new Uint8Array(buf);
    this.view = new DataView(buf);
    this.pos = 0;
  }
  need(n, what) {
    if (this.pos + n > this.bytes.length) throw new ExrError(`the file ends inside ${what} (byte ${this.pos})`);
  }
  u8(what) {
    this.need(1, what);
    return this.bytes[this.pos++];
  }
  i32(what) {
    this.need(4, what);
    const v = this.view.getInt32(this.pos, true);
    this.pos += 4;
    return v;
  }
  u64(what) {
    this.need(8, what);
    const lo = this.view.getUint32(this.pos, true), hi = this.view.getUint32(this.pos + 4, true);
    this.pos += 8;
    return hi * 4294967296 + lo;
  }
  str(what) {
    const end = this.bytes.indexOf(0, this.pos);
    if (end < 0 || end - this.pos > 255) throw new ExrError(`unterminated name in ${what} (byte ${this.pos})`);
    const s = new TextDecoder().decode(this.bytes.subarray(this.pos, end));
    this.pos = end + 1;
    return s;
  }
}

function parseChannels(r, end) {
  const channels = [];
  for (;;) {
    const name = r.str('the channel list');
    if (!name) break;
    const type = r.i32('the channel list');
    r.pos += 4; // pLinear and three reserved bytes
    const xs = r.i32('the channel list'), ys = r.i32('the channel list');
    channels.push({name, type, xs, ys});
    if (r.pos > end) throw new ExrError('the channel list overruns its attribute');
  }
  return channels;
}

/** The header attributes the decoder needs, checked against what it supports. */
function parseHeader(r) {
  r.need(8, 'the magic number');
  if (r.i32('the magic number') !== 20000630) throw new ExrError('not an OpenEXR file (wrong magic number)');
  const version = r.i32('the version');
  if ((version & 0xff) !== 2) throw new ExrError(`OpenEXR version ${version & 0xff} (only 2 is read)`);
  if (version & 0x200) throw new ExrError('tiled EXR files are not read by the viewer (obscura writes scanlines)');
  if (version & 0x800) throw new ExrError('deep EXR data is not read by the viewer');
  if (version & 0x1000) throw new ExrError('multi-part EXR files are not read by the viewer');
  const h = {};
  for (;;) {
    const name = r.str('the header');
    if (!name) break;
    r.str('the header'); // attribute type: the names below fix it
    const size = r.i32('the header');
    r.need(size, `attribute ${name}`);
    const start = r.pos;
    if (name === 'channels') h.channels = parseChannels(r, start + size);
    else if (name === 'compression') h.compression = r.u8(name);
    else if (name === 'lineOrder') h.lineOrder = r.u8(name);
    else if (name === 'dataWindow') h.dw = [r.i32(name), r.i32(name), r.i32(name), r.i32(name)];
    r.pos = start + size;
  }
  if (!h.channels || h.compression === undefined || !h.dw) throw new ExrError('the header lacks channels, compression or dataWindow');
  h.compressionName = COMPRESSIONS[h.compression] || `#${h.compression}`;
  if (!LINES[h.compressionName]) {
    throw new ExrError(`${h.compressionName} compression is not read by the viewer (NONE, RLE, ZIPS and ZIP are; obscura writes RLE)`);
  }
  for (const c of h.channels) {
    if (c.type !== 1 && c.type !== 2) throw new ExrError(`channel "${c.name}" has pixel type ${PIXEL_TYPES[c.type] || c.type} (HALF and FLOAT are read)`);
    if (c.xs !== 1 || c.ys !== 1) throw new ExrError(`channel "${c.name}" is subsampled (${c.xs}x${c.ys})`);
  }
  h.width = h.dw[2] - h.dw[0] + 1;
  h.height = h.dw[3] - h.dw[1] + 1;
  if (!(h.width > 0 && h.height > 0 && h.width * h.height <= 1 << 26)) throw new ExrError(`data window ${h.dw.join(',')} is empty or too large`);
  return h;
}

async function inflate(bytes) {
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function rleDecode(src, size) {
  const out = new Uint8Array(size);
  let i = 0, o = 0;
  while (i < src.length) {
    const n = (src[i] << 24) >> 24; // a signed byte
    if (n < 0) {
      if (o - n > size || i + 1 - n > src.length) throw new ExrError('corrupt RLE data');
      out.set(src.subarray(i + 1, i + 1 - n), o);
      o -= n;
      i += 1 - n;
    } else {
      if (o + n + 1 > size || i + 1 >= src.length) throw new ExrError('corrupt RLE data');
      out.fill(src[i + 1], o, o + n + 1);
      o += n + 1;
      i += 2;
    }
  }
  if (o !== size) throw new ExrError(`corrupt RLE data (${o} of ${size} bytes)`);
  return out;
}

/**
 * ZIP and RLE store the bytes split in two halves (even positions, then odd ones) as differences
 * (+128) of the byte before: undoes both in one pass.
 */
function unpredict(t) {
  const n = t.length, out = new Uint8Array(n), half = (n + 1) >> 1;
  if (!n) return out;
  let prev = t[0];
  out[0] = prev;
  for (let k = 1; k < half; k++) {
    prev = (prev + t[k] + 128) & 255;
    out[2 * k] = prev;
  }
  for (let k = 0; k < n - half; k++) {
    prev = (prev + t[half + k] + 128) & 255;
    out[2 * k + 1] = prev;
  }
  return out;
}

async function chunkBytes(data, raw, compression) {
  // A chunk that did not get smaller is stored as it is, whatever the file's compression.
  if (compression === 'NONE' || data.length === raw) return data;
  const t = compression === 'RLE' ? rleDecode(data, raw) : await inflate(data);
  if (t.length !== raw) throw new ExrError(`a chunk decompressed to ${t.length} bytes, expected ${raw}`);
  return unpredict(t);
}

function halfToFloat(h) {
  const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, m = h & 0x3ff;
  if (e === 0) return s * m * 2 ** -24;
  if (e === 31) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * 2 ** (e - 15);
}

/** Copies one chunk's scanlines (each: every channel's row in turn) into the float planes. */
function scatter(bytes, y0, lines, h, planes) {
  const w = h.width;
  if (LITTLE_ENDIAN && h.channels.every((c) => c.type === 2)) {
    // All FLOAT: the rows are the platform's own layout, copied whole from one aligned view.
    const b = bytes.byteOffset % 4 ? bytes.slice() : bytes;
    const f = new Float32Array(b.buffer, b.byteOffset, b.byteLength >> 2);
    let q = 0;
    for (let l = 0; l < lines; l++) {
      for (const dst of planes) {
        dst.set(f.subarray(q, q + w), (y0 + l) * w);
        q += w;
      }
    }
    return;
  }
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let p = 0;
  for (let l = 0; l < lines; l++) {
    const row = (y0 + l) * w;
    h.channels.forEach((c, k) => {
      const dst = planes[k];
      if (c.type === 2) {
        for (let x = 0; x < w; x++, p += 4) dst[row + x] = view.getFloat32(p, true);
      } else {
        for (let x = 0; x < w; x++, p += 2) dst[row + x] = halfToFloat(view.getUint16(p, true));
      }
    });
  }
}

/**
 * Decodes an EXR file (an ArrayBuffer) into {width, height, compression, channels: [{name, type,
 * data: Float32Array}]}, the channels in file order (sorted by name), row 0 at the top.
 */
export async function decodeExr(buf) {
  const r = new Reader(buf);
  const h = parseHeader(r);
  const per = LINES[h.compressionName];
  const nchunks = Math.ceil(h.height / per);
  const offsets = [];
  for (let k = 0; k < nchunks; k++) offsets.push(r.u64('the offset table'));
  const planes = h.channels.map(() => new Float32Array(h.width * h.height));
  const lineBytes = h.channels.reduce((n, c) => n + h.width * (c.type === 2 ? 4 : 2), 0);
  const seen = new Uint8Array(nchunks);
  await Promise.all(offsets.map(async (off) => {
    r.pos = off;
    const y = r.i32('a chunk'), size = r.i32('a chunk');
    r.need(size, 'a chunk');
    const k = (y - h.dw[1]) / per;
    if (!Number.isInteger(k) || k < 0 || k >= nchunks || seen[k]) throw new ExrError(`a chunk starts at line ${y}, not a chunk's first line`);
    seen[k] = 1;
    const lines = Math.min(per, h.height - k * per);
    const data = r.bytes.subarray(r.pos, r.pos + size);
    scatter(await chunkBytes(data, lines * lineBytes, h.compressionName), k * per, lines, h, planes);
  }));
  return {width: h.width, height: h.height, compression: h.compressionName,
          channels: h.channels.map((c, k) => ({name: c.name, type: PIXEL_TYPES[c.type], data: planes[k]}))};
}
