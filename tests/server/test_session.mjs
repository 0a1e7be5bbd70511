// The dashboard's session cookie (POST /api/v1/session) on a daemon with a token: the cookie lets
// GETs of outputs and pages through without the bearer header, expires, cannot be forged or
// renewed by itself, never authorises a request that changes something (same-site or not) and is
// ignored on cross-site reads; the bearer token works exactly as before. Also the favicon.
//
//   node tests/server/test_session.mjs <obscurad> <obscura>
import assert from 'node:assert/strict';
import {test} from 'node:test';

import {pngSize, request, sleep, sql, submit, validate, waitJob, withDaemon} from './lib.mjs';

const TOKEN = 'session-test-token-0123456789';
const small = {scene_file: 'sphere_on_plane.json', set: {'/image/width': 16, '/image/height': 12, '/technique/params/samples': 4}};
const COOKIE_RE = /^obscura_session=(\d+)\.([0-9a-f]{64}); Path=\/; Max-Age=(\d+); HttpOnly; SameSite=Strict$/;
const jobCount = (d) => Number(sql(d.db, 'SELECT count(*) FROM jobs')[0][0]);

async function login(d) {
  const r = await request(d, 'POST', '/api/v1/session');
  assert.equal(r.status, 200, `login: ${r.status} ${r.text}`);
  validate('Session', r.json);
  const set = r.headers['set-cookie'];
  assert.equal(set && set.length, 1, 'one Set-Cookie');
  const m = COOKIE_RE.exec(set[0]);
  assert.ok(m, `cookie attributes: ${set[0]}`);
  return {cookie: `obscura_session=${m[1]}.${m[2]}`, expires: Number(m[1]), sig: m[2], maxAge: Number(m[3]), json: r.json};
}

const get = (d, p, cookie, headers = {}) => request(d, 'GET', p, {auth: false, headers: {cookie, ...headers}});

function assert401(r, pattern, what) {
  assert.equal(r.status, 401, `${what}: ${r.status} ${r.text}`);
  validate('Error', r.json);
  assert.match(r.json.error, pattern, what);
  assert.match(r.headers['www-authenticate'] || '', /^Bearer/, `${what}: WWW-Authenticate`);
}

test('the session cookie stands in for the token on reads only', async () => {
  await withDaemon({token: TOKEN}, async (d) => {
    // Logging in needs the token itself.
    assert401(await request(d, 'POST', '/api/v1/session', {auth: false}), /bearer token/, 'login without a token');
    const wrong = await request(d, 'POST', '/api/v1/session', {auth: false, headers: {authorization: `Bearer ${TOKEN}x`}});
    assert401(wrong, /bearer token/, 'login with a wrong token');
    assert.equal(wrong.headers['set-cookie'], undefined, 'no cookie for a wrong token');

    const s = await login(d);
    assert.equal(s.json.token_required, true);
    assert.equal(s.maxAge, 43200, 'default --session-seconds');
    assert.equal(s.json.expires_in, 43200);
    assert.equal(Date.parse(s.json.expires) / 1000, s.expires, 'expires names the cookie\'s expiry');

    const id = await submit(d, small);
    const job = await waitJob(d, id);
    assert.equal(job.state, 'succeeded', JSON.stringify(job));
    const png = job.outputs.find((o) => o.content_type === 'image/png');
    assert.ok(png, 'a PNG output');

    // Reads with the cookie alone: an output, the job, the list, HEAD.
    const img = await get(d, png.url, s.cookie);
    assert.equal(img.status, 200, `output with the cookie: ${img.status} ${img.text}`);
    assert.deepEqual(pngSize(img.body), {width: 16, height: 12});
    assert.equal((await get(d, `/api/v1/jobs/${id}`, s.cookie)).status, 200);
    assert.equal((await get(d, '/api/v1/jobs', s.cookie, {'sec-fetch-site': 'same-origin'})).status, 200);
    assert.equal((await request(d, 'HEAD', png.url, {auth: false, headers: {cookie: s.cookie}})).status, 200);
    // ... and without it, as before.
    assert401(await request(d, 'GET', png.url, {auth: false}), /bearer token/, 'output without anything');

    // A cross-site read does not get the cookie's help (SameSite=Strict keeps browsers from
    // sending it; this is the server's own check).
    assert401(await get(d, png.url, s.cookie, {'sec-fetch-site': 'cross-site'}), /cross-site/, 'cross-site read');

    // Forged cookies: another signature, a later expiry under the same signature, garbage.
    const flipped = s.sig.replace(/^./, (c) => (c === '0' ? '1' : '0'));
    assert401(await get(d, png.url, `obscura_session=${s.expires}.${flipped}`), /not valid/, 'altered signature');
    assert401(await get(d, png.url, `obscura_session=${s.expires + 3600}.${s.sig}`), /not valid/, 'altered expiry');
    assert401(await get(d, png.url, 'obscura_session=garbage'), /not valid/, 'garbage');

    // Changing anything needs the token, whatever the cookie: same-origin or cross-site.
    const before = jobCount(d);
    assert401(await request(d, 'POST', '/api/v1/jobs', {auth: false, body: small, headers: {cookie: s.cookie, 'sec-fetch-site': 'same-origin'}}),
      /GET and HEAD only/, 'same-origin POST with the cookie');
    const cross = await request(d, 'POST', '/api/v1/jobs', {auth: false, body: small,
      headers: {cookie: s.cookie, 'sec-fetch-site': 'cross-site', origin: 'http://evil.example'}});
    assert.equal(cross.status, 403, `cross-site POST with the cookie: ${cross.status} ${cross.text}`);
    assert401(await request(d, 'DELETE', `/api/v1/jobs/${id}`, {auth: false, headers: {cookie: s.cookie}}), /GET and HEAD only/, 'DELETE with the cookie');
    assert401(await request(d, 'POST', `/api/v1/jobs/${id}/cancel`, {auth: false, headers: {cookie: s.cookie}}), /GET and HEAD only/, 'cancel with the cookie');
    assert.equal(jobCount(d), before, 'nothing was submitted or deleted');
    assert.equal((await request(d, 'GET', `/api/v1/jobs/${id}`)).status, 200, 'the job is still there');
    // The cookie cannot renew itself.
    assert401(await request(d, 'POST', '/api/v1/session', {auth: false, headers: {cookie: s.cookie}}), /GET and HEAD only/, 'renewal with the cookie');

    // The bearer token works exactly as before, with or without a cookie beside it.
    assert.equal((await request(d, 'GET', png.url)).status, 200, 'output with the bearer token');
    assert.equal((await request(d, 'GET', '/metrics')).status, 200, 'metrics with the bearer token');
    await submit(d, small);

    // Logging out clears the cookie.
    const out = await request(d, 'DELETE', '/api/v1/session');
    assert.equal(out.status, 200, out.text);
    validate('Session', out.json);
    assert.match(out.headers['set-cookie'][0], /^obscura_session=; Path=\/; Max-Age=0; HttpOnly; SameSite=Strict$/);
  });
});

test('session cookies expire and do not survive a restart', async () => {
  await withDaemon({token: TOKEN, args: ['--session-seconds', '1']}, async (d) => {
    const s = await login(d);
    assert.equal(s.maxAge, 1);
    // The signed expiry is a whole second: wait until it has passed, then the cookie is refused.
    while (Date.now() / 1000 <= s.expires + 0.05) await sleep(100);
    assert401(await get(d, '/api/v1/jobs', s.cookie), /expired/, 'expired cookie');
  });
  let cookie;
  let dir;
  await withDaemon({token: TOKEN, keep: true}, async (d) => {
    cookie = (await login(d)).cookie;
    assert.equal((await get(d, '/api/v1/jobs', cookie)).status, 200);
    dir = d.dir;
  });
  await withDaemon({token: TOKEN, dir}, async (d) => {
    assert401(await get(d, '/api/v1/jobs', cookie), /not valid/, 'a cookie of the previous start');
  });
});

test('without a token there is no session to make', async () => {
  await withDaemon({}, async (d) => {
    const r = await request(d, 'POST', '/api/v1/session');
    assert.equal(r.status, 200, r.text);
    validate('Session', r.json);
    assert.equal(r.json.token_required, false);
    assert.equal(r.headers['set-cookie'], undefined);
    assert.equal((await request(d, 'GET', '/api/v1/session')).status, 405);
  });
});

test('the favicon is served and the page links it', async () => {
  await withDaemon({token: TOKEN}, async (d) => {
    const icon = await request(d, 'GET', '/favicon.svg', {auth: false});
    assert.equal(icon.status, 200, icon.text);
    assert.equal(icon.headers['content-type'], 'image/svg+xml');
    assert.match(icon.text, /^<svg [^>]*xmlns="http:\/\/www\.w3\.org\/2000\/svg"/);
    const page = await request(d, 'GET', '/', {auth: false});
    assert.equal(page.status, 200);
    assert.match(page.text, /<link rel="icon" href="favicon\.svg" type="image\/svg\+xml">/);
  });
});
