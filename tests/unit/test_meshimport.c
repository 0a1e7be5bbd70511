/* obscurad's contained mesh import: the daemon-side decoding of worker replies (every malformed
 * reply is refused before it is trusted), the cache of imported meshes (identity, LRU, byte bound,
 * failures), and the client against the real worker program and against fake workers that hang
 * or answer garbage. */
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "meshimport.h"
#include "testutil.h"

/* ---- protocol decoding ------------------------------------------------------------------------ */

static const srv_mesh_limits LIM = {1000, 3000};

/* Decodes `len` bytes written into a pipe (then closed, so a short reply reads as EOF). */
static int decode(const void *bytes, size_t len, obs_mesh *m, char *msg, size_t n, int *code) {
  int p[2];
  assert_int_equal(pipe(p), 0);
  assert_int_equal(write(p[1], bytes, len), (ssize_t)len);
  close(p[1]);
  int r = srv_meshproto_read_reply(p[0], 5000, &LIM, m, code, msg, n);
  close(p[0]);
  return r;
}

/* A reply of one triangle, built with the encoder, patched by the caller. */
typedef struct reply {
  unsigned char b[256];
  size_t len;
} reply;

static void triangle_reply(reply *r, int normals) {
  float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  uint32_t idx[3] = {0, 1, 2};
  obs_mesh m = {pos, normals ? nrm : NULL, idx, 3, 1, 0, NULL, NULL};
  int p[2];
  assert_int_equal(pipe(p), 0);
  assert_int_equal(srv_meshproto_write_mesh(p[1], &m), 0);
  close(p[1]);
  r->len = (size_t)read(p[0], r->b, sizeof r->b);
  close(p[0]);
}

/* Offsets in a reply: magic 0, status 4, nverts 8, ntris 16, normals 24, pos 28. */
#define OFF_NVERTS 8
#define OFF_NTRIS 16
#define OFF_POS 28

static void test_reply_valid(void **state) {
  (void)state;
  for (int normals = 0; normals < 2; normals++) {
    reply r;
    triangle_reply(&r, normals);
    obs_mesh m;
    char msg[256];
    int code = 0;
    assert_int_equal(decode(r.b, r.len, &m, msg, sizeof msg, &code), SRV_MESH_REPLY_MESH);
    assert_int_equal(m.nverts, 3);
    assert_int_equal(m.ntris, 1);
    assert_true(m.pos[3] == 1.0f && m.pos[7] == 1.0f);
    assert_int_equal(m.idx[2], 2);
    assert_int_equal(m.nrm != NULL, normals);
    obs_geometry_mesh_free(&m);
  }
}

static void expect_bad(reply *r, int want, const char *needle) {
  obs_mesh m;
  char msg[256];
  int code = 0;
  int got = decode(r->b, r->len, &m, msg, sizeof msg, &code);
  if (got != want || (needle && !strstr(msg, needle)))
    fprintf(stderr, "expected %d \"%s\", got %d \"%s\"\n", want, needle ? needle : "", got, msg);
  assert_int_equal(got, want);
  if (needle) assert_non_null(strstr(msg, needle));
  assert_null(m.pos);
  assert_null(m.idx);
}

static void test_reply_malformed(void **state) {
  (void)state;
  reply r;
  triangle_reply(&r, 0);
  r.b[0] ^= 1;
  expect_bad(&r, SRV_MESH_REPLY_BAD, "magic");

  triangle_reply(&r, 0);
  uint32_t nine = 9; /* index 2 -> 9, with 3 vertices */
  memcpy(r.b + r.len - 4, &nine, 4);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "index out of range");

  triangle_reply(&r, 0);
  float nan = NAN;
  memcpy(r.b + OFF_POS + 4, &nan, 4);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "non-finite");

  /* Counts beyond the limits are refused from the header, before anything is allocated. */
  triangle_reply(&r, 0);
  uint64_t huge = (uint64_t)1 << 60;
  memcpy(r.b + OFF_NTRIS, &huge, 8);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "beyond the limit");
  triangle_reply(&r, 0);
  memcpy(r.b + OFF_NVERTS, &huge, 8);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "beyond the limit");

  triangle_reply(&r, 0);
  uint64_t zero = 0;
  memcpy(r.b + OFF_NTRIS, &zero, 8);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "empty");

  triangle_reply(&r, 0);
  int32_t weird = 7;
  memcpy(r.b + 4, &weird, 4);
  expect_bad(&r, SRV_MESH_REPLY_BAD, "status");

  /* Cut anywhere: the worker died mid-reply. */
  triangle_reply(&r, 1);
  for (size_t cut = 0; cut < r.len; cut += 5) {
    reply c = r;
    c.len = cut;
    expect_bad(&c, SRV_MESH_REPLY_EOF, NULL);
  }
}

static void test_reply_error_and_timeout(void **state) {
  (void)state;
  int p[2];
  assert_int_equal(pipe(p), 0);
  assert_int_equal(srv_meshproto_write_error(p[1], OBS_EINVAL, "x.ply: cannot\nimport"), 0);
  obs_mesh m;
  char msg[256];
  int code = 0;
  assert_int_equal(srv_meshproto_read_reply(p[0], 5000, &LIM, &m, &code, msg,
                                            sizeof msg),
                   SRV_MESH_REPLY_ERROR);
  assert_int_equal(code, OBS_EINVAL);
  assert_string_equal(msg, "x.ply: cannot import"); /* control characters flattened */
  /* Nothing more arrives: the deadline ends the wait (the pipe stays open). */
  assert_int_equal(srv_meshproto_read_reply(p[0], 50, &LIM, &m, &code, msg,
                                            sizeof msg),
                   SRV_MESH_REPLY_TIMEOUT);
  close(p[0]);
  close(p[1]);
}

static void test_request_roundtrip(void **state) {
  (void)state;
  int p[2];
  assert_int_equal(pipe(p), 0);
  assert_int_equal(srv_meshproto_write_request(p[1], "/s/models/a.ply", "/s", 77), 0);
  static char path[SRV_MESH_MAX_PATH + 1], root[SRV_MESH_MAX_PATH + 1];
  uint64_t mt = 0;
  assert_int_equal(srv_meshproto_read_request(p[0], path, root, &mt), 0);
  assert_string_equal(path, "/s/models/a.ply");
  assert_string_equal(root, "/s");
  assert_int_equal(mt, 77);
  close(p[1]);
  assert_int_equal(srv_meshproto_read_request(p[0], path, root, &mt), 1); /* clean end */
  close(p[0]);
}

/* ---- cache ------------------------------------------------------------------------------------ */

static void make_mesh(obs_mesh *m, size_t ntris) {
  memset(m, 0, sizeof *m);
  m->nverts = ntris * 3;
  m->ntris = ntris;
  m->pos = calloc(m->nverts * 3, sizeof(float));
  m->idx = malloc(ntris * 3 * sizeof(uint32_t));
  for (size_t i = 0; i < ntris * 3; i++) m->idx[i] = (uint32_t)i;
  m->pos[0] = (float)ntris;
}

static srv_meshkey key(const char *path, long mtime) {
  srv_meshkey k = {path, "/root", 1, 42, 100, {mtime, 0}};
  return k;
}

static void test_cache_hit_copy_identity(void **state) {
  (void)state;
  srv_meshcache *c = srv_meshcache_new(1 << 20);
  obs_mesh m, got;
  make_mesh(&m, 10);
  srv_meshkey k = key("/root/a.ply", 1);
  int code;
  char *msg;
  assert_int_equal(srv_meshcache_get(c, &k, &got, &code, &msg), 0);
  srv_meshcache_put_mesh(c, &k, &m);
  assert_int_equal(srv_meshcache_get(c, &k, &got, &code, &msg), 1);
  assert_int_equal(got.ntris, 10);
  assert_true(got.pos != m.pos && got.pos[0] == 10.0f);
  got.pos[0] = -1; /* the caller owns its copy */
  obs_geometry_mesh_free(&got);
  assert_int_equal(srv_meshcache_get(c, &k, &got, &code, &msg), 1);
  assert_true(got.pos[0] == 10.0f);
  obs_geometry_mesh_free(&got);
  /* Same path, new mtime (or inode, size): a different file. */
  srv_meshkey k2 = key("/root/a.ply", 2);
  assert_int_equal(srv_meshcache_get(c, &k2, &got, &code, &msg), 0);
  k2.mtim.tv_sec = 1;
  k2.ino = 43;
  assert_int_equal(srv_meshcache_get(c, &k2, &got, &code, &msg), 0);
  srv_meshkey k3 = k;
  k3.root = "/other";
  assert_int_equal(srv_meshcache_get(c, &k3, &got, &code, &msg), 0);
  /* Putting the new identity replaces the stale entry rather than adding one. */
  srv_meshcache_put_error(c, &k2, OBS_EINVAL, "a.ply: the mesh importer crashed (signal 6)");
  srv_meshcache_stats st;
  srv_meshcache_stats_get(c, &st);
  assert_int_equal(st.entries, 1);
  assert_int_equal(srv_meshcache_get(c, &k2, &got, &code, &msg), 2);
  assert_int_equal(code, OBS_EINVAL);
  assert_string_equal(msg, "a.ply: the mesh importer crashed (signal 6)");
  free(msg);
  assert_int_equal(srv_meshcache_get(c, &k, &got, &code, &msg), 0);
  srv_meshcache_stats_get(c, &st);
  assert_int_equal(st.hits, 3);
  assert_int_equal(st.misses, 5);
  obs_geometry_mesh_free(&m);
  srv_meshcache_free(c);
}

static void test_cache_lru_bound(void **state) {
  (void)state;
  /* Each mesh of 100 triangles is 300 x 12 + 300 x 4... about 4.8 KB: room for three. */
  obs_mesh m;
  make_mesh(&m, 100);
  srv_meshcache *c = srv_meshcache_new(16000);
  srv_meshkey a = key("/root/a", 1), b = key("/root/b", 1), d = key("/root/d", 1),
              e = key("/root/e", 1);
  obs_mesh got;
  int code;
  char *msg;
  srv_meshcache_put_mesh(c, &a, &m);
  srv_meshcache_put_mesh(c, &b, &m);
  srv_meshcache_put_mesh(c, &d, &m);
  assert_int_equal(srv_meshcache_get(c, &a, &got, &code, &msg), 1); /* a is now most recent */
  obs_geometry_mesh_free(&got);
  srv_meshcache_put_mesh(c, &e, &m); /* evicts b, the least recently used */
  srv_meshcache_stats st;
  srv_meshcache_stats_get(c, &st);
  assert_true(st.bytes <= 16000);
  assert_int_equal(st.entries, 3);
  assert_int_equal(st.evictions, 1);
  assert_int_equal(srv_meshcache_get(c, &b, &got, &code, &msg), 0);
  assert_int_equal(srv_meshcache_get(c, &a, &got, &code, &msg), 1);
  obs_geometry_mesh_free(&got);
  /* Larger than the whole bound: not kept, nothing evicted for it. */
  obs_mesh big;
  make_mesh(&big, 2000);
  srv_meshkey bk = key("/root/big", 1);
  srv_meshcache_put_mesh(c, &bk, &big);
  assert_int_equal(srv_meshcache_get(c, &bk, &got, &code, &msg), 0);
  srv_meshcache_stats_get(c, &st);
  assert_int_equal(st.entries, 3);
  obs_geometry_mesh_free(&big);
  srv_meshcache_free(c);
  /* A zero bound keeps nothing. */
  c = srv_meshcache_new(0);
  srv_meshcache_put_mesh(c, &a, &m);
  srv_meshcache_put_error(c, &b, OBS_EINVAL, "x");
  assert_int_equal(srv_meshcache_get(c, &a, &got, &code, &msg), 0);
  assert_int_equal(srv_meshcache_get(c, &b, &got, &code, &msg), 0);
  srv_meshcache_free(c);
  obs_geometry_mesh_free(&m);
}

/* ---- the client, against the real worker and fake ones ------------------------------------------ */

static const char *scenes(void) {
  static char dir[1024];
  snprintf(dir, sizeof dir, "%s", obs_test_tmpdir("meshimport"));
  char cmd[4096], good[1024];
  snprintf(good, sizeof good, "%s", obs_test_src("tests/data/tetra.obj"));
  snprintf(cmd, sizeof cmd, "mkdir -p '%s/models' && cp '%s' '%s' '%s/models/'", dir, good,
           obs_test_src("tests/data/mesh/crash_triangulate.ply"), dir);
  assert_int_equal(system(cmd), 0);
  return dir;
}

static srv_meshimport *client(const char *exe, int seconds) {
  srv_meshimport_opts o = {exe, seconds, 1LL << 31, 100000, 1 << 20};
  srv_meshimport *mi;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(srv_meshimport_new(&o, &mi, &err), 0);
  return mi;
}

static int import(srv_meshimport *mi, const char *dir, const char *rel, obs_mesh *m,
                  obs_err *err) {
  char path[1200];
  snprintf(path, sizeof path, "%s/%s", dir, rel);
  return srv_meshimport_import(mi, path, dir, m, err, "t.json: /objects/0/shape/file");
}

static void test_client_real_worker(void **state) {
  (void)state;
  const char *dir = scenes();
  srv_meshimport *mi = client(OBS_IMPORT_EXE, 30);
  obs_mesh m;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(import(mi, dir, "models/tetra.obj", &m, &err), 0);
  assert_int_equal(m.ntris, 4);
  for (size_t i = 0; i < m.ntris * 3; i++) assert_true(m.idx[i] < m.nverts);
  obs_geometry_mesh_free(&m);
  assert_int_equal(import(mi, dir, "models/crash_triangulate.ply", &m, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "t.json: /objects/0/shape/file: "
                                                "models/crash_triangulate.ply: the mesh "
                                                "importer crashed (signal 6)"));
  obs_err_clear(&err);
  /* Both again: from the cache, no worker started for either. */
  assert_int_equal(import(mi, dir, "models/crash_triangulate.ply", &m, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "crashed (signal 6)"));
  obs_err_clear(&err);
  assert_int_equal(import(mi, dir, "models/tetra.obj", &m, &err), 0);
  obs_geometry_mesh_free(&m);
  srv_meshimport_stats st;
  srv_meshimport_stats_get(mi, &st);
  assert_int_equal(st.spawns, 1); /* the good import's worker took the crashing file */
  assert_int_equal(st.imports, 2);
  assert_int_equal(st.crashes, 1);
  assert_int_equal(st.cache.hits, 2);
  /* Missing file: refused here, before any worker. */
  assert_int_equal(import(mi, dir, "models/none.obj", &m, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "not a readable regular file"));
  obs_err_free(&err);
  srv_meshimport_free(mi);
}

/* A fake worker: a shell script in the test's directory. */
static const char *script(const char *dir, const char *name, const char *body) {
  static char path[1200];
  snprintf(path, sizeof path, "%s/%s", dir, name);
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fprintf(f, "#!/bin/sh\n%s\n", body);
  fclose(f);
  chmod(path, 0755);
  return path;
}

static void test_client_fake_workers(void **state) {
  (void)state;
  const char *dir = scenes();
  obs_mesh m;
  obs_err err = OBS_ERR_INIT;
  srv_meshimport *mi = client(script(dir, "hang.sh", "exec sleep 60"), 1);
  assert_int_equal(import(mi, dir, "models/tetra.obj", &m, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "models/tetra.obj: the mesh importer timed out "
                                                "after 1 s"));
  obs_err_clear(&err);
  srv_meshimport_stats st;
  srv_meshimport_stats_get(mi, &st);
  assert_int_equal(st.timeouts, 1);
  srv_meshimport_free(mi);

  mi = client(script(dir, "garbage.sh", "head -c 12 >/dev/null; printf 'garbage garbage'; "
                                        "exec sleep 60"), 5);
  assert_int_equal(import(mi, dir, "models/tetra.obj", &m, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "answered malformed data (wrong magic number)"));
  obs_err_clear(&err);
  srv_meshimport_free(mi);

  mi = client(script(dir, "exits.sh", "exit 3"), 5);
  int rc = import(mi, dir, "models/tetra.obj", &m, &err);
  const char *msg = obs_err_message(&err);
  /* Gone before or after reading the request: either way an exit, not a hang (and a failure to
   * reach any worker, EIO, is not the file's fault). */
  assert_true((rc == OBS_EINVAL && strstr(msg, "exited with status 3")) ||
              (rc == OBS_EIO && strstr(msg, "cannot send")));
  obs_err_free(&err);
  srv_meshimport_free(mi);

  assert_int_not_equal(srv_meshimport_new(&(srv_meshimport_opts){"/nonexistent/importer", 1, 0,
                                                                   1, 0},
                                          &mi, &err),
                       0);
  assert_non_null(strstr(obs_err_message(&err), "/nonexistent/importer"));
  obs_err_free(&err);
}

int main(void) {
  signal(SIGPIPE, SIG_IGN); /* as in obscurad: a dead worker's pipe is an error, not a signal */
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_reply_valid),
      cmocka_unit_test(test_reply_malformed),
      cmocka_unit_test(test_reply_error_and_timeout),
      cmocka_unit_test(test_request_roundtrip),
      cmocka_unit_test(test_cache_hit_copy_identity),
      cmocka_unit_test(test_cache_lru_bound),
      cmocka_unit_test(test_client_real_worker),
      cmocka_unit_test(test_client_fake_workers),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
