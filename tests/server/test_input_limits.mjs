// Input limits: deep `set` pointers, deep bodies and bodies of millions of values are refused with
// a 422 naming where and which limit, before the JSON parser builds them, so the daemon neither
// crashes (stack overflow in recursive dump/free) nor swells (a parsed value costs ~20x its text);
// numbers that a double would hold as another value are refused with their pointer; problems
// name a scene's files relative to the scenes directory; and a read-only data or database
// directory at start is named with the reason.
//
//   node tests/server/test_input_limits.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {test} from 'node:test';

import {SCENES_DIR, SLOW, getJSON, request, sql, startDaemon, validate, withDaemon} from './lib.mjs';

const MiB = 1024 * 1024;

// Nothing was stored: no job, no comparison, no output.
function assertNothingStored(d) {
  assert.deepEqual(sql(d.db, 'SELECT count(*) FROM jobs'), [['0']]);
  assert.deepEqual(sql(d.db, 'SELECT count(*) FROM comparisons'), [['0']]);
}

async function assertAlive(d) {
  assert.equal(d.exit, null, `obscurad exited: ${JSON.stringify(d.exit)}`);
  const h = await getJSON(d, '/api/v1/health');
  assert.equal(h.status, 'ok');
}

function assertProblem(r, re) {
  assert.equal(r.status, 422, `${r.status} ${r.text.slice(0, 500)}`);
  validate('Error', r.json);
  assert.ok(r.json.problems.some((p) => re.test(p)), `no problem matches ${re}: ${JSON.stringify(r.json.problems).slice(0, 800)}`);
  // Never blamed on the bundled file's syntax (the deep document the pointer would have built).
  assert.ok(!r.json.problems.some((p) => /invalid JSON|maximum parsing depth/.test(p)), JSON.stringify(r.json.problems).slice(0, 800));
  // Problems stay readable: a 60 KB pointer is shortened.
  assert.ok(r.text.length < 4000, `answer of ${r.text.length} bytes`);
}

test('a 30,000-level set pointer is a 422 naming /set/..., for jobs and comparisons', async () => {
  await withDaemon({}, async (d) => {
    const deep = '/a'.repeat(30000);
    const job = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: {[deep]: 1}}});
    assertProblem(job, /^request: \/set\/~1a~1a~1a.*\.\.\.: pointer "\/a\/a.*has 30000 reference tokens; at most 32/);
    // An inline scene goes the same way.
    const inline = await request(d, 'POST', '/api/v1/jobs', {body: {camera: {}, set: {[deep]: 1}}});
    assertProblem(inline, /^request: \/set\/~1a~1a.*has 30000 reference tokens/);
    const cmp = await request(d, 'POST', '/api/v1/comparisons', {
      body: {scene_file: 'sphere_on_plane.json', set: {[deep]: 1}, candidates: [{technique: 'rt_ao', backend: 'cpu'}]},
    });
    assertProblem(cmp, /^request: \/set\/~1a~1a.*has 30000 reference tokens/);
    // 31 tokens pass the pointer bound, but a deep value under them makes the document too deep.
    const p31 = '/a'.repeat(31);
    const over = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: {[p31]: [[1]]}}});
    assertProblem(over, /^sphere_on_plane\.json: \/a\/a\/a.*nested deeper than 32/);
    await assertAlive(d);
    assertNothingStored(d);
  });
});

// A number is what its text says, or refused: JSON parsers store numbers as doubles, and a text
// that becomes another value (1e-99999 becomes 0, which priority, a radius or a weight would take
// as given) is a 422 naming its pointer, in every field of jobs and comparisons alike.
test('numbers a double would hold as another value are refused with their pointer', async () => {
  await withDaemon({}, async (d) => {
    const raw = (text) => request(d, 'POST', '/api/v1/jobs', {body: text});
    assertProblem(await raw('{"scene_file": "sphere_on_plane.json", "priority": 1e-99999}'),
                  /^request: \/priority: nonzero number too small for a double .*\(got 1e-99999; it would be read as 0\)$/);
    assertProblem(await raw('{"scene_file": "sphere_on_plane.json", "priority": 49.99999999999999999}'),
                  /^request: \/priority: fraction that a double rounds to a whole number \(got 49\.99999999999999999; it would be read as 50\)$/);
    assertProblem(await raw('{"scene_file": "sphere_on_plane.json", "set": {"/technique/params/samples": 9007199254740993}}'),
                  /^request: \/set\/~1technique~1params~1samples: integer a double cannot hold exactly .*it would be read as 9007199254740992\)$/);
    // Inside an inline scene and a comparison's candidates.
    const doc = fs.readFileSync(path.join(SCENES_DIR, 'sphere_on_plane.json'), 'utf8');
    assertProblem(await raw(doc.replace('"radius": 0.5', '"radius": 5e-400')), /^request: \/objects\/1\/shape\/radius: nonzero number too small/);
    const cmp = await request(d, 'POST', '/api/v1/comparisons',
                              {body: '{"scene_file": "sphere_on_plane.json", "candidates": [{"technique": "rt_ao", "backend": "cpu", "params": {"samples": [4, 1e-99999]}}]}'});
    assertProblem(cmp, /^request: \/candidates\/0\/params\/samples\/1: nonzero number too small/);
    // A syntax error is still one (400), whatever its numbers.
    assert.equal((await raw('{"scene_file": "sphere_on_plane.json", "priority": 1e-99999')).status, 400);
    // Small and precise numbers that are themselves pass.
    const ok = await raw('{"scene_file": "sphere_on_plane.json", "priority": 50.0, "set": {"/image/width": 16, "/image/height": 16, "/camera/position/0": 1e-300, "/technique/params/samples": 4}}');
    assert.equal(ok.status, 201, ok.text);
    await assertAlive(d);
  });
});

// A 422 names a scene's file as the scene does, never by where the server keeps it.
test('problems name files relative to the scenes directory', async () => {
  await withDaemon({}, async (d) => {
    const raw = {scene_file: 'volume_head.json', set: {'/objects/0/shape/format': 'raw', '/objects/0/shape/data_type': 'uint8',
                                                       '/objects/0/shape/dims': [2, 2, 2]}};
    const nrrd = {scene_file: 'volume_head.json', set: {'/objects/0/shape/format': 'nrrd'}};
    for (const body of [raw, nrrd]) {
      const r = await request(d, 'POST', '/api/v1/jobs', {body});
      assertProblem(r, /^volume_head\.json: \/objects\/0\/shape\/file: models\/brainsmall\.den: /);
      assert.ok(!r.text.includes(SCENES_DIR) && !r.text.includes(fs.realpathSync(SCENES_DIR)), `the answer names the scenes directory: ${r.text}`);
    }
    assertNothingStored(d);
  });
});

test('a 100,000-deep body is a 422 with the depth limit and a location', async () => {
  await withDaemon({}, async (d) => {
    for (const [open, close, where] of [['[', ']', /^request: \/0\/0\/0/], ['{"a":', '}', /^request: \/a\/a\/a/]]) {
      const body = open.repeat(100000) + '1' + close.repeat(100000);
      const r = await request(d, 'POST', '/api/v1/jobs', {body, headers: {'content-type': 'application/json'}});
      assertProblem(r, where);
      assertProblem(r, /nested deeper than 32 arrays\/objects \(the depth limit\)/);
      const c = await request(d, 'POST', '/api/v1/comparisons', {body, headers: {'content-type': 'application/json'}});
      assertProblem(c, /nested deeper than 32/);
    }
    await assertAlive(d);
    assertNothingStored(d);
  });
});

function memory(pid) {
  const s = fs.readFileSync(`/proc/${pid}/status`, 'utf8');
  const kib = (k) => Number(s.match(new RegExp(`${k}:\\s+(\\d+) kB`))[1]) * 1024;
  return {hwm: kib('VmHWM'), rss: kib('VmRSS')};
}

// Peak RSS is read from the kernel's high-water mark, each case on a fresh daemon (the upload
// buffers of earlier requests stay in their threads' malloc arenas). The bound, 2x idle RSS + 2x
// the bytes in flight, is generous against allocator noise but far below what parsing these
// bodies cost (an 8M-integer body took the peak from 68 MB to over 1 GB). Under ASan freed memory
// sits in its quarantine, so only the answers are checked there.
test('16 MiB bodies of 8M integers, one string or small objects: refused, peak RSS bounded', async () => {
  const size = 16 * MiB;
  const ints = '[' + '1,'.repeat(size / 2 - 2) + '1]';
  const inObject = '{"objects":[' + '1,'.repeat(size / 2 - 8) + '1]}';
  const str = '"' + 'a'.repeat(size - 3) + '"';
  const objects = '[' + '{},'.repeat(Math.floor(size / 3) - 1) + '{}]';
  const cases = [['integers', [ints], /more than 100000 JSON values/],
                 ['integers in an object', [inObject], /^request: \/objects\/99998: more than 100000 JSON values/],
                 ['one string', [str], /string of \d+ bytes; at most 65536/],
                 ['small objects', [objects], /more than 100000 JSON values/],
                 ['two bodies of integers at once', [inObject, inObject], /more than 100000 JSON values/]];
  for (const [name, bodies, re] of cases) {
    await withDaemon({args: ['--max-body', String(size)]}, async (d) => {
      await getJSON(d, '/api/v1/health');
      const idle = memory(d.proc.pid).rss;
      const answers = await Promise.all(bodies.map((body, i) => {
        assert.ok(Buffer.byteLength(body) <= size, `${name}: ${Buffer.byteLength(body)} bytes`);
        return request(d, 'POST', i ? '/api/v1/comparisons' : '/api/v1/jobs', {body, headers: {'content-type': 'application/json'}});
      }));
      for (const r of answers) {
        assert.ok(r.status === 413 || r.status === 422, `${name}: ${r.status} ${r.text.slice(0, 300)}`);
        if (r.status === 422) assertProblem(r, re);
      }
      const m = memory(d.proc.pid);
      const bound = 2 * idle + 2 * size * bodies.length;
      console.log(`# ${name}: idle RSS ${(idle / MiB).toFixed(1)} MiB, peak ${(m.hwm / MiB).toFixed(1)} MiB, ` +
                  `after ${(m.rss / MiB).toFixed(1)} MiB (bound ${(bound / MiB).toFixed(1)} MiB)`);
      if (SLOW === 1) assert.ok(m.hwm <= bound, `${name}: peak RSS ${m.hwm} > ${bound}`);
      else console.log('# (bound not checked under ASan: its quarantine keeps freed memory)');
      await assertAlive(d);
      assertNothingStored(d);
    });
  }
  // A legitimate job still goes through under the same options.
  await withDaemon({args: ['--max-body', String(size)]}, async (d) => {
    const ok = await request(d, 'POST', '/api/v1/jobs', {body: {scene_file: 'sphere_on_plane.json', set: {'/image/width': 16, '/image/height': 16}}});
    assert.equal(ok.status, 201, ok.text);
  });
});

// A grid of 256 candidates whose entry also carries a large parameter object (not a list, so not
// a grid key): candidates share the entry's parameters, and their documents' values count
// towards the comparison's bound before anything is copied per candidate.
test('a comparison grid over a large parameter object is refused without a copy per candidate', async () => {
  const junk = {};
  for (let i = 0; i < 90000; i++) junk[`k${i}`] = i;
  const body = {scene_file: 'cornell_box.json', candidates: [{technique: 'ssao', params: {
    radius: Array.from({length: 64}, (_, i) => 0.1 + i / 100), samples: [4, 8, 12, 16], junk}}]};
  await withDaemon({args: ['--max-body', String(4 * MiB)]}, async (d) => {
    await getJSON(d, '/api/v1/health');
    const idle = memory(d.proc.pid).rss;
    const r = await request(d, 'POST', '/api/v1/comparisons', {body});
    assert.equal(r.status, 422, r.text.slice(0, 300));
    const m = memory(d.proc.pid);
    const bound = 2 * idle + 2 * 4 * MiB;
    console.log(`# grid over a large object: idle ${(idle / MiB).toFixed(1)} MiB, peak ${(m.hwm / MiB).toFixed(1)} MiB (bound ${(bound / MiB).toFixed(1)} MiB)`);
    if (SLOW === 1) assert.ok(m.hwm <= bound, `peak RSS ${m.hwm} > ${bound}`);
    await assertAlive(d);
    assertNothingStored(d);
  });
});

// Tests run as root, for whom chmod restricts nothing: a read-only tmpfs is the read-only
// directory. Skipped (with the reason) where mounting is not allowed.
function mountReadOnly(dir, prepare) {
  fs.mkdirSync(dir, {recursive: true});
  let r = spawnSync('mount', ['-t', 'tmpfs', '-o', 'size=1m', 'tmpfs', dir], {encoding: 'utf8'});
  if (r.status !== 0) return `mount -t tmpfs failed: ${(r.stderr || r.error || '').toString().trim()}`;
  if (prepare) prepare(dir);
  r = spawnSync('mount', ['-o', 'remount,ro', dir], {encoding: 'utf8'});
  if (r.status !== 0) {
    spawnSync('umount', [dir]);
    return `remount,ro failed: ${(r.stderr || '').trim()}`;
  }
  return null;
}

async function startFails(args, re) {
  let log = '';
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-test-'));
  await assert.rejects(startDaemon({args, dir}), (e) => {
    log = e.message;
    return /exited .* before listening/.test(e.message);
  });
  fs.rmSync(dir, {recursive: true, force: true});
  assert.match(log, re);
  assert.doesNotMatch(log, /^obscurad: [^\n]*unable to open database file\s*$/m);
  return log;
}

test('a read-only data or database directory at start is named, with the reason', async (t) => {
  const base = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-ro-'));
  const ro = path.join(base, 'ro');
  const why = mountReadOnly(ro, (dir) => {
    // An existing database: SQLite opens it read-only and fails at the first write.
    fs.mkdirSync(path.join(dir, 'old'));
    const r = spawnSync('sqlite3', [path.join(dir, 'old', 'obscura.db'), 'CREATE TABLE t (x INTEGER);']);
    assert.equal(r.status, 0, String(r.stderr));
  });
  if (why) {
    t.skip(why);
    fs.rmSync(base, {recursive: true, force: true});
    return;
  }
  try {
    const data = await startFails(['--data-dir', ro], new RegExp(`--data-dir ${ro}: cannot create ${ro}/results: Read-only file system \\(the data directory is on a read-only file system\\)`));
    console.log(`# ${data.split('\n').find((l) => l.includes('--data-dir'))}`);
    const db = path.join(ro, 'obscura.db');
    const fresh = await startFails(['--db', db], new RegExp(`cannot open database ${db}: the directory ${ro} is on a read-only file system \\(EROFS\\)`));
    console.log(`# ${fresh.split('\n').find((l) => l.includes('cannot open database'))}`);
    const olddb = path.join(ro, 'old', 'obscura.db');
    const old = await startFails(['--db', olddb], new RegExp(`cannot open database ${olddb}: the directory ${ro}/old is on a read-only file system \\(EROFS\\)`));
    console.log(`# ${old.split('\n').find((l) => l.includes('cannot open database'))}`);
  } finally {
    const r = spawnSync('umount', [ro], {encoding: 'utf8'});
    assert.equal(r.status, 0, `umount ${ro}: ${r.stderr}`);
    fs.rmSync(base, {recursive: true, force: true});
  }
});
