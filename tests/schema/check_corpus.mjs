#!/usr/bin/env node
// Checks the scene corpus with two validators side by side: ajv (JSON Schema 2020-12, the schema in
// schema/scene.schema.json) and the C loader through `obscura validate FILE`.
//
//   node tests/schema/check_corpus.mjs <path-to-obscura-cli> <repo-root>
//
// Expectations:
//   scenes/*.json, tests/corpus/scene_good/*.json   ajv valid,    CLI exit 0
//   tests/corpus/scene_bad/*.json                   ajv invalid,  CLI exit 2, output names the file
//                                                                 and a JSON pointer ("<file>: /...")
//   tests/corpus/scene_semantic/*.json              ajv valid,    CLI exit 2, same output rule
// plus checks that every technique of `obscura techniques` is in the schema with the same
// parameters (descriptions aside).
// Prints one line per check and finally "N passed, M failed"; exits 1 when M > 0.
// Only node built-ins and ajv (resolved from <repo-root>/node_modules) are used.

import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import {createRequire} from 'node:module';
import path from 'node:path';

const CLI_TIMEOUT_MS = 60_000;
const EXIT_INVALID = 2;

function usage(msg) {
  if (msg) console.error(`check_corpus: ${msg}`);
  console.error('usage: node tests/schema/check_corpus.mjs <path-to-obscura-cli> <repo-root>');
  process.exit(64);
}

const [cliArg, rootArg] = process.argv.slice(2);
if (!cliArg || !rootArg || process.argv.length > 4) usage();
const cli = path.resolve(cliArg);
const root = path.resolve(rootArg);
if (!fs.existsSync(path.join(root, 'schema', 'scene.schema.json'))) {
  usage(`${root} has no schema/scene.schema.json`);
}

let passed = 0;
let failed = 0;
function report(ok, label, detail) {
  if (ok) passed++;
  else failed++;
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${label}${detail ? `: ${detail}` : ''}`);
}
function finish() {
  console.log(`${passed} passed, ${failed} failed`);
  process.exit(failed > 0 ? 1 : 0);
}

// ---- ajv ------------------------------------------------------------------------------------

let validate;
let schema;
try {
  const requireFromRoot = createRequire(path.join(root, 'package.json'));
  const mod = requireFromRoot('ajv/dist/2020.js');
  const Ajv2020 = mod.default ?? mod;
  schema = JSON.parse(fs.readFileSync(path.join(root, 'schema', 'scene.schema.json'), 'utf8'));
  // strict: unknown keywords, ignored defaults, untyped keywords and stray `required` names throw.
  // Union types are allowed for max_distance (number or null).
  const ajv = new Ajv2020({strict: true, allErrors: true, allowUnionTypes: true});
  validate = ajv.compile(schema);
} catch (e) {
  report(false, 'schema/scene.schema.json compiles (ajv strict, draft 2020-12)',
         `${e.message.split('\n')[0]}${e.code === 'MODULE_NOT_FOUND' ? ' (run npm ci in the repo root)' : ''}`);
  finish();
}

// Where each ajv error points: the member itself for missing/unknown members.
function ajvLocations(errors) {
  return errors.map((e) => {
    const p = e.params ?? {};
    const name = p.missingProperty ?? p.additionalProperty ?? p.unevaluatedProperty;
    if (name === undefined) return e.instancePath;
    return `${e.instancePath}/${String(name).replace(/~/g, '~0').replace(/\//g, '~1')}`;
  });
}
function ajvSummary(errors, max = 3) {
  const parts = errors
    .filter((e) => e.keyword !== 'if') // "must match then schema" only repeats the real error
    
    .map((e) => `${ajvLocations([e])[0] || '(root)'} ${e.keyword}`);
  const uniq = [...new Set(parts)];
  return uniq.slice(0, max).join(', ') + (uniq.length > max ? `, +${uniq.length - max}` : '');
}

// ---- CLI ------------------------------------------------------------------------------------

function runCli(args) {
  const r = spawnSync(cli, args, {encoding: 'utf8', timeout: CLI_TIMEOUT_MS, maxBuffer: 16 << 20});
  if (r.error) {
    const why = r.error.code === 'ENOENT' ? `${cli} not found` :
                r.error.code === 'ETIMEDOUT' ? `timed out after ${CLI_TIMEOUT_MS / 1000} s` :
                r.error.message;
    return {error: why, status: r.status, out: `${r.stdout ?? ''}${r.stderr ?? ''}`};
  }
  const how = r.status === null ? `killed by ${r.signal}` : `exit ${r.status}`;
  return {status: r.status, how, stdout: r.stdout, out: `${r.stdout}${r.stderr}`};
}

function firstLines(text, n = 3) {
  const lines = text.split('\n').filter((l) => l.trim() !== '');
  return lines.slice(0, n).join(' | ') + (lines.length > n ? ` | (+${lines.length - n} lines)` : '');
}

// Pointers from "<...name>: </pointer>: <rule> (got <value>)" lines that mention `base`.
function cliPointers(out, base) {
  const ptrs = [];
  const marker = `${base}: /`;
  for (const line of out.split('\n')) {
    const at = line.indexOf(marker);
    if (at < 0) continue;
    const rest = line.slice(at + base.length + 2);
    const end = rest.indexOf(': ');
    ptrs.push(end < 0 ? rest.trim() : rest.slice(0, end));
  }
  return ptrs;
}

// Two pointers are related when one is the other or a parent of it (segment-wise).
function related(a, b) {
  return a === b || a.startsWith(`${b}/`) || b.startsWith(`${a}/`) || a === '' || b === '';
}

// ---- corpus -----------------------------------------------------------------------------------

function listJson(dir, required) {
  const abs = path.join(root, dir);
  if (!fs.existsSync(abs)) {
    if (required) report(false, `${dir}/`, 'folder missing');
    return [];
  }
  const files = fs.readdirSync(abs).filter((f) => f.endsWith('.json')).sort();
  if (files.length === 0 && required) report(false, `${dir}/`, 'no *.json files');
  return files.map((f) => ({abs: path.join(abs, f), rel: `${dir}/${f}`, base: f}));
}

function readDoc(file) {
  try {
    return {doc: JSON.parse(fs.readFileSync(file.abs, 'utf8'))};
  } catch (e) {
    return {error: `not parseable JSON (${e.message})`};
  }
}

// kind: 'good' (both accept), 'bad' (both reject), 'semantic' (ajv accepts, CLI rejects)
function checkFile(file, kind) {
  const {doc, error} = readDoc(file);
  if (error) return report(false, file.rel, error);
  const problems = [];
  const notes = [];

  const ajvOk = validate(doc);
  const ajvErrors = ajvOk ? [] : [...validate.errors];
  if (kind === 'bad' && ajvOk) problems.push('ajv accepts it, expected rejection');
  if (kind !== 'bad' && !ajvOk) problems.push(`ajv rejects it: ${ajvSummary(ajvErrors)}`);

  const r = runCli(['validate', file.abs]);
  let ptrs = [];
  if (r.error) {
    problems.push(`CLI: ${r.error}`);
  } else if (kind === 'good') {
    if (r.status !== 0) problems.push(`CLI ${r.how}, expected exit 0: ${firstLines(r.out)}`);
  } else {
    ptrs = cliPointers(r.out, file.base);
    if (r.status !== EXIT_INVALID) {
      problems.push(`CLI ${r.how}, expected exit ${EXIT_INVALID}: ${firstLines(r.out)}`);
    } else if (ptrs.length === 0 &&
               !(kind === 'semantic' && new RegExp(`${file.base}: line \\d+, column \\d+: invalid JSON`).test(r.out))) {
      // Documents that JSON.parse accepts but a strict parser must not (duplicate keys, lone
      // surrogates) have no pointer: the C loader names the line and column instead.
      problems.push(`CLI output has no "${file.base}: /<pointer>: ..." line: ${firstLines(r.out)}`);
    }
  }

  if (kind === 'bad' && !ajvOk && ptrs.length > 0) {
    // Not a failure: both reject, but they may disagree about where the problem is.
    const locs = ajvLocations(ajvErrors);
    if (!ptrs.some((p) => locs.some((l) => related(p, l)))) {
      notes.push(`note: pointers differ (ajv ${[...new Set(locs)].join(' ')}; CLI ${ptrs.join(' ')})`);
    }
  }

  let detail;
  if (problems.length > 0) detail = problems.join('; ');
  else if (kind === 'bad') detail = `ajv ${ajvSummary(ajvErrors, 2)}; CLI ${ptrs.slice(0, 2).join(' ')}`;
  else if (kind === 'semantic') detail = `CLI ${ptrs.slice(0, 2).join(' ')}`;
  if (notes.length > 0) detail = `${detail ? `${detail}; ` : ''}${notes.join('; ')}`;
  report(problems.length === 0, file.rel, detail);
}

for (const f of listJson('scenes', false)) checkFile(f, 'good');
for (const f of listJson('tests/corpus/scene_good', true)) checkFile(f, 'good');
for (const f of listJson('tests/corpus/scene_bad', true)) checkFile(f, 'bad');
for (const f of listJson('tests/corpus/scene_semantic', true)) checkFile(f, 'semantic');

// ---- technique parameters: schema vs registry -----------------------------------------------

function stripDescriptions(v) {
  if (Array.isArray(v)) return v.map(stripDescriptions);
  if (v !== null && typeof v === 'object') {
    const o = {};
    for (const [k, x] of Object.entries(v)) if (k !== 'description') o[k] = stripDescriptions(x);
    return o;
  }
  return v;
}

// Differences between two JSON values as "path: a vs b" strings (key order ignored).
function diff(a, b, at = '', out = []) {
  const kind = (v) => (v === null ? 'null' : Array.isArray(v) ? 'array' : typeof v);
  if (kind(a) !== kind(b)) {
    out.push(`${at || '/'}: ${JSON.stringify(a)} vs ${JSON.stringify(b)}`);
  } else if (kind(a) === 'array') {
    if (a.length !== b.length) out.push(`${at || '/'}: ${JSON.stringify(a)} vs ${JSON.stringify(b)}`);
    else a.forEach((x, i) => diff(x, b[i], `${at}/${i}`, out));
  } else if (kind(a) === 'object') {
    for (const k of new Set([...Object.keys(a), ...Object.keys(b)])) {
      if (!(k in a)) out.push(`${at}/${k}: missing in schema`);
      else if (!(k in b)) out.push(`${at}/${k}: missing in registry`);
      else diff(a[k], b[k], `${at}/${k}`, out);
    }
  } else if (a !== b) {
    out.push(`${at || '/'}: ${JSON.stringify(a)} vs ${JSON.stringify(b)}`);
  }
  return out;
}

// Every registry technique appears in the schema: its name in the technique enum, its parameters
// as $defs/<name>_params (equal to the registry's params_schema.properties, descriptions aside)
// and an if/then selecting them. One check per technique, plus one for the name list.
(function checkRegistry() {
  const r = runCli(['techniques']);
  const fail = (label, why) => report(false, label, why);
  if (r.error) return fail('registry', `CLI: ${r.error}`);
  if (r.status !== 0) return fail('registry', `CLI ${r.how}: ${firstLines(r.out)}`);
  let list;
  try {
    list = JSON.parse(r.stdout);
  } catch (e) {
    return fail('registry', `output is not JSON (${e.message})`);
  }
  if (!Array.isArray(list)) return fail('registry', 'output is not a JSON array');
  const names = list.map((t) => t && t.name).filter(Boolean);
  const enumNames = schema.$defs?.technique?.properties?.name?.enum || [];
  const nd = diff([...enumNames].sort(), [...names].sort());
  report(nd.length === 0, 'schema technique names == registry names',
         nd.length ? `schema ${JSON.stringify(enumNames)} vs registry ${JSON.stringify(names)}` : '');
  const branches = schema.$defs?.technique?.allOf || [];
  for (const entry of list) {
    const name = entry.name;
    const label = `schema $defs/${name}_params/properties == registry ${name} params_schema.properties`;
    const ps = typeof entry.params_schema === 'string' ? JSON.parse(entry.params_schema)
                                                       : entry.params_schema;
    if (!ps || typeof ps !== 'object' || !ps.properties) {
      fail(label, 'params_schema has no properties object');
      continue;
    }
    const mine = schema.$defs?.[`${name}_params`]?.properties;
    if (!mine) {
      fail(label, `schema has no $defs/${name}_params/properties`);
      continue;
    }
    const branch = branches.find((b) => b?.if?.properties?.name?.const === name);
    if (branch?.then?.properties?.params?.$ref !== `#/$defs/${name}_params`) {
      fail(label, `schema has no if/then selecting #/$defs/${name}_params for "${name}"`);
      continue;
    }
    const d = diff(stripDescriptions(mine), stripDescriptions(ps.properties));
    report(d.length === 0, label, d.length ? `schema vs registry: ${d.slice(0, 6).join('; ')}` : '');
  }
})();

finish();
