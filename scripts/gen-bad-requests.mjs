#!/usr/bin/env node
// Writes the generated part of the attack corpus tests/server/bad_requests.json: wrong types and
// ranges of every scene field (walked from schema/scene.schema.json) and of every technique
// parameter (from the registry, `obscura techniques`), unknown keys at every level, bad JSON
// syntax, deep nesting, huge numbers and strings, bad UTF-8, bad ids, routes, methods, queries,
// tokens and Content-Types, cross-origin requests and raw malformed HTTP. Hand-written entries
// (those without "generated": true) are kept as they are, first; the generated ones are replaced.
// The output is deterministic, so a run on an unchanged tree leaves the file unchanged.
//
//   node scripts/gen-bad-requests.mjs [path-to-obscura-cli]   (default build/obscura)
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {fileURLToPath} from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const CORPUS = path.join(ROOT, 'tests/server/bad_requests.json');
const cli = path.resolve(process.argv[2] || path.join(ROOT, 'build/obscura'));
const reg = spawnSync(cli, ['techniques'], {encoding: 'utf8'});
if (reg.status !== 0) {
  console.error(`gen-bad-requests: ${cli} techniques failed (build the CLI first)\n${reg.stderr}`);
  process.exit(1);
}
const techniques = JSON.parse(reg.stdout);
const schema = JSON.parse(fs.readFileSync(path.join(ROOT, 'schema/scene.schema.json'), 'utf8'));
const corpus = JSON.parse(fs.readFileSync(CORPUS, 'utf8'));

const out = [];
const names = new Set();
function add(cls, e) {
  const entry = {name: e.name, class: cls, generated: true, ...e};
  if (names.has(entry.name)) throw new Error(`duplicate name: ${entry.name}`);
  names.add(entry.name);
  out.push(entry);
}
const resolve = (s) => (s && s.$ref ? resolve(schema.$defs[s.$ref.replace('#/$defs/', '')]) : s);

// ---- wrong types and ranges, from the schema --------------------------------------------------

const big = (m) => (Math.abs(m) < 1e6 ? 1 : Math.abs(m) * 9);
// Values that break `s` (a resolved property schema), each with a short label.
function badValues(s) {
  s = resolve(s);
  const types = [].concat(s.type || []);
  const v = [];
  const allowsNull = types.includes('null');
  if (s.const !== undefined) return [['another value', 'nope'], ['a number', 1]];
  if (s.enum && !types.includes('integer')) {
    v.push(['not one of the choices', 'nope'], ['in capitals', String(s.enum[0]).toUpperCase()]);
    v.push(['a number', 7], ['a list of a choice', [s.enum[0]]]);
    if (!allowsNull) v.push(['null', null]);
    return v;
  }
  if (types.includes('number') || types.includes('integer')) {
    v.push(['a string', '1'], ['a boolean', true], ['an array', [1]], ['an object', {}]);
    if (!allowsNull) v.push(['null', null]);
    if (types.includes('integer')) v.push(['fractional', 1.5]);
    if (s.enum) v.push(['not one of the choices', 12], ['zero', 0]);
    if (s.minimum !== undefined) v.push(['below its minimum', s.minimum - big(s.minimum)]);
    if (s.exclusiveMinimum !== undefined) {
      v.push(['at its exclusive minimum', s.exclusiveMinimum]);
      v.push(['below its exclusive minimum', s.exclusiveMinimum - big(s.exclusiveMinimum)]);
    }
    if (s.maximum !== undefined) v.push(['above its maximum', s.maximum + big(s.maximum)]);
    if (s.exclusiveMaximum !== undefined) v.push(['at its exclusive maximum', s.exclusiveMaximum]);
    return v;
  }
  if (types.includes('string')) {
    v.push(['a number', 42], ['an array', ['x']], ['an object', {}], ['null', null]);
    if (s.minLength) v.push(['empty', '']);
    if (s.maxLength && s.maxLength <= 8192) v.push(['too long', 'x'.repeat(s.maxLength + 1)]);
    return v;
  }
  if (types.includes('boolean')) {
    return [['a number', 0], ['a string', 'true'], ['null', null], ['an array', [true]]];
  }
  if (types.includes('array')) {
    v.push(['a string', '1, 2, 3'], ['an object', {}], ['null', null]);
    if (!s.items) return v;
    v.push(['empty', []]);
    const item = resolve(s.items);
    const good = goodValue(item);
    if (s.minItems > 1) v.push(['one item short', Array(s.minItems - 1).fill(good)]);
    if (s.maxItems && s.maxItems < 100) v.push(['one item too many', Array(s.maxItems + 1).fill(good)]);
    const n = s.minItems || 1;
    for (const [label, bad] of badValues(item).slice(0, 3)) {
      const arr = Array(n).fill(good);
      arr[0] = bad;
      v.push([`its first item ${label}`, arr]);
    }
    return v;
  }
  if (types.includes('object')) return [['a string', 'x'], ['an array', []], ['a number', 1], ['null', null]];
  return v;
}
function goodValue(s) {
  s = resolve(s);
  if (s.type === 'array') return Array(s.minItems || 1).fill(goodValue(s.items));
  if (s.type === 'number' || s.type === 'integer') return s.minimum > 0 ? s.minimum : 0.5;
  return 0.5;
}

// Each scene object type, where it sits in the inline base and a valid instance of it.
const V = [[-1, 2, -1], [-1, 2, 1], [1, 2, 1], [1, 2, -1]];
const contexts = [
  {ptr: '/camera', def: 'camera', value: corpus.bases.inline.camera, skip: ['height']},
  {ptr: '/camera', def: 'camera', tag: 'orthographic ',
   value: {type: 'orthographic', position: [0, 3, -4], look_at: [0, 0.3, 0], height: 4}, skip: ['fov_y', 'type']},
  {ptr: '/image', def: 'image', value: {width: 16, height: 16, spp: 1}},
  {ptr: '/objects/0', def: 'object', value: {name: 'ball', shape: {type: 'sphere', center: [0, 1, 0], radius: 0.5}},
   skip: ['shape', 'material', 'transform']},
  {ptr: '/objects/0/shape', def: 'shape_quad', value: {type: 'quad', vertices: V}},
  {ptr: '/objects/0/shape', def: 'shape_triangle', value: {type: 'triangle', vertices: V.slice(0, 3)}},
  {ptr: '/objects/0/shape', def: 'shape_sphere', value: {type: 'sphere', center: [0, 1, 0], radius: 0.5}},
  {ptr: '/objects/0/shape', def: 'shape_box', value: {type: 'box', min: [-1, 0, -1], max: [1, 1, 1]}},
  {ptr: '/objects/0/shape', def: 'shape_mesh', value: {type: 'mesh', file: 'models/teapot.obj'}},
  {ptr: '/objects/0/shape', def: 'shape_displaced_sphere', value: {type: 'displaced_sphere', subdivisions: 2}},
  {ptr: '/objects/0/material', def: 'material', value: {reflectivity: [0.5, 0.5, 0.5]}},
  {ptr: '/objects/0/transform', def: 'transform', value: {scale: [1, 1, 1], rotate: [0, 0, 0], translate: [0, 0, 0]}},
  {ptr: '/lights/0', def: 'light', value: {type: 'quad', vertices: V, emission: [1, 1, 1]}},
  {ptr: '/environment', def: 'environment', value: {color: [0.2, 0.2, 0.2]}},
  {ptr: '/technique', def: 'technique', value: {name: 'rt_ao', backend: 'cpu', params: {samples: 4}}, skip: ['params']},
];
// The patch that puts `value` at `ptr` of the inline base (lists and parents built whole).
function placeAt(ptr, value) {
  const base = corpus.bases.inline;
  if (ptr === '/lights/0') return {'/lights': [value]};
  if (ptr.startsWith('/objects/0')) {
    const obj = structuredClone(base.objects[0]);
    const rest = ptr.slice('/objects/0'.length).split('/').filter(Boolean);
    if (!rest.length) return {'/objects/0': value};
    obj[rest[0]] = value;
    return {'/objects/0': obj};
  }
  return {[ptr]: value};
}
function sceneFields() {
  for (const c of contexts) {
    const def = schema.$defs[c.def];
    const what = `${c.tag || (c.def.startsWith('shape_') ? `${c.def.slice(6)} ` : '')}${c.ptr}`;
    for (const [key, ps] of Object.entries(def.properties)) {
      if ((c.skip || []).includes(key)) continue;
      for (const [label, bad] of badValues(ps)) {
        add('scene-field-types', {
          name: `${what}/${key} ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
          patch: placeAt(c.ptr, {...c.value, [key]: bad}), status: 422, expect: [`${c.ptr}/${key}`]});
      }
    }
    for (const key of def.required || []) {
      const v = {...c.value};
      delete v[key];
      add('scene-field-types', {
        name: `${what}/${key} missing`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
        patch: placeAt(c.ptr, v), status: 422, expect: [`${c.ptr}/${key}`, 'required']});
    }
    add('unknown-keys', {
      name: `unknown key in ${what}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
      patch: placeAt(c.ptr, {...c.value, frobnicate: 1}), status: 422, expect: [`${c.ptr}/frobnicate`]});
    if (c.ptr !== '/technique' && !c.ptr.startsWith('/objects/0/')) {
      for (const [label, bad] of [['a string', 'x'], ['an array', []], ['a number', 1]]) {
        const patch = c.ptr === '/lights/0' ? {'/lights': [bad]} : c.ptr === '/objects/0' ? {'/objects/0': bad} : {[c.ptr]: bad};
        add('scene-field-types', {
          name: `${what} ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'inline', patch,
          status: 422, expect: [c.ptr]});
      }
    }
  }
  for (const [label, bad] of [['a string', 'x'], ['an object', {}], ['null', null], ['a number', 3]]) {
    add('scene-field-types', {name: `/objects ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
                              patch: {'/objects': bad}, status: 422, expect: ['/objects']});
    add('scene-field-types', {name: `/lights ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
                              patch: {'/lights': bad}, status: 422, expect: ['/lights']});
  }
  // Keys of another shape type.
  for (const [type, extra] of [['sphere', {vertices: V}], ['quad', {radius: 1}], ['box', {center: [0, 0, 0]}],
                               ['triangle', {subdivisions: 2}], ['displaced_sphere', {file: 'models/teapot.obj'}]]) {
    const c = contexts.find((x) => x.def === `shape_${type}`);
    const key = Object.keys(extra)[0];
    add('unknown-keys', {name: `${type} shape with ${key}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
                         patch: placeAt(c.ptr, {...c.value, ...extra}), status: 422,
                         expect: [`/objects/0/shape/${key}`]});
  }
}

// ---- technique parameters, from the registry --------------------------------------------------

function techniqueParams() {
  for (const t of techniques) {
    const props = (t.params_schema && t.params_schema.properties) || {};
    for (const [key, ps] of Object.entries(props)) {
      for (const [label, bad] of badValues(ps)) {
        add('technique-params', {
          name: `${t.name} param ${key} ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
          patch: {'/technique': {name: t.name, backend: 'cpu', params: {[key]: bad}}}, status: 422,
          expect: [`/technique/params/${key}`]});
      }
    }
    add('unknown-keys', {
      name: `${t.name} unknown param`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
      patch: {'/technique': {name: t.name, backend: 'cpu', params: {frobnicate: 1}}}, status: 422,
      expect: ['/technique/params/frobnicate']});
    add('technique-params', {
      name: `${t.name} params a list`, method: 'POST', path: '/api/v1/jobs', base: 'inline',
      patch: {'/technique': {name: t.name, backend: 'cpu', params: []}}, status: 422, expect: ['/technique/params']});
    // The same through a bundled scene and `set`.
    const first = Object.keys(props)[0];
    if (first) {
      add('technique-params', {
        name: `${t.name} param ${first} a string through set`, method: 'POST', path: '/api/v1/jobs', base: 'file',
        patch: {'/technique': {name: t.name, backend: 'cpu'}, '/set': {'/image/width': 16, '/image/height': 16,
                [`/technique/params/${first}`]: 'x'}},
        status: 422, expect: [`/technique/params/${first}`]});
    }
  }
}

// ---- the request wrappers ---------------------------------------------------------------------

const COMPARISON = {scene_file: 'sphere_on_plane.json', set: {'/image/width': 16, '/image/height': 16},
                    candidates: [{technique: 'ssao', backend: 'cpu', params: {samples: 8}}]};
function wrappers() {
  const job = [['priority', {type: 'integer', minimum: 0, maximum: 100}], ['label', {type: 'string', maxLength: 256}],
               ['time_budget_ms', {type: 'number'}]];
  for (const [key, s] of job) {
    for (const [label, bad] of badValues(s)) {
      const name = `job ${key} ${label}`;
      if (key === 'time_budget_ms' && label === 'null') continue;
      const patch = {[`/${key}`]: bad};
      if (key === 'time_budget_ms') patch['/technique'] = 'auto';
      add('wrapper-fields', {name, method: 'POST', path: '/api/v1/jobs', base: 'file', patch, status: 422, expect: [`/${key}`]});
    }
  }
  add('wrapper-fields', {name: 'job time_budget_ms without technique auto', method: 'POST', path: '/api/v1/jobs',
                         base: 'file', patch: {'/time_budget_ms': 100}, status: 422, expect: ['/time_budget_ms']});
  add('wrapper-fields', {name: 'job time_budget_ms 0', method: 'POST', path: '/api/v1/jobs', base: 'file',
                         patch: {'/technique': 'auto', '/time_budget_ms': 0}, status: 422, expect: ['/time_budget_ms']});
  add('wrapper-fields', {name: 'job technique auto without a budget', method: 'POST', path: '/api/v1/jobs', base: 'file',
                         patch: {'/technique': 'auto'}, status: 422, expect: ['/time_budget_ms']});
  for (const [label, bad] of [['a number', 1], ['an array', ['/image/width']], ['a string', '/image/width=3'], ['null', null]]) {
    add('wrapper-fields', {name: `job set ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'file',
                           patch: {'/set': bad}, status: 422, expect: ['/set']});
  }
  const many = {};
  for (let i = 0; i < 65; i++) many[`/objects/0/name${i}`] = 'x';
  add('wrapper-fields', {name: 'job set with 65 entries', method: 'POST', path: '/api/v1/jobs', base: 'file',
                         patch: {'/set': many}, status: 422, expect: ['/set']});
  for (const [label, ptr] of [['empty pointer', ''], ['bad escape ~2', '/image/~2'],
                              ['index with a sign', '/objects/+0/name'], ['index with a leading zero', '/objects/01/name'],
                              ['index past int64', '/objects/99999999999999999999/name'], ['dash in the middle', '/objects/-/name'],
                              ['through a number', '/image/width/x'], ['through a string', '/technique/name/x']]) {
    add('wrapper-fields', {name: `job set ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'file',
                           patch: {'/set': {[ptr]: 1}}, status: 422, expect: ['/set']});
  }
  add('unknown-keys', {name: 'unknown key in a file job', method: 'POST', path: '/api/v1/jobs', base: 'file',
                       patch: {'/Scene_File': 'x'}, status: 422, expect: ['Scene_File']});
  add('unknown-keys', {name: 'unknown key in a set pointer', method: 'POST', path: '/api/v1/jobs', base: 'file',
                       patch: {'/set': {'/camera/frobnicate': 1}}, status: 422, expect: ['frobnicate']});
  add('unknown-keys', {name: 'unknown key in a set value', method: 'POST', path: '/api/v1/jobs', base: 'file',
                       patch: {'/set': {'/image': {width: 16, height: 16, frobnicate: 1}}}, status: 422, expect: ['frobnicate']});

  // POST /api/v1/comparisons
  const cmp = [['priority', {type: 'integer', minimum: 0, maximum: 100}], ['repeats', {type: 'integer', minimum: 1, maximum: 20}],
               ['label', {type: 'string', maxLength: 256}], ['scene_file', {type: 'string', minLength: 1}],
               ['candidates', {type: 'array'}]];
  for (const [key, s] of cmp) {
    for (const [label, bad] of badValues(s)) {
      if (key === 'candidates' && label === 'an object') continue;
      add('comparison-fields', {name: `comparison ${key} ${label}`, method: 'POST', path: '/api/v1/comparisons',
                                base: 'comparison', patch: {[`/${key}`]: bad}, status: 422, expect: [`/${key}`]});
    }
  }
  for (const [key, s] of [['samples', {type: 'integer', minimum: 1, maximum: 65536}], ['seed', {type: 'integer', minimum: 0, maximum: 4294967295}],
                          ['backend', {enum: ['cpu', 'vulkan', 'auto']}]]) {
    for (const [label, bad] of badValues(s)) {
      add('comparison-fields', {name: `comparison reference ${key} ${label}`, method: 'POST', path: '/api/v1/comparisons',
                                base: 'comparison', patch: {'/reference': {[key]: bad}}, status: 422, expect: [`/reference/${key}`]});
    }
  }
  const cand = (c) => ({'/candidates': [c]});
  for (const [label, c, ptr] of [
    ['a string', 'ssao', '/candidates/0'], ['technique missing', {params: {}}, '/candidates/0/technique'],
    ['technique unknown', {technique: 'nope'}, '/candidates/0/technique'], ['technique a number', {technique: 1}, '/candidates/0/technique'],
    ['backend gpu', {technique: 'ssao', backend: 'gpu'}, '/candidates/0/backend'],
    ['backend an empty list', {technique: 'ssao', backend: []}, '/candidates/0/backend'],
    ['backend listed twice', {technique: 'ssao', backend: ['cpu', 'cpu']}, '/candidates/0/backend'],
    ['backend vulkan without a lane', {technique: 'ssao', backend: 'vulkan'}, 'vulkan'],
    ['params a list', {technique: 'ssao', params: []}, '/candidates/0/params'],
    ['param value out of range', {technique: 'hbao', backend: 'cpu', params: {directions: [4, 99]}}, '/candidates/0/params/directions'],
    ['param unknown', {technique: 'hbao', backend: 'cpu', params: {frobnicate: [1]}}, 'frobnicate'],
    ['unknown key', {technique: 'ssao', frobnicate: 1}, '/candidates/0/frobnicate']]) {
    add('comparison-fields', {name: `comparison candidate ${label}`, method: 'POST', path: '/api/v1/comparisons',
                              base: 'comparison', patch: cand(c), status: 422, expect: [ptr]});
  }
  add('comparison-fields', {name: 'comparison candidates empty', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/candidates': []}, status: 422, expect: ['/candidates']});
  add('comparison-fields', {name: 'comparison without candidates', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/candidates': {$delete: true}}, status: 422, expect: ['/candidates']});
  add('comparison-fields', {name: 'comparison scene_file and scene', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/scene': corpus.bases.inline}, status: 422, expect: ['/scene']});
  add('comparison-fields', {name: 'comparison scene a string', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/scene_file': {$delete: true}, '/scene': 'x'}, status: 422, expect: ['/scene']});
  add('comparison-fields', {name: 'comparison scene_file traversal', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/scene_file': '../../etc/passwd'}, status: 422, expect: ['/scene_file']});
  add('comparison-fields', {name: 'comparison set an array', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/set': []}, status: 422, expect: ['/set']});
  add('comparison-fields', {name: 'comparison set width 0', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/set': {'/image/width': 0, '/image/height': 16}}, status: 422, expect: ['/image/width']});
  add('comparison-fields', {name: 'comparison set over --max-pixels', method: 'POST', path: '/api/v1/comparisons',
                            base: 'comparison', patch: {'/set': {'/image/width': 4000, '/image/height': 4000}}, status: 422, expect: ['max-pixels']});
  add('unknown-keys', {name: 'unknown key in a comparison', method: 'POST', path: '/api/v1/comparisons',
                       base: 'comparison', patch: {'/frobnicate': 1}, status: 422, expect: ['/frobnicate']});
  add('unknown-keys', {name: 'unknown key in a comparison reference', method: 'POST', path: '/api/v1/comparisons',
                       base: 'comparison', patch: {'/reference': {frobnicate: 1}}, status: 422, expect: ['/reference/frobnicate']});
  for (const [label, raw] of [['not JSON', '{"scene_file": '], ['an array', '[]'], ['empty', '']]) {
    add('json-syntax', {name: `comparison body ${label}`, method: 'POST', path: '/api/v1/comparisons', raw,
                        headers: {'content-type': 'application/json'}, status: label === 'an array' ? 422 : 400,
                        expect: label === 'an array' ? ['object'] : []});
  }
}

// ---- bad JSON syntax --------------------------------------------------------------------------

function jsonSyntax() {
  const body = JSON.stringify({scene_file: 'sphere_on_plane.json', label: 'cut', priority: 5,
                               set: {'/image/width': 16, '/image/height': 16}});
  // Cut off at 24 points spread over the body (never at its end).
  for (let i = 1; i <= 24; i++) {
    const at = Math.floor((body.length - 1) * i / 25);
    add('json-syntax', {name: `body cut after ${at} bytes`, method: 'POST', path: '/api/v1/jobs', raw: body.slice(0, at),
                        headers: {'content-type': 'application/json'}, status: 400, expect: ['not valid JSON']});
  }
  const S = '{"scene_file": "sphere_on_plane.json", "priority": ';
  const bad = [['unquoted key', '{scene_file: "sphere_on_plane.json"}'], ['hex number', `${S}0x10}`],
    ['leading zero', `${S}01}`], ['plus sign', `${S}+1}`], ['bare fraction', `${S}.5}`], ['trailing dot', `${S}1.}`],
    ['exponent without digits', `${S}1e}`], ['truncated true', `${S}tru}`], ['truncated null', `${S}nul}`],
    ['capitalised True', `${S}True}`], ['tab in a string', '{"scene_file": "sphere_on\tplane.json"}'],
    ['newline in a string', '{"scene_file": "sphere_on\nplane.json"}'], ['bad escape \\x', '{"scene_file": "\\x41.json"}'],
    ['short \\u escape', '{"scene_file": "\\u12.json"}'], ['lone low surrogate', '{"scene_file": "x", "label": "\\udc00"}'],
    ['unterminated string', '{"scene_file": "sphere_on_plane.json'], ['missing colon', '{"scene_file" "x"}'],
    ['missing comma', '{"scene_file": "x" "label": "y"}'], ['double comma', '{"scene_file": "x",, "label": "y"}'],
    ['leading comma', '{, "scene_file": "x"}'], ['array trailing comma', '{"scene_file": "x", "set": {"/objects": [1,]}}'],
    ['unclosed array', '{"scene_file": "x", "set": {"/objects": [1, 2}}'], ['closing bracket mismatch', '{"scene_file": "x"]'],
    ['byte order mark', '\ufeff{"scene_file": "sphere_on_plane.json"}'], ['key not a string', '{1: "x"}'],
    ['single value then garbage', '"x" "y"'], ['only a comma', ','], ['only a colon', ':'], ['lone minus', `${S}-}`],
    ['minus space', `${S}- 1}`], ['undefined literal', `${S}undefined}`], ['JavaScript comment block', '{/* c */ "scene_file": "x"}'],
    ['XML', '<job scene_file="sphere_on_plane.json"/>'], ['YAML', 'scene_file: sphere_on_plane.json\n'],
    ['form encoding', 'scene_file=sphere_on_plane.json'], ['escaped NUL in a key', '{"scene\\u0000file": "x"}'],
    ['duplicate key in set', '{"scene_file": "sphere_on_plane.json", "set": {"/image/width": 8, "/image/width": 9}}'],
    ['duplicate key deep', '{"camera": {"type": "perspective", "type": "orthographic"}}']];
  for (const [label, raw] of bad) {
    add('json-syntax', {name: `JSON ${label}`, method: 'POST', path: '/api/v1/jobs', raw,
                        headers: {'content-type': 'application/json'}, status: 400,
                        expect: [label.startsWith('duplicate') ? 'duplicate' : 'not valid JSON']});
  }
}

// ---- deep nesting, huge numbers and strings, bad UTF-8 ----------------------------------------

function depthAndSize() {
  const F = '{"scene_file": "sphere_on_plane.json", ';
  for (const [label, open, close] of [['arrays', '[', ']'], ['objects', '{"a":', '}']]) {
    add('deep-nesting', {name: `label nested 100000 ${label} deep`, method: 'POST', path: '/api/v1/jobs',
                         raw_gen: {prefix: `${F}"label": `, repeat: open, count: 100000, middle: '1', repeat2: close, count2: 100000, suffix: '}'},
                         headers: {'content-type': 'application/json'}, status: 422, expect: ['depth limit']});
    add('deep-nesting', {name: `set value nested 100000 ${label} deep`, method: 'POST', path: '/api/v1/jobs',
                         raw_gen: {prefix: `${F}"set": {"/label": `, repeat: open, count: 100000, middle: '1', repeat2: close, count2: 100000, suffix: '}}'},
                         headers: {'content-type': 'application/json'}, status: 422, expect: ['depth limit']});
    add('deep-nesting', {name: `comparison nested 100000 ${label} deep`, method: 'POST', path: '/api/v1/comparisons',
                         raw_gen: {prefix: '{"scene_file": "sphere_on_plane.json", "label": ', repeat: open, count: 100000,
                                   middle: '1', repeat2: close, count2: 100000, suffix: ', "candidates": [{"technique": "ssao"}]}'},
                         headers: {'content-type': 'application/json'}, status: 422, expect: ['depth limit']});
  }
  // A pointer 30,000 (and 10,000) levels deep builds a document that deep: refused, naming /set.
  for (const depth of [30000, 10000]) {
    add('deep-nesting', {name: `set pointer ${depth} levels deep`, method: 'POST', path: '/api/v1/jobs',
                         raw_gen: {prefix: `${F}"set": {"`, repeat: '/a', count: depth, suffix: '": 1}}'},
                         headers: {'content-type': 'application/json'}, status: 422, expect: ['/set']});
    add('deep-nesting', {name: `comparison set pointer ${depth} levels deep`, method: 'POST', path: '/api/v1/comparisons',
                         raw_gen: {prefix: '{"scene_file": "sphere_on_plane.json", "candidates": [{"technique": "ssao"}], "set": {"',
                                   repeat: '/a', count: depth, suffix: '": 1}}'},
                         headers: {'content-type': 'application/json'}, status: 422, expect: ['/set']});
  }
  add('deep-nesting', {name: 'set pointer 30000 levels deep into an array', method: 'POST', path: '/api/v1/jobs',
                       raw_gen: {prefix: `${F}"set": {"/objects`, repeat: '/0', count: 30000, suffix: '": 1}}'},
                       headers: {'content-type': 'application/json'}, status: 422, expect: ['/set']});

  const J = (o) => ({method: 'POST', path: '/api/v1/jobs', base: 'file', patch: o});
  for (const [label, raw] of [['priority 2^63', '9223372036854775808'], ['priority -2^63-1', '-9223372036854775809'],
                              ['priority 1e308', '1e308'], ['priority -1e308', '-1e308'], ['priority 1e-7', '1e-7'],
                              ['priority 2^53+1', '9007199254740993'], ['priority 400 digits', '1'.repeat(400)]]) {
    const overflow = /2\^63|400 digits/.test(label);
    add('huge-values', {name: `raw ${label}`, method: 'POST', path: '/api/v1/jobs',
                        raw: `{"scene_file": "sphere_on_plane.json", "priority": ${raw}}`, headers: {'content-type': 'application/json'},
                        status: 422, expect: overflow ? ['/priority', 'outside'] : ['/priority']});
  }
  for (const [label, v, ptr] of [['width 2^31', 2147483648, '/image/width'], ['width 2^53', 9007199254740992, '/image/width'],
                                 ['height -2^31', -2147483648, '/image/height'], ['spp 1e15', 1e15, '/image/spp'],
                                 ['samples 2^32', 4294967296, '/technique/params/samples']]) {
    add('huge-values', {name: `set ${label}`, ...J({'/set': {[ptr]: v}}), status: 422, expect: [ptr]});
  }
  const long = (prefix, r, n, suffix) => ({method: 'POST', path: '/api/v1/jobs', headers: {'content-type': 'application/json'},
                                           raw_gen: {prefix, repeat: r, count: n, suffix}});
  add('huge-values', {name: 'label of 600000 characters', ...long('{"scene_file": "sphere_on_plane.json", "label": "', 'y', 600000, '"}'),
                      status: 422, expect: ['/label']});
  add('huge-values', {name: 'scene_file of 30000 characters', ...long('{"scene_file": "', 's', 30000, '.json"}'),
                      status: 422, expect: ['/scene_file']});
  add('huge-values', {name: 'key of 30000 characters', ...long('{"scene_file": "sphere_on_plane.json", "', 'k', 30000, '": 1}'),
                      status: 422, expect: ['kkkk']});
  add('huge-values', {name: 'set pointer of 30000 characters',
                      ...long('{"scene_file": "sphere_on_plane.json", "set": {"/', 'p', 30000, '": 1}}'), status: 422, expect: ['pppp']});
  const {objects, ...noObjects} = corpus.bases.inline;
  const INL = JSON.stringify(noObjects);
  add('huge-values', {name: 'object name of 20000 characters',
                      ...long(`${INL.slice(0, -1)}, "objects": [{"shape": {"type": "sphere", "center": [0, 1, 0], "radius": 0.5}, "name": "`,
                              'n', 20000, '"}]}'), status: 422, expect: ['/objects/0/name']});
  add('huge-values', {name: 'mesh file of 20000 characters',
                      ...long(`${INL.slice(0, -1)}, "objects": [{"shape": {"type": "mesh", "file": "`, 'm/', 10000, 'x.obj"}}]}'),
                      status: 422, expect: ['/objects/0/shape/file']});
  add('huge-values', {name: '1500 bad objects',
                      ...long(`${INL.slice(0, -1)}, "objects": [`, '{"shape": {"type": "sphere"}}, ', 1500, '{"shape": {"type": "sphere"}}]}'),
                      status: 422, expect: ['/objects/0/shape']});
  add('oversize', {name: 'Content-Length far over --max-body, no body sent', method: 'POST', path: '/api/v1/jobs',
                   raw_http: 'POST /api/v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer @TOKEN@\r\nContent-Type: application/json\r\nContent-Length: 99999999999\r\n\r\n',
                   status: 413, expect: ['max-body']});
  add('oversize', {name: 'comparison body over --max-body', method: 'POST', path: '/api/v1/comparisons',
                   raw_gen: {prefix: '{"scene_file": "sphere_on_plane.json", "label": "', repeat: 'z', count: 1100000, suffix: '"}'},
                   headers: {'content-type': 'application/json'}, status: 413, expect: ['max-body']});
  add('oversize', {name: 'body of spaces over --max-body', method: 'POST', path: '/api/v1/jobs',
                   raw_gen: {prefix: '', repeat: ' ', count: 1100000, suffix: '{}'}, headers: {'content-type': 'application/json'},
                   status: 413, expect: ['max-body']});
  add('oversize', {name: 'chunked body of many small chunks over --max-body', method: 'POST', path: '/api/v1/jobs', chunked: true,
                   raw_gen: {prefix: '[', repeat: '1,', count: 600000, suffix: '1]'}, headers: {'content-type': 'application/json'},
                   status: 413, expect: ['max-body']});

  // Invalid UTF-8 in every kind of string of a body.
  const seqs = [['0xff', [0xff]], ['overlong slash', [0xc0, 0xaf]], ['overlong NUL', [0xc0, 0x80]],
                ['UTF-8 surrogate', [0xed, 0xa0, 0x80]], ['5-byte form', [0xf8, 0x88, 0x80, 0x80, 0x80]],
                ['truncated 3-byte', [0xe2, 0x82]], ['lone continuation', [0x80]], ['above U+10FFFF', [0xf4, 0x90, 0x80, 0x80]]];
  const where = [['label', (b) => ['{"scene_file": "sphere_on_plane.json", "label": "', b, '"}']],
                 ['scene_file', (b) => ['{"scene_file": "sphere', b, '.json"}']],
                 ['a key', (b) => ['{"scene_file": "sphere_on_plane.json", "k', b, '": 1}']],
                 ['a set pointer', (b) => ['{"scene_file": "sphere_on_plane.json", "set": {"/objects/0/name', b, '": "x"}}']],
                 ['a set value', (b) => ['{"scene_file": "sphere_on_plane.json", "set": {"/objects/0/name": "', b, '"}}']],
                 ['an object name', (b) => ['{"camera": {"type": "perspective", "position": [0, 3, -4], "look_at": [0, 0, 0], "fov_y": 45}, "image": {"width": 8, "height": 8}, "objects": [{"name": "', b, '", "shape": {"type": "sphere", "center": [0, 1, 0], "radius": 0.5}}], "technique": {"name": "rt_ao", "backend": "cpu"}}']]];
  for (const [wl, mk] of where) {
    for (const [sl, bytes] of seqs) {
      const [a, , c] = mk();
      const buf = Buffer.concat([Buffer.from(a), Buffer.from(bytes), Buffer.from(c)]);
      add('bad-utf8', {name: `invalid UTF-8 (${sl}) in ${wl}`, method: 'POST', path: '/api/v1/jobs',
                       raw_base64: buf.toString('base64'), headers: {'content-type': 'application/json'},
                       status: 400, expect: ['not valid JSON']});
    }
  }
  for (const [sl, bytes] of seqs.slice(0, 3)) {
    const buf = Buffer.concat([Buffer.from('{"scene_file": "sphere_on_plane.json", "candidates": [{"technique": "ss'),
                               Buffer.from(bytes), Buffer.from('ao"}]}')]);
    add('bad-utf8', {name: `invalid UTF-8 (${sl}) in a comparison`, method: 'POST', path: '/api/v1/comparisons',
                     raw_base64: buf.toString('base64'), headers: {'content-type': 'application/json'},
                     status: 400, expect: ['not valid JSON']});
  }
  add('bad-utf8', {name: 'Content-Type with bytes that are not UTF-8', method: 'POST', path: '/api/v1/jobs',
                   raw_http_base64: Buffer.concat([
                     Buffer.from('POST /api/v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer @TOKEN@\r\nContent-Type: text/pl'),
                     Buffer.from([0xff, 0xfe]), Buffer.from('ain\r\nContent-Length: 2\r\n\r\n{}')]).toString('base64'),
                   status: 415, expect: ['application/json']});
  for (const [label, p, status] of [['job id', '/api/v1/jobs/%FF%FE', 404], ['output name', '/api/v1/jobs/{id}/outputs/ao%C0%AF.png', 404],
                                    ['query value', '/api/v1/jobs?state=%FF', 400], ['query key', '/api/v1/jobs?%FF=1', 400],
                                    ['static path', '/%FF%FE.html', 404], ['comparison id', '/api/v1/comparisons/%ED%A0%80', 404]]) {
    add('bad-utf8', {name: `invalid UTF-8 in a ${label}`, method: 'GET', path: p, status, expect: []});
  }
}

// ---- routes, ids, methods, queries, tokens ----------------------------------------------------

function routes() {
  const notFound = [
    ['/api/v1/jobs/1/', 'no such route'], ['/api/v1/jobs//1', 'no such route'], ['/api/v1/jobs/{id}/cancel/x', 'no such route'],
    ['/api/v1/jobs/{id}/outputs', 'no such route'], ['/api/v1/jobs/{id}/outputs/ao.png/x', 'no such route'],
    ['/api/v1/jobs/{id}/frobnicate', 'no such route'], ['/api/v1/techniques/rt_ao', 'no such route'],
    ['/api/v1/health/x', 'no such route'], ['/api/v1/scenes/sphere_on_plane.json', 'no such route'],
    ['/api/v1/JOBS', 'no such route'], ['/API/v1/jobs', 'not found'],
    ['/api/v1', 'no such route'], ['/api/', 'no such route'], ['/api/v1/comparisons/1/x', 'no such route'],
    ['/api/v1/comparisons//1', 'no such route']];
  for (const [p, msg] of notFound) add('routes', {name: `route ${p}`, method: 'GET', path: p, status: 404, expect: [msg]});
  const ids = [['9223372036854775807', 'no job'], ['9223372036854775808', 'no such job'], ['0x1', 'no such job'],
               ['1e3', 'no such job'], ['%20{id}', 'no such job'], ['{id}%20', 'no such job'], ['%31', ''],
               ['{id}abc', 'no such job'], ['-0', 'no such job'], ['%EF%BC%91', 'no such job'], ['{id};', 'no such job'],
               ['{id}%00', 'no such job']];
  for (const [id, msg] of ids) {
    const st = id === '%31' ? null : 404;
    if (st === null) continue;
    add('bad-ids', {name: `job id ${id}`, method: 'GET', path: `/api/v1/jobs/${id}`, status: 404, expect: msg ? [msg] : []});
    add('bad-ids', {name: `cancel job id ${id}`, method: 'POST', path: `/api/v1/jobs/${id}/cancel`, status: 404, expect: msg ? [msg] : []});
    add('bad-ids', {name: `delete job id ${id}`, method: 'DELETE', path: `/api/v1/jobs/${id}`, status: 404, expect: msg ? [msg] : []});
  }
  for (const id of ['0', '-1', 'abc', '999999', '1.5', '99999999999999999999', '999999.csv', 'x.csv', '.csv']) {
    add('bad-ids', {name: `comparison id ${id}`, method: 'GET', path: `/api/v1/comparisons/${id}`, status: 404, expect: []});
  }
  add('bad-ids', {name: 'output of job 0', method: 'GET', path: '/api/v1/jobs/0/outputs/ao.png', status: 404, expect: []});
  add('bad-ids', {name: 'output summary.json.bak', method: 'GET', path: '/api/v1/jobs/{id}/outputs/summary.json.bak', status: 404, expect: ['no output named']});

  const table = [['/api/v1/jobs', ['GET', 'POST']], ['/api/v1/jobs/{id}', ['GET', 'DELETE']], ['/api/v1/jobs/{id}/cancel', ['POST']],
                 ['/api/v1/jobs/{id}/outputs/ao.png', ['GET']], ['/api/v1/techniques', ['GET']], ['/api/v1/scenes', ['GET']],
                 ['/api/v1/health', ['GET']], ['/metrics', ['GET']], ['/api/v1/comparisons', ['GET', 'POST']],
                 ['/api/v1/comparisons/1', ['GET', 'DELETE']], ['/api/v1/jobs/{id}/retry', ['POST']],
                 ['/api/v1/jobs/{id}/document', ['GET']], ['/api/v1/jobs/{id}/log', ['GET']], ['/', ['GET']], ['/index.html', ['GET']]];
  const have = new Set(corpus.requests.filter((e) => !e.generated && e.status === 405).map((e) => `${e.method} ${e.path}`));
  for (const [p, allow] of table) {
    for (const m of ['GET', 'POST', 'PUT', 'PATCH', 'DELETE', 'OPTIONS']) {
      if (allow.includes(m) || have.has(`${m} ${p}`)) continue;
      add('methods', {name: `${m} on ${p}`, method: m, path: p, status: 405, expect: ['not allowed'], allow});
    }
  }

  const q = [['limit empty', 'limit='], ['limit 1.5', 'limit=1.5'], ['limit -5', 'limit=-5'], ['limit with a space', 'limit=5%20'],
             ['limit twice', 'limit=5&limit=6'], ['limit 2^64', 'limit=18446744073709551616'], ['limit hex', 'limit=0x10'],
             ['after empty', 'after='], ['after abc', 'after=abc'], ['after 1.0', 'after=1.0'], ['after twice', 'after=1&after=2'],
             ['state in capitals', 'state=QUEUED'], ['state empty', 'state='], ['state twice', 'state=queued&state=failed'],
             ['order empty', 'order='], ['order DESC', 'order=DESC'], ['backend empty', 'backend='], ['backend Vulkan', 'backend=Vulkan'],
             ['technique empty', 'technique='], ['technique unknown', 'technique=nope'], ['key without a value', 'limit'],
             ['unknown key with a valid one', 'limit=5&frobnicate=1'], ['encoded key', 'lim%69t=5&x%00=1'],
             ['SQL in state', "state=queued'%20OR%20'1'='1"], ['SQL in technique', "technique=rt_ao'--"]];
  for (const [label, qs] of q) {
    add('queries', {name: `jobs query ${label}`, method: 'GET', path: `/api/v1/jobs?${qs}`, status: 400, expect: []});
  }
  for (const [label, qs] of [['limit 0', 'limit=0'], ['limit abc', 'limit=abc'], ['after 0', 'after=0'], ['after -1', 'after=-1'],
                             ['unknown key', 'frobnicate=1'], ['limit 100000', 'limit=100000']]) {
    add('queries', {name: `comparisons query ${label}`, method: 'GET', path: `/api/v1/comparisons?${qs}`, status: 400, expect: []});
  }

  const tok = corpus.token;
  const auths = [['lowercase bearer scheme and a wrong token', 'bearer x'], ['Bearer alone', 'Bearer'],
                 ['two spaces', `Bearer  ${tok}x`], ['token in quotes', `Bearer "${tok}"`], ['two tokens', `Bearer wrong, Bearer ${tok}`],
                 ['token then garbage', `Bearer ${tok} x`], ['Digest', 'Digest username="a"'], ['a token of 5000 characters', `Bearer ${'t'.repeat(5000)}`],
                 ['token with a NUL escape', `Bearer ${tok.slice(0, 4)}%00`], ['token with a tab', `Bearer\t${tok}x`]];
  for (const [label, h] of auths) {
    add('auth', {name: `auth ${label}`, method: 'GET', path: '/api/v1/jobs', auth: h, status: 401, expect: ['bearer token']});
  }
  for (const [m, p] of [['GET', '/api/v1/jobs/{id}'], ['GET', '/api/v1/techniques'], ['GET', '/api/v1/scenes'],
                        ['GET', '/api/v1/comparisons'], ['GET', '/api/v1/comparisons/1'], ['POST', '/api/v1/comparisons'],
                        ['GET', '/api/v1/jobs/{id}/outputs/summary.json'], ['GET', '/api/v1/nope'], ['PUT', '/api/v1/jobs'],
                        ['GET', '/api/v1/jobs?limit=0']]) {
    add('auth', {name: `${m} ${p} without a token`, method: m, path: p, auth: 'none', status: 401, expect: ['bearer token']});
  }
  add('auth', {name: 'token in the query string', method: 'GET', path: `/api/v1/jobs?token=${tok}`, auth: 'none', status: 401, expect: ['bearer token']});
  add('auth', {name: 'token in a cookie', method: 'GET', path: '/api/v1/jobs', auth: 'none', headers: {cookie: `token=${tok}`}, status: 401, expect: ['bearer token']});
}

// ---- Content-Type, cross-origin, raw HTTP -----------------------------------------------------

function headersAndHttp() {
  for (const [p, base] of [['/api/v1/jobs', 'file'], ['/api/v1/comparisons', 'comparison']]) {
    for (const ct of ['application/jsonp', 'application/json-seq', 'text/plain', 'text/json', 'application/x-json',
                      'application/javascript', 'multipart/form-data; boundary=x', 'application/json5', 'application/jsonx; charset=utf-8',
                      '', 'application/x-www-form-urlencoded']) {
      add('content-type', {name: `${p} with Content-Type "${ct}"`, method: 'POST', path: p, base, patch: {},
                           headers: {'content-type': ct}, status: 415, expect: ['application/json']});
    }
  }
  // No Content-Type at all, with a body: a plain form or fetch from another page sends none.
  for (const [p, base] of [['/api/v1/jobs', 'file'], ['/api/v1/comparisons', 'comparison']]) {
    add('content-type', {name: `${p} with a body and no Content-Type`, method: 'POST', path: p, base, patch: {},
                         no_content_type: true, status: 415, expect: ['application/json']});
  }

  const cross = [['Origin http://evil.example', {origin: 'http://evil.example'}],
                 ['Sec-Fetch-Site cross-site', {'sec-fetch-site': 'cross-site'}],
                 ['Origin null', {origin: 'null'}],
                 ['Origin evil and Sec-Fetch-Site cross-site', {origin: 'http://evil.example', 'sec-fetch-site': 'cross-site'}],
                 ['Origin https://evil.example:8443', {origin: 'https://evil.example:8443'}]];
  for (const [label, h] of cross) {
    add('cross-origin', {name: `job POST from ${label}`, method: 'POST', path: '/api/v1/jobs', base: 'file', patch: {},
                         headers: {'content-type': 'application/json', ...h}, status: 403, expect: []});
    add('cross-origin', {name: `comparison POST from ${label}`, method: 'POST', path: '/api/v1/comparisons', base: 'comparison',
                         patch: {}, headers: {'content-type': 'application/json', ...h}, status: 403, expect: []});
    add('cross-origin', {name: `cancel from ${label}`, method: 'POST', path: '/api/v1/jobs/{id}/cancel', headers: h, status: 403, expect: []});
    add('cross-origin', {name: `delete from ${label}`, method: 'DELETE', path: '/api/v1/jobs/999999', headers: h, status: 403, expect: []});
  }
  add('cross-origin', {name: 'job POST as a text/plain form from another origin', method: 'POST', path: '/api/v1/jobs', base: 'file',
                       patch: {}, headers: {'content-type': 'text/plain', origin: 'http://evil.example', 'sec-fetch-site': 'cross-site'},
                       status: [403, 415], expect: []});

  const H = 'Host: 127.0.0.1\r\nAuthorization: Bearer @TOKEN@\r\n';
  const JB = '{"scene_file": "sphere_on_plane.json"}';
  const raw = [
    ['two different Content-Length headers', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nContent-Length: 2\r\nContent-Length: ${JB.length}\r\n\r\n${JB}`, 400],
    ['two equal Content-Length headers', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nContent-Length: ${JB.length}\r\nContent-Length: ${JB.length}\r\n\r\n${JB}`, 400],
    ['Transfer-Encoding gzip, chunked', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nTransfer-Encoding: gzip, chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n`, [400, 501]],
    ['Transfer-Encoding gzip', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nTransfer-Encoding: gzip\r\n\r\n`, [400, 501]],
    ['Transfer-Encoding chunked twice', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nTransfer-Encoding: chunked, chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n`, [400, 501]],
    ['Transfer-Encoding and Content-Length', `POST /api/v1/jobs HTTP/1.1\r\n${H}Content-Type: application/json\r\nContent-Length: 7\r\nTransfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n`, [400, 422]],
    ['HTTP/1.1 without Host', `GET /api/v1/health HTTP/1.1\r\nAuthorization: Bearer @TOKEN@\r\n\r\n`, 400],
    ['HTTP/1.1 POST without Host', `POST /api/v1/jobs HTTP/1.1\r\nAuthorization: Bearer @TOKEN@\r\nContent-Type: application/json\r\nContent-Length: ${JB.length}\r\n\r\n${JB}`, 400],
  ];
  for (const [label, text, status] of raw) {
    add('raw-http', {name: `raw HTTP: ${label}`, method: text.split(' ')[0], path: text.split(' ')[1], raw_http: text, status, expect: []});
  }
}

sceneFields();
techniqueParams();
wrappers();
jsonSyntax();
depthAndSize();
routes();
headersAndHttp();

// Hand-written entries keep their place; their class comes from what they test.
function classOf(e) {
  if (e.class) return e.class;
  const n = e.name.toLowerCase();
  if (e.status === 401) return 'auth';
  if (e.status === 405) return 'methods';
  if (e.status === 413) return 'oversize';
  if (e.status === 415) return 'content-type';
  if (/travers|absolute|\.\.|encoded|backslash|hidden|nul/.test(n) && e.method === 'GET') return 'traversal';
  if (/travers|absolute|\.\.|percent|slash|backslash|hidden/.test(n)) return 'traversal';
  if (e.path.includes('?')) return 'queries';
  if (/job id|no such|output|range|cancel|delete/.test(n) || e.status === 404 || e.status === 409 || e.status === 416) return 'bad-ids';
  if (e.status === 400) return /nesting/.test(n) ? 'deep-nesting' : /utf|surrogate/.test(n) ? 'bad-utf8' : 'json-syntax';
  if (/max-|over --|triangles/.test(n)) return 'limits';
  if (e.base === 'inline') return 'scene-field-types';
  return 'wrapper-fields';
}
const hand = corpus.requests.filter((e) => !e.generated).map((e) => ({name: e.name, class: classOf(e), ...e}));
for (const e of hand) {
  if (names.has(e.name)) throw new Error(`generated name collides with a hand-written entry: ${e.name}`);
}
corpus.bases.comparison = COMPARISON;
corpus.requests = [...hand, ...out];

// One request per line, as the hand-written part was laid out.
const head = {...corpus};
delete head.requests;
let text = JSON.stringify(head, null, 2).replace(/\n}$/, ',\n  "requests": [\n');
text += corpus.requests.map((e) => `    ${JSON.stringify(e)}`).join(',\n');
text += '\n  ]\n}\n';
fs.writeFileSync(CORPUS, text);
const byClass = {};
for (const e of corpus.requests) byClass[e.class] = (byClass[e.class] || 0) + 1;
console.log(`${corpus.requests.length} requests (${hand.length} hand-written, ${out.length} generated):`,
            Object.entries(byClass).map(([k, v]) => `${k} ${v}`).join(', '));
