// Client-side checks of technique parameters against the registry's params_schema (the subset of
// JSON Schema the registry uses: type, enum, minimum, maximum, exclusiveMinimum, exclusiveMaximum,
// default, description), and parsing of what people type: one value, or for a comparison a
// comma-separated list of values. The server checks everything again; this only saves a round trip.

const typesOf = (schema) => (schema.type === undefined ? [] : Array.isArray(schema.type) ? schema.type : [schema.type]);

/** Whether a parameter is itself a list (never expanded into a sweep). */
export const isArrayParam = (schema) => typesOf(schema).includes('array');

/** A typed token: JSON when it parses (8, 0.5, true, null, [1,2]), else the text (an enum name). */
export function parseToken(text) {
  const t = text.trim();
  try {
    return JSON.parse(t);
  } catch {
    return t;
  }
}

function typeOk(type, v) {
  switch (type) {
    case 'integer': return typeof v === 'number' && Number.isInteger(v);
    case 'number': return typeof v === 'number' && Number.isFinite(v);
    case 'boolean': return typeof v === 'boolean';
    case 'null': return v === null;
    case 'string': return typeof v === 'string';
    case 'array': return Array.isArray(v);
    case 'object': return v !== null && typeof v === 'object' && !Array.isArray(v);
    default: return true;
  }
}

const show = (v) => (typeof v === 'string' ? `"${v}"` : JSON.stringify(v));

/** null when v satisfies schema, else a message in the server's style ("must be >= 1 (got 0)"). */
export function checkValue(schema, v) {
  const types = typesOf(schema);
  if (types.length && !types.some((t) => typeOk(t, v))) {
    return `must be ${types.map((t) => (t === 'integer' ? 'an integer' : t === 'null' ? 'null' : `a ${t}`)).join(' or ')} (got ${show(v)})`;
  }
  if (schema.enum && !schema.enum.some((e) => JSON.stringify(e) === JSON.stringify(v))) {
    return `must be one of ${schema.enum.map(show).join(', ')} (got ${show(v)})`;
  }
  if (typeof v === 'number') {
    if (schema.minimum !== undefined && v < schema.minimum) return `must be >= ${schema.minimum} (got ${v})`;
    if (schema.maximum !== undefined && v > schema.maximum) return `must be <= ${schema.maximum} (got ${v})`;
    if (schema.exclusiveMinimum !== undefined && v <= schema.exclusiveMinimum) return `must be > ${schema.exclusiveMinimum} (got ${v})`;
    if (schema.exclusiveMaximum !== undefined && v >= schema.exclusiveMaximum) return `must be < ${schema.exclusiveMaximum} (got ${v})`;
  }
  return null;
}

/** Splits "4, 16,64" on top-level commas (a list-typed value like [1,2] stays whole). */
export function splitList(text) {
  const out = [];
  let depth = 0, cur = '';
  for (const ch of text) {
    if (ch === '[' || ch === '{') depth++;
    if (ch === ']' || ch === '}') depth--;
    if (ch === ',' && depth === 0) {
      out.push(cur);
      cur = '';
    } else cur += ch;
  }
  out.push(cur);
  return out.map((s) => s.trim());
}

/**
 * Parses one field. text '' means "not given" (the default applies). With list = true the text may
 * hold several comma-separated values (unless the parameter is itself a list). Returns
 * {given, values, errors}: values the parsed values, errors one message per bad value.
 */
export function parseField(schema, text, {list = false} = {}) {
  if (text.trim() === '') return {given: false, values: [], errors: []};
  const parts = list && !isArrayParam(schema) ? splitList(text) : [text];
  const values = [], errors = [];
  parts.forEach((p, i) => {
    if (p === '') {
      errors.push(`value ${i + 1} is empty`);
      return;
    }
    const v = parseToken(p);
    const e = checkValue(schema, v);
    if (e) errors.push(parts.length > 1 ? `value ${i + 1}: ${e}` : e);
    else values.push(v);
  });
  if (list && new Set(values.map((v) => JSON.stringify(v))).size !== values.length) errors.push('lists a value twice');
  return {given: true, values, errors};
}

/** Human description of a parameter's rule ("integer, 1 to 65536, default 64"). */
export function describeRule(schema) {
  const bits = [];
  const types = typesOf(schema);
  if (types.length) bits.push(types.join(' or '));
  if (schema.enum) bits.push(`one of ${schema.enum.map((e) => JSON.stringify(e)).join(', ')}`);
  const lo = schema.minimum !== undefined ? `≥ ${schema.minimum}` : schema.exclusiveMinimum !== undefined ? `> ${schema.exclusiveMinimum}` : null;
  const hi = schema.maximum !== undefined ? `≤ ${schema.maximum}` : schema.exclusiveMaximum !== undefined ? `< ${schema.exclusiveMaximum}` : null;
  if (lo || hi) bits.push([lo, hi].filter(Boolean).join(', '));
  if (schema.default !== undefined) bits.push(`default ${JSON.stringify(schema.default)}`);
  return bits.join('; ');
}
