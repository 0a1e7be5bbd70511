// Health-check latency of obscurad under a slow-client (slowloris) attack: N sockets each
// trickling one byte of a never-ending request header every 2 s, reopened as soon as the daemon
// closes them, while GET /api/v1/health is timed on fresh connections from 127.0.0.1. Prints
// p50/p99/max for no attack, the attack from 127.0.0.1, and the attack spread over
// 127.0.0.2..127.0.0.9, each with the daemon's default limits.
//
//   cmake -S . -B build -DCMAKE_BUILD_TYPE=Release && cmake --build build --target obscurad
//   node bench/bench_slow_clients.mjs [--obscurad build/obscurad] [--clients 1000]
//                                     [--requests 200] [--no-reconnect] [-- extra daemon options]
import {spawn} from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import {fileURLToPath} from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function parseArgs(argv) {
  const o = {obscurad: path.join(ROOT, 'build/obscurad'), clients: 1000, requests: 200, reconnect: true, extra: []};
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i], v = () => argv[++i];
    if (a === '--obscurad') o.obscurad = path.resolve(v());
    else if (a === '--clients') o.clients = Number(v());
    else if (a === '--requests') o.requests = Number(v());
    else if (a === '--no-reconnect') o.reconnect = false;
    else if (a === '--') {
      o.extra = argv.slice(i + 1);
      break;
    } else throw new Error(`unknown argument ${a} (see the comment at the top of this file)`);
  }
  if (!(o.clients >= 1 && o.clients <= 20000) || !(o.requests >= 1 && o.requests <= 100000)) throw new Error('--clients 1..20000, --requests 1..100000');
  return o;
}

async function startDaemon(o, extra) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'obsd-bench-slow-'));
  const proc = spawn(o.obscurad, ['--listen', '127.0.0.1', '--port', '0', '--data-dir', dir, '--db', path.join(dir, 'obscura.db'),
                                  '--scenes-dir', path.join(ROOT, 'scenes'), '--web-dir', path.join(ROOT, 'web'),
                                  '--no-vulkan', '--quiet', ...o.extra, ...extra], {stdio: ['ignore', 'pipe', 'pipe']});
  let log = '';
  proc.stdout.on('data', (b) => (log += b));
  proc.stderr.on('data', (b) => (log += b));
  for (let i = 0; i < 3000; i++) {
    const m = /listening on http:\/\/127\.0\.0\.1:(\d+)/.exec(log);
    if (m) return {proc, dir, port: Number(m[1]), log: () => log};
    if (proc.exitCode !== null) throw new Error(`obscurad exited: ${log}`);
    await sleep(10);
  }
  proc.kill('SIGKILL');
  throw new Error(`obscurad did not start: ${log}`);
}

/** Slow clients; each one closed by the daemon is reopened while `reconnect` holds. */
function attack(port, count, addresses, reconnect) {
  const text = `GET /api/v1/health HTTP/1.1\r\nHost: 127.0.0.1:${port}\r\nX-Slow: ${'a'.repeat(4000)}`;
  const live = new Set();
  let stopped = false;
  let closedByServer = 0;
  const open = (i) => {
    const s = net.connect({host: '127.0.0.1', port, localAddress: addresses[i % addresses.length]});
    const c = {s, pos: 0};
    live.add(c);
    s.once('connect', () => s.write(text[c.pos++]));
    s.on('error', () => {});
    s.on('close', () => {
      live.delete(c);
      if (stopped) return;
      closedByServer++;
      if (reconnect) setTimeout(() => !stopped && open(i), 10);
    });
  };
  for (let i = 0; i < count; i++) open(i);
  const timer = setInterval(() => {
    for (const c of live) if (c.pos < text.length && c.s.writable) c.s.write(text[c.pos++]);
  }, 2000);
  return {
    open: () => live.size,
    closed: () => closedByServer,
    stop: () => {
      stopped = true;
      clearInterval(timer);
      for (const c of live) c.s.destroy();
    },
  };
}

function healthOnce(port) {
  return new Promise((resolve, reject) => {
    const t0 = performance.now();
    const req = http.get({host: '127.0.0.1', port, path: '/api/v1/health', agent: false, localAddress: '127.0.0.1', timeout: 10000}, (res) => {
      res.resume();
      res.on('end', () => (res.statusCode === 200 ? resolve(performance.now() - t0) : reject(new Error(`health answered ${res.statusCode}`))));
    });
    req.on('timeout', () => req.destroy(new Error('health: no answer within 10 s')));
    req.on('error', reject);
  });
}

const pct = (sorted, p) => sorted[Math.min(sorted.length - 1, Math.floor((p / 100) * sorted.length))];

async function run(o, name, addresses, extra = []) {
  const d = await startDaemon(o, extra);
  try {
    let a = null;
    if (addresses) {
      a = attack(d.port, o.clients, addresses, o.reconnect);
      await sleep(2500); // all connected, the per-address quota and the reaper at work
    }
    const openBefore = a ? a.open() : 0;
    const t = [];
    let failed = 0;
    for (let i = 0; i < o.requests; i++) {
      try {
        t.push(await healthOnce(d.port));
      } catch {
        failed++;
      }
      await sleep(5);
    }
    const openAfter = a ? a.open() : 0;
    const closed = a ? a.closed() : 0;
    if (a) a.stop();
    t.sort((x, y) => x - y);
    console.log(`| ${name} | ${openBefore} / ${openAfter} | ${closed} | ${t.length ? pct(t, 50).toFixed(2) : '-'} | ` +
                `${t.length ? pct(t, 99).toFixed(2) : '-'} | ${t.length ? t[t.length - 1].toFixed(2) : '-'} | ${failed} |`);
  } finally {
    d.proc.kill('SIGTERM');
    await new Promise((r) => (d.proc.exitCode !== null ? r() : d.proc.once('exit', r)));
    fs.rmSync(d.dir, {recursive: true, force: true});
  }
}

const o = parseArgs(process.argv.slice(2));
console.log(`# ${o.requests} health checks each; ${o.clients} slow clients, one header byte every 2 s` +
            `${o.reconnect ? ', reopened when closed' : ''}; daemon options: defaults ${o.extra.join(' ')}`);
console.log('| attack | slow sockets open (before / after) | closed by the daemon | p50 ms | p99 ms | max ms | failed |');
console.log('|---|---|---|---|---|---|---|');
await run(o, 'none', null);
await run(o, `${o.clients} from 127.0.0.1`, ['127.0.0.1']);
await run(o, `${o.clients} from 127.0.0.2-9`, ['2', '3', '4', '5', '6', '7', '8', '9'].map((x) => `127.0.0.${x}`));
await run(o, `${o.clients} from 127.0.0.2-9, --max-pending-per-address ${o.clients}`,
          ['2', '3', '4', '5', '6', '7', '8', '9'].map((x) => `127.0.0.${x}`), ['--max-pending-per-address', String(o.clients)]);
