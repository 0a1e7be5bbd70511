// Where a JSON pointer (RFC 6901) lies in a JSON text, so that the submit form can point at the
// part of a pasted scene document a problem names: the value's character range and its line and
// column. The text is walked, not parsed into objects, because objects forget positions.

const WS = new Set([' ', '\t', '\n', '\r']);

function skipWs(t, i) {
  while (i < t.length && WS.has(t[i])) i++;
  return i;
}

// The end (exclusive) of the string starting at t[i] === '"', and its decoded value.
function readString(t, i) {
  let j = i + 1;
  while (j < t.length && t[j] !== '"') j += t[j] === '\\' ? 2 : 1;
  let value = null;
  try {
    value = JSON.parse(t.slice(i, j + 1));
  } catch {
    value = null;
  }
  return {end: j + 1, value};
}

// The end (exclusive) of the value starting at t[i] (after white space).
function skipValue(t, i) {
  if (t[i] === '"') return readString(t, i).end;
  if (t[i] === '{' || t[i] === '[') {
    let depth = 0;
    for (let j = i; j < t.length; j++) {
      const c = t[j];
      if (c === '"') {
        j = readString(t, j).end - 1;
      } else if (c === '{' || c === '[') {
        depth++;
      } else if (c === '}' || c === ']') {
        depth--;
        if (depth === 0) return j + 1;
      }
    }
    return t.length;
  }
  let j = i;
  while (j < t.length && !WS.has(t[j]) && !',}]'.includes(t[j])) j++;
  return j;
}

// The start of member `key` of the object at t[i] === '{', or -1.
function member(t, i, key) {
  let j = skipWs(t, i + 1);
  while (j < t.length && t[j] === '"') {
    const k = readString(t, j);
    j = skipWs(t, k.end);
    if (t[j] !== ':') return -1;
    j = skipWs(t, j + 1);
    if (k.value === key) return j;
    j = skipWs(t, skipValue(t, j));
    if (t[j] !== ',') return -1;
    j = skipWs(t, j + 1);
  }
  return -1;
}

// The start of element `n` of the array at t[i] === '[', or -1.
function element(t, i, n) {
  let j = skipWs(t, i + 1);
  for (let k = 0; j < t.length && t[j] !== ']'; k++) {
    if (k === n) return j;
    j = skipWs(t, skipValue(t, j));
    if (t[j] !== ',') return -1;
    j = skipWs(t, j + 1);
  }
  return -1;
}

/** Line and column (both from 1) of character offset `at` in `text`. */
export function lineColumn(text, at) {
  const before = text.slice(0, at).split('\n');
  return {line: before.length, column: before[before.length - 1].length + 1};
}

/**
 * The value `pointer` names in JSON `text`: {start, end, line, column, pointer}, where `pointer`
 * is the part found (a missing member is pointed at through the nearest object or array that
 * holds it). null when the text does not start with a JSON value.
 */
export function locatePointer(text, pointer) {
  const segs = pointer === '' ? [] : pointer.slice(1).split('/').map((s) => s.replace(/~1/g, '/').replace(/~0/g, '~'));
  let i = skipWs(text, 0);
  if (i >= text.length) return null;
  let found = '';
  for (const seg of segs) {
    let next = -1;
    if (text[i] === '{') next = member(text, i, seg);
    else if (text[i] === '[' && /^(0|[1-9]\d*)$/.test(seg)) next = element(text, i, Number(seg));
    if (next < 0) break;
    i = next;
    found += `/${seg.replace(/~/g, '~0').replace(/\//g, '~1')}`;
  }
  return {start: i, end: skipValue(text, i), ...lineColumn(text, i), pointer: found};
}
