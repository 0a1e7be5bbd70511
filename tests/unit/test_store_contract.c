/* The store's contract (server/db.h), one suite for both implementations: every test opens the
 * store named by OBSCURA_TEST_STORE (unset: a fresh SQLite file; a postgresql:// URL: a fresh
 * database created on that server for the test and dropped after it) with two nodes on it, and
 * checks what the interface promises through the interface alone: states and transitions, the
 * attempt guard, heartbeats, claims racing from two nodes, the reaper and the per-node exclusion,
 * recovery, comparisons, the admission limits' reads, blobs, retention and wake-ups. Where the
 * contract answers differently for the one-daemon SQLite store (reap, wait, blobs), the test says
 * so and checks that answer. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "testutil.h"
#include "obscurad.h"
#include <libpq-fe.h>

/* ---- the store under test ------------------------------------------------------------------- */

typedef struct store {
  char where[1200];  /* the SQLite file or this test's PostgreSQL URL */
  char dbname[80];   /* PostgreSQL: this test's database, dropped at teardown */
  int pg;
  srv_db *a, *b;     /* nodes "node-a" and "node-b" on the same store */
} store;

static obs_err E = OBS_ERR_INIT;

#define OK(call)                                                                                  \
  do {                                                                                            \
    obs_err_clear(&E);                                                                            \
    int rc_ = (call);                                                                             \
    if (rc_ != 0) fail_msg("%s -> %d: %s", #call, rc_, obs_err_message(&E));                     \
  } while (0)
#define RC(want, call)                                                                            \
  do {                                                                                            \
    obs_err_clear(&E);                                                                            \
    int rc_ = (call);                                                                             \
    if (rc_ != (want)) fail_msg("%s -> %d (%s), want %d", #call, rc_, obs_err_message(&E), (want)); \
  } while (0)

static const char *store_env(void) {
  const char *v = getenv("OBSCURA_TEST_STORE");
  return v && *v ? v : NULL;
}

static int is_pg(void) {
  const char *v = store_env();
  return v && (!strncmp(v, "postgresql://", 13) || !strncmp(v, "postgres://", 11));
}

static srv_db *open_node(const store *s, const char *name, int lease_seconds) {
  srv_node n;
  srv_node_init(&n, name, lease_seconds);
  srv_db *db = NULL;
  OK(srv_db_open(&db, s->where, 4, &n, &E));
  return db;
}

/* Runs one administrative statement on the server of `url` (creating or dropping this test's
 * database: the store itself is reached only through srv_db). */
static void no_notice(void *arg, const char *message) { (void)arg, (void)message; }

static void pg_admin(const char *url, const char *sql) {
  PGconn *c = PQconnectdb(url);
  if (PQstatus(c) != CONNECTION_OK) fail_msg("cannot connect to %s: %s", url, PQerrorMessage(c));
  PQsetNoticeProcessor(c, no_notice, NULL); /* "database ... does not exist, skipping" */
  PGresult *r = PQexec(c, sql);
  int ok = PQresultStatus(r) == PGRES_COMMAND_OK;
  char msg[512];
  snprintf(msg, sizeof msg, "%s", PQresultErrorMessage(r));
  PQclear(r);
  PQfinish(c);
  if (!ok) fail_msg("%s: %s", sql, msg);
}

/* The URL with its database replaced by `name`. */
static void url_with_db(const char *url, const char *name, char *out, size_t n) {
  const char *host = strstr(url, "://") + 3;
  const char *path = strchr(host, '/');
  const char *query = strchr(host, '?');
  size_t keep = path ? (size_t)(path - url) : query ? (size_t)(query - url) : strlen(url);
  snprintf(out, n, "%.*s/%s%s", (int)keep, url, name, query ? query : "");
}

static int setup(void **state) {
  static int serial;
  store *s = calloc(1, sizeof *s);
  assert_non_null(s);
  serial++;
  const char *env = store_env();
  if (!env) {
    snprintf(s->where, sizeof s->where, "%s",
             obs_test_path(obs_test_tmpdir("store_contract"), "store.db"));
    char extra[1300];
    unlink(s->where);
    snprintf(extra, sizeof extra, "%s-wal", s->where);
    unlink(extra);
    snprintf(extra, sizeof extra, "%s-shm", s->where);
    unlink(extra);
  } else if (is_pg()) {
    s->pg = 1;
    snprintf(s->dbname, sizeof s->dbname, "obscura_contract_%ld_%d", (long)getpid(), serial);
    char sql[200];
    snprintf(sql, sizeof sql, "DROP DATABASE IF EXISTS %s WITH (FORCE)", s->dbname);
    pg_admin(env, sql);
    snprintf(sql, sizeof sql, "CREATE DATABASE %s", s->dbname);
    pg_admin(env, sql);
    url_with_db(env, s->dbname, s->where, sizeof s->where);
  } else {
    fail_msg("OBSCURA_TEST_STORE=%s: neither unset (SQLite) nor a postgresql:// URL", env);
  }
  s->a = open_node(s, "node-a", 30);
  s->b = open_node(s, "node-b", 30);
  *state = s;
  return 0;
}

static int teardown(void **state) {
  store *s = *state;
  srv_db_close(s->a);
  srv_db_close(s->b);
  if (s->pg) {
    char sql[200];
    snprintf(sql, sizeof sql, "DROP DATABASE IF EXISTS %s WITH (FORCE)", s->dbname);
    pg_admin(store_env(), sql);
  }
  free(s);
  return 0;
}

/* ---- helpers -------------------------------------------------------------------------------- */

static srv_new_job job_of(const char *technique, int priority) {
  srv_new_job nj = {0};
  nj.priority = priority;
  nj.label = "contract";
  nj.scene = "cornell_box.json";
  nj.doc = "{\"scene\":\"cornell_box.json\"}";
  nj.technique = technique;
  nj.backend_requested = "cpu";
  nj.lane = SRV_LANE_CPU;
  nj.width = 32;
  nj.height = 24;
  nj.spp = 4;
  nj.repeats = 1;
  nj.work = 32.0 * 24 * 4;
  return nj;
}

static int64_t insert(srv_db *db, const char *technique, int priority) {
  srv_new_job nj = job_of(technique, priority);
  int64_t id = 0;
  OK(srv_db_insert_job(db, &nj, &id, &E));
  assert_true(id > 0);
  return id;
}

static int64_t insert_vulkan(srv_db *db, const char *technique, int priority) {
  srv_new_job nj = job_of(technique, priority);
  nj.backend_requested = "vulkan";
  nj.lane = SRV_LANE_VULKAN;
  int64_t id = 0;
  OK(srv_db_insert_job(db, &nj, &id, &E));
  return id;
}

/* Claims the next CPU job: its id and *attempt, or 0 when none is ready. */
static int64_t claim(srv_db *db, int *attempt) {
  srv_job j;
  obs_err_clear(&E);
  int rc = srv_db_claim(db, SRV_LANE_CPU, &j, &E);
  if (rc < 0) fail_msg("claim -> %d: %s", rc, obs_err_message(&E));
  if (rc == 1) return 0;
  int64_t id = j.id;
  if (attempt) *attempt = j.attempts;
  srv_job_free(&j);
  return id;
}

static srv_job get(srv_db *db, int64_t id) {
  srv_job j;
  OK(srv_db_get_job(db, id, &j, &E));
  return j;
}

static srv_state state_of(srv_db *db, int64_t id) {
  srv_job j = get(db, id);
  srv_state st = j.state;
  srv_job_free(&j);
  return st;
}

static void succeed(srv_db *db, int64_t id, int attempt, const srv_run *runs, int nruns,
                    int64_t machine) {
  srv_output o = {.name = "ao", .size = 1234, .content_type = "image/png"};
  memset(o.sha256, 'a', 64);
  OK(srv_db_finish_success(db, id, attempt, "cpu", "{\"ok\":true}", &o, 1, runs, nruns, machine,
                           &E));
}

static json_t *query(srv_db *db, srv_query q, int64_t a1, int64_t a2, int nargs) {
  srv_arg args[2] = {{.kind = SRV_ARG_INT, .i = a1}, {.kind = SRV_ARG_INT, .i = a2}};
  json_t *rows = NULL;
  OK(srv_db_query(db, q, args, nargs, &rows, &E));
  assert_true(json_is_array(rows));
  return rows;
}

static int64_t col_int(json_t *rows, size_t i, const char *col) {
  json_t *v = json_object_get(json_array_get(rows, i), col);
  if (!json_is_integer(v)) fail_msg("row %zu column %s is not an integer", i, col);
  return json_integer_value(v);
}

static const char *col_str(json_t *rows, size_t i, const char *col) {
  json_t *v = json_object_get(json_array_get(rows, i), col);
  if (!json_is_string(v)) fail_msg("row %zu column %s is not a string", i, col);
  return json_string_value(v);
}

static double now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

static void sleep_ms(int ms) {
  struct timespec t = {ms / 1000, (long)(ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

/* ---- states and transitions ----------------------------------------------------------------- */

static void test_insert_claim_succeed(void **state) {
  store *s = *state;
  srv_new_job nj = job_of("rt_ao", 3);
  nj.backend_reason = "asked for";
  nj.notes = "[\"radius\"]";
  nj.scene_name = "box";
  nj.repeats = 2;
  nj.warmup = 1;
  int64_t id = 0;
  OK(srv_db_insert_job(s->a, &nj, &id, &E));
  srv_job j = get(s->a, id);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_int_equal(j.attempts, 0);
  assert_int_equal(j.priority, 3);
  assert_string_equal(j.technique, "rt_ao");
  assert_string_equal(j.scene, "cornell_box.json");
  assert_string_equal(j.label, "contract");
  assert_string_equal(j.backend_requested, "cpu");
  assert_string_equal(j.backend_reason, "asked for");
  assert_string_equal(j.notes, "[\"radius\"]");
  assert_string_equal(j.scene_name, "box");
  assert_int_equal(j.lane, SRV_LANE_CPU);
  assert_int_equal(j.width, 32);
  assert_int_equal(j.height, 24);
  assert_int_equal(j.spp, 4);
  assert_int_equal(j.repeats, 2);
  assert_int_equal(j.warmup, 1);
  assert_int_equal(j.ranks, 1);
  assert_int_equal(j.comparison, 0);
  assert_true(j.created_ms > 0);
  assert_int_equal(j.noutputs, 0);
  srv_job_free(&j);
  srv_state st = SRV_FAILED;
  RC(1, srv_db_job_exists(s->a, id, &st, &E));
  assert_int_equal(st, SRV_QUEUED);
  RC(0, srv_db_job_exists(s->a, id + 1000, &st, &E));
  RC(OBS_ENOTFOUND, srv_db_get_job(s->a, id + 1000, &j, &E));

  OK(srv_db_claim(s->a, SRV_LANE_CPU, &j, &E));
  assert_int_equal(j.id, id);
  assert_int_equal(j.state, SRV_RUNNING);
  assert_int_equal(j.attempts, 1);
  assert_string_equal(j.node, "node-a");
  assert_string_equal(j.doc, nj.doc);
  assert_true(j.started_ms >= j.created_ms);
  srv_job_free(&j);
  OK(srv_db_set_backend(s->a, id, "cpu", &E));

  int64_t machine = 0;
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &machine, &E));
  srv_output outs[2] = {{.name = "ao", .size = 100, .content_type = "image/png"},
                        {.name = "stderr", .size = 200, .content_type = "image/x-exr"}};
  memset(outs[0].sha256, 'a', 64);
  memset(outs[1].sha256, 'b', 64);
  srv_run runs[2] = {{1, 10, 2, 13}, {1, 11, 2, 14}};
  OK(srv_db_finish_success(s->a, id, 1, "cpu", "{\"summary\":1}", outs, 2, runs, 2, machine, &E));
  j = get(s->b, id);
  assert_int_equal(j.state, SRV_SUCCEEDED);
  assert_string_equal(j.backend, "cpu");
  assert_string_equal(j.summary, "{\"summary\":1}");
  assert_string_equal(j.node, "node-a");
  assert_null(j.error);
  assert_true(j.progress == 1.0);
  assert_true(j.finished_ms >= j.started_ms && j.started_ms > 0);
  assert_int_equal(j.noutputs, 2);
  assert_string_equal(j.outputs[0].name, "ao");
  assert_string_equal(j.outputs[1].name, "stderr");
  assert_int_equal(j.outputs[1].size, 200);
  assert_string_equal(j.outputs[1].sha256, outs[1].sha256);
  assert_string_equal(j.outputs[1].content_type, "image/x-exr");
  srv_job_free(&j);
  srv_output o;
  OK(srv_db_get_output(s->b, id, "stderr", &o, &E));
  assert_int_equal(o.size, 200);
  assert_string_equal(o.sha256, outs[1].sha256);
  RC(OBS_ENOTFOUND, srv_db_get_output(s->b, id, "nothing", &o, &E));
  json_t *r = query(s->b, SRV_Q_JOB_RUNS, id, 0, 1);
  assert_int_equal(json_array_size(r), 2);
  assert_true(json_number_value(json_object_get(json_array_get(r, 1), "total_ms")) == 14.0);
  json_decref(r);
  r = query(s->b, SRV_Q_JOB_MACHINE, id, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  assert_string_equal(col_str(r, 0, "cpu_model"), "Contract CPU");
  json_decref(r);
}

static void test_finish_keeps_progress(void **state) {
  store *s = *state;
  int64_t f = insert(s->a, "ssao", 0), c = insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), f);
  OK(srv_db_finish(s->a, f, att, SRV_FAILED, "renderer said no", 0.25, &E));
  assert_int_equal(claim(s->a, &att), c);
  OK(srv_db_finish(s->a, c, att, SRV_CANCELLED, "cancelled by request", 0.5, &E));
  srv_job j = get(s->a, f);
  assert_int_equal(j.state, SRV_FAILED);
  assert_string_equal(j.error, "renderer said no");
  assert_true(j.progress == 0.25);
  assert_true(j.finished_ms > 0);
  srv_job_free(&j);
  j = get(s->a, c);
  assert_int_equal(j.state, SRV_CANCELLED);
  assert_true(j.progress == 0.5);
  srv_job_free(&j);
}

static void test_requeue_does_not_count(void **state) {
  store *s = *state;
  int64_t id = insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), id);
  assert_int_equal(att, 1);
  OK(srv_db_requeue(s->a, id, att, &E));
  srv_job j = get(s->a, id);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_int_equal(j.attempts, 0);
  srv_job_free(&j);
  assert_int_equal(claim(s->b, &att), id);
  assert_int_equal(att, 1);
  j = get(s->a, id);
  assert_string_equal(j.node, "node-b");
  srv_job_free(&j);
}

static void test_cancel(void **state) {
  store *s = *state;
  int64_t run = insert(s->a, "ssao", 1), q = insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), run);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, q, &res, &E));
  assert_int_equal(res, SRV_CANCEL_DONE);
  srv_job j = get(s->a, q);
  assert_int_equal(j.state, SRV_CANCELLED);
  assert_true(j.finished_ms > 0);
  srv_job_free(&j);
  OK(srv_db_cancel(s->b, run, &res, &E));
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  j = get(s->a, run);
  assert_int_equal(j.state, SRV_RUNNING); /* the node that runs it stops it */
  assert_int_equal(j.cancel_requested, 1);
  srv_job_free(&j);
  OK(srv_db_cancel(s->b, q, &res, &E));
  assert_int_equal(res, SRV_CANCEL_FINISHED);
  RC(OBS_ENOTFOUND, srv_db_cancel(s->b, q + 1000, &res, &E));
}

static void test_retry(void **state) {
  store *s = *state;
  int64_t f = insert(s->a, "ssao", 0), ok = insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), f);
  OK(srv_db_finish(s->a, f, att, SRV_FAILED, "broke", 0.5, &E));
  assert_int_equal(claim(s->a, &att), ok);
  succeed(s->a, ok, att, NULL, 0, 0);
  srv_state st = SRV_QUEUED;
  OK(srv_db_retry(s->b, f, &st, &E));
  srv_job j = get(s->a, f);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_null(j.error);
  assert_int_equal(j.cancel_requested, 0);
  assert_int_equal(j.finished_ms, 0);
  srv_job_free(&j);
  assert_int_equal(claim(s->a, &att), f); /* the same row runs again */
  RC(OBS_EINVAL, srv_db_retry(s->b, ok, &st, &E));
  assert_int_equal(st, SRV_SUCCEEDED);
  RC(OBS_EINVAL, srv_db_retry(s->b, f, &st, &E));
  assert_int_equal(st, SRV_RUNNING);
  RC(OBS_ENOTFOUND, srv_db_retry(s->b, f + 1000, &st, &E));
  /* A cancelled job comes back too. */
  OK(srv_db_finish(s->a, f, att, SRV_CANCELLED, "cancelled by request", 0.1, &E));
  OK(srv_db_retry(s->b, f, &st, &E));
  assert_int_equal(state_of(s->a, f), SRV_QUEUED);
}

static void test_delete_and_counts(void **state) {
  store *s = *state;
  int64_t ids[6];
  for (int i = 0; i < 6; i++) ids[i] = insert(s->a, "ssao", 0);
  int att[4];
  for (int i = 0; i < 4; i++) assert_int_equal(claim(s->a, &att[i]), ids[i]);
  succeed(s->a, ids[0], att[0], NULL, 0, 0);
  OK(srv_db_finish(s->a, ids[1], att[1], SRV_FAILED, "x", 0, &E));
  OK(srv_db_finish(s->a, ids[2], att[2], SRV_CANCELLED, "y", 0, &E));
  int64_t counts[SRV_NSTATES];
  OK(srv_db_counts(s->b, counts, &E));
  assert_int_equal(counts[SRV_QUEUED], 2);
  assert_int_equal(counts[SRV_RUNNING], 1);
  assert_int_equal(counts[SRV_SUCCEEDED], 1);
  assert_int_equal(counts[SRV_FAILED], 1);
  assert_int_equal(counts[SRV_CANCELLED], 1);
  RC(OBS_EINVAL, srv_db_delete(s->b, ids[3], &E)); /* running */
  RC(OBS_EINVAL, srv_db_delete(s->b, ids[4], &E)); /* queued */
  assert_int_equal(state_of(s->a, ids[3]), SRV_RUNNING);
  assert_int_equal(state_of(s->a, ids[4]), SRV_QUEUED);
  for (int i = 0; i < 3; i++) {
    OK(srv_db_delete(s->b, ids[i], &E));
    RC(0, srv_db_job_exists(s->a, ids[i], NULL, &E));
    srv_output o;
    RC(OBS_ENOTFOUND, srv_db_get_output(s->a, ids[i], "ao", &o, &E));
  }
  RC(OBS_ENOTFOUND, srv_db_delete(s->b, ids[0], &E));
  OK(srv_db_counts(s->b, counts, &E));
  assert_int_equal(counts[SRV_QUEUED] + counts[SRV_RUNNING], 3);
  assert_int_equal(counts[SRV_SUCCEEDED] + counts[SRV_FAILED] + counts[SRV_CANCELLED], 0);
}

static void test_priorities_fifo_and_lanes(void **state) {
  store *s = *state;
  int64_t vid = insert_vulkan(s->a, "ssao", 9);
  int64_t low = insert(s->a, "ssao", 0), hi1 = insert(s->a, "ssao", 5);
  int64_t hi2 = insert(s->a, "ssao", 5), mid = insert(s->a, "ssao", 1);
  assert_int_equal(claim(s->a, NULL), hi1);
  assert_int_equal(claim(s->b, NULL), hi2);
  assert_int_equal(claim(s->a, NULL), mid);
  assert_int_equal(claim(s->b, NULL), low);
  assert_int_equal(claim(s->a, NULL), 0); /* the Vulkan job is not the CPU lane's */
  srv_job j;
  OK(srv_db_claim(s->a, SRV_LANE_VULKAN, &j, &E));
  assert_int_equal(j.id, vid);
  srv_job_free(&j);
}

/* ---- listing and keyset paging -------------------------------------------------------------- */

/* Pages through the filter's jobs `limit` at a time: their ids in order into out (count returned). */
static int page_all(srv_db *db, srv_job_filter f, int64_t *out, int cap) {
  int total = 0;
  for (int pages = 0; pages < 100; pages++) {
    srv_job *jobs = NULL;
    int n = 0;
    OK(srv_db_list_jobs(db, &f, &jobs, &n, &E));
    assert_true(n <= f.limit + 1);
    int shown = n > f.limit ? f.limit : n;
    for (int i = 0; i < shown; i++) {
      assert_true(total < cap);
      out[total++] = jobs[i].id;
    }
    if (shown) f.after = jobs[shown - 1].id;
    srv_jobs_free(jobs, n);
    if (n <= f.limit) return total;
  }
  fail_msg("paging did not end");
  return 0;
}

static void test_list_filters_and_paging(void **state) {
  store *s = *state;
  int64_t ids[9];
  for (int i = 0; i < 9; i++) ids[i] = insert(s->a, i % 3 ? "ssao" : "hbao", 0);
  int64_t vid = insert_vulkan(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), ids[0]);
  succeed(s->a, ids[0], att, NULL, 0, 0);

  int64_t got[32];
  srv_job_filter f = {.limit = 4};
  int n = page_all(s->b, f, got, 32);
  assert_int_equal(n, 10);
  assert_int_equal(got[0], vid);
  for (int i = 1; i < 10; i++) assert_int_equal(got[i], ids[9 - i]);
  f.ascending = 1;
  f.limit = 3;
  n = page_all(s->b, f, got, 32);
  assert_int_equal(n, 10);
  for (int i = 0; i < 9; i++) assert_int_equal(got[i], ids[i]);
  assert_int_equal(got[9], vid);

  srv_job_filter ft = {.technique = "hbao", .limit = 2};
  n = page_all(s->b, ft, got, 32);
  assert_int_equal(n, 3);
  assert_int_equal(got[0], ids[6]);
  assert_int_equal(got[1], ids[3]);
  assert_int_equal(got[2], ids[0]);
  srv_job_filter fs = {.has_state = 1, .state = SRV_SUCCEEDED, .limit = 50};
  n = page_all(s->b, fs, got, 32);
  assert_int_equal(n, 1);
  assert_int_equal(got[0], ids[0]);
  srv_job_filter fb = {.backend = "vulkan", .limit = 50};
  n = page_all(s->b, fb, got, 32);
  assert_int_equal(n, 1);
  assert_int_equal(got[0], vid);
  srv_job_filter fq = {.has_state = 1, .state = SRV_QUEUED, .technique = "ssao", .limit = 50};
  n = page_all(s->b, fq, got, 32);
  assert_int_equal(n, 7);
  /* One page of exactly `limit` rows and its extra row. */
  srv_job *jobs = NULL;
  srv_job_filter one = {.limit = 2};
  OK(srv_db_list_jobs(s->b, &one, &jobs, &n, &E));
  assert_int_equal(n, 3);
  srv_jobs_free(jobs, n);
  one.after = ids[1];
  OK(srv_db_list_jobs(s->b, &one, &jobs, &n, &E));
  assert_int_equal(n, 1);
  assert_int_equal(jobs[0].id, ids[0]);
  assert_int_equal(jobs[0].noutputs, 1);
  srv_jobs_free(jobs, n);
}

/* ---- the attempt guard, heartbeats, two nodes claiming -------------------------------------- */

static void expect_unchanged_running(srv_db *db, int64_t id, const char *node) {
  srv_job j = get(db, id);
  assert_int_equal(j.state, SRV_RUNNING);
  assert_int_equal(j.attempts, 1);
  assert_string_equal(j.node, node);
  assert_int_equal(j.noutputs, 0);
  assert_null(j.error);
  srv_job_free(&j);
}

static void test_attempt_guard(void **state) {
  store *s = *state;
  int64_t id = insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(claim(s->a, &att), id);
  srv_output o = {.name = "ao", .size = 1, .content_type = "image/png"};
  memset(o.sha256, 'c', 64);
  RC(OBS_ECONFLICT, srv_db_finish_success(s->a, id, att + 1, "cpu", "{}", &o, 1, NULL, 0, 0, &E));
  RC(OBS_ECONFLICT, srv_db_finish(s->a, id, att + 1, SRV_FAILED, "late", 0.5, &E));
  RC(OBS_ECONFLICT, srv_db_requeue(s->a, id, att + 1, &E));
  expect_unchanged_running(s->b, id, "node-a");
  /* Another node, right attempt: not its job. */
  RC(OBS_ECONFLICT, srv_db_finish_success(s->b, id, att, "cpu", "{}", &o, 1, NULL, 0, 0, &E));
  RC(OBS_ECONFLICT, srv_db_finish(s->b, id, att, SRV_FAILED, "not mine", 0.5, &E));
  RC(OBS_ECONFLICT, srv_db_requeue(s->b, id, att, &E));
  expect_unchanged_running(s->a, id, "node-a");
  /* The same node name after a restart (another boot) does not hold it either. */
  srv_db *a2 = open_node(s, "node-a", 30);
  RC(OBS_ECONFLICT, srv_db_finish(a2, id, att, SRV_FAILED, "previous boot's", 0.5, &E));
  srv_db_close(a2);
  expect_unchanged_running(s->a, id, "node-a");
  succeed(s->a, id, att, NULL, 0, 0);
  RC(OBS_ECONFLICT, srv_db_finish(s->a, id, att, SRV_FAILED, "after the end", 0.5, &E));
  RC(OBS_ECONFLICT, srv_db_requeue(s->a, id, att, &E));
  assert_int_equal(state_of(s->b, id), SRV_SUCCEEDED);
}

static void test_heartbeat(void **state) {
  store *s = *state;
  int64_t mine = insert(s->a, "ssao", 0), theirs = insert(s->a, "ssao", 0);
  int am = 0, at = 0;
  assert_int_equal(claim(s->a, &am), mine);
  assert_int_equal(claim(s->b, &at), theirs);
  int64_t ids[2] = {mine, theirs};
  int atts[2] = {am, at};
  int held[2] = {-1, -1}, cancel[2] = {-1, -1};
  OK(srv_db_heartbeat(s->a, ids, atts, 2, held, cancel, &E));
  assert_int_equal(held[0], 1);
  assert_int_equal(held[1], 0);
  assert_int_equal(cancel[0], 0);
  int wrong = am + 1;
  OK(srv_db_heartbeat(s->a, ids, &wrong, 1, held, cancel, &E));
  assert_int_equal(held[0], 0); /* another attempt of the job is not held */
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, mine, &res, &E));
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  OK(srv_db_heartbeat(s->a, ids, atts, 1, held, cancel, &E));
  assert_int_equal(held[0], 1);
  assert_int_equal(cancel[0], 1);
  OK(srv_db_finish(s->a, mine, am, SRV_CANCELLED, "cancelled by request", 0.3, &E));
  OK(srv_db_heartbeat(s->a, ids, atts, 1, held, cancel, &E));
  assert_int_equal(held[0], 0);
}

typedef struct claimer {
  srv_db *db;
  int64_t ids[64];
  int n, rc;
  char msg[256];
} claimer;

static void *claim_loop(void *arg) {
  claimer *c = arg;
  obs_err e = OBS_ERR_INIT;
  for (;;) {
    srv_job j;
    int rc = srv_db_claim(c->db, SRV_LANE_CPU, &j, &e);
    if (rc == 1) break;
    if (rc < 0 || c->n == 64) {
      c->rc = rc < 0 ? rc : -1;
      snprintf(c->msg, sizeof c->msg, "%s", obs_err_message(&e));
      break;
    }
    c->ids[c->n++] = j.id;
    srv_job_free(&j);
  }
  obs_err_free(&e);
  return NULL;
}

static void test_two_nodes_claim_each_job_once(void **state) {
  store *s = *state;
  enum { N = 50 };
  int64_t ids[N];
  for (int i = 0; i < N; i++) ids[i] = insert(s->a, "ssao", i % 3);
  claimer c[2] = {{.db = s->a}, {.db = s->b}};
  pthread_t t[2];
  for (int i = 0; i < 2; i++) assert_int_equal(pthread_create(&t[i], NULL, claim_loop, &c[i]), 0);
  for (int i = 0; i < 2; i++) pthread_join(t[i], NULL);
  for (int i = 0; i < 2; i++)
    if (c[i].rc) fail_msg("claimer %d: %d %s", i, c[i].rc, c[i].msg);
  assert_int_equal(c[0].n + c[1].n, N);
  for (int i = 0; i < N; i++) {
    int seen = 0;
    for (int k = 0; k < 2; k++)
      for (int m = 0; m < c[k].n; m++) seen += c[k].ids[m] == ids[i];
    if (seen != 1) fail_msg("job %lld claimed %d times", (long long)ids[i], seen);
    srv_job j = get(s->a, ids[i]);
    assert_int_equal(j.state, SRV_RUNNING);
    assert_int_equal(j.attempts, 1);
    srv_job_free(&j);
  }
}

/* ---- leases: the reaper, the per-node exclusion, recovery ----------------------------------- */

/* PostgreSQL: `holder` (a 1 s lease) claims job `id` and never heartbeats, max_attempts times; each
 * expiry is reaped by another node: requeued behind a back-off with the attempt counted, the late
 * holder refused, and at the last attempt the job fails naming the node. */
static void expire_until_failed(store *s, srv_db *holder, int64_t id) {
  for (int attempt = 1; attempt <= SRV_MAX_ATTEMPTS; attempt++) {
    int att = 0;
    int64_t got = 0;
    double t0 = now_ms();
    while (!(got = claim(holder, &att)) && now_ms() - t0 < 20000) sleep_ms(100);
    assert_int_equal(got, id);
    assert_int_equal(att, attempt);
    sleep_ms(2000);
    int requeued = -1, failed = -1;
    OK(srv_db_reap(s->b, &requeued, &failed, &E));
    srv_job j = get(s->a, id);
    if (attempt < SRV_MAX_ATTEMPTS) {
      assert_int_equal(requeued, 1);
      assert_int_equal(failed, 0);
      assert_int_equal(j.state, SRV_QUEUED);
      assert_int_equal(j.attempts, attempt);
      /* Backed off: run_after lies ahead, so no node can claim it yet. */
      assert_int_equal(claim(s->b, NULL), 0);
      RC(OBS_ECONFLICT, srv_db_finish_success(holder, id, att, "cpu", "{}", NULL, 0, NULL, 0, 0,
                                              &E));
      int held = -1, cancel = -1;
      OK(srv_db_heartbeat(holder, &id, &att, 1, &held, &cancel, &E));
      assert_int_equal(held, 0);
      assert_int_equal(state_of(s->a, id), SRV_QUEUED);
    } else {
      assert_int_equal(requeued, 0);
      assert_int_equal(failed, 1);
      assert_int_equal(j.state, SRV_FAILED);
      assert_non_null(j.error);
      if (!strstr(j.error, "node-h")) fail_msg("the error does not name the node: %s", j.error);
    }
    srv_job_free(&j);
  }
}

static void test_reap(void **state) {
  store *s = *state;
  srv_db *h = open_node(s, "node-h", 1);
  int64_t id = insert(s->a, "ssao", 0);
  if (!s->pg) {
    /* One daemon owns a SQLite file: its leases never expire while it lives. */
    int att = 0;
    assert_int_equal(claim(h, &att), id);
    sleep_ms(1500);
    int requeued = -1, failed = -1;
    RC(0, srv_db_reap(s->b, &requeued, &failed, &E));
    assert_int_equal(requeued, 0);
    assert_int_equal(failed, 0);
    assert_int_equal(state_of(s->a, id), SRV_RUNNING);
    succeed(h, id, att, NULL, 0, 0);
  } else {
    expire_until_failed(s, h, id);
  }
  srv_db_close(h);
}

static void test_exclusion(void **state) {
  store *s = *state;
  if (!s->pg) {
    printf("skipped on SQLite: no failure of a node can be recorded through the store interface "
           "there (its reap never expires a lease), so the exclusion is checked on PostgreSQL\n");
    skip();
  }
  srv_db *h = open_node(s, "node-h", 1);
  int64_t id = insert(s->a, "ssao", 0);
  expire_until_failed(s, h, id);
  srv_state st;
  OK(srv_db_retry(s->a, id, &st, &E));
  assert_int_equal(state_of(s->a, id), SRV_QUEUED);
  assert_int_equal(claim(h, NULL), 0); /* node-h failed it three times */
  srv_db *h2 = open_node(s, "node-h", 30); /* its next boot too: the node, not the boot */
  assert_int_equal(claim(h2, NULL), 0);
  srv_db_close(h2);
  int att = 0;
  assert_int_equal(claim(s->b, &att), id);
  succeed(s->b, id, att, NULL, 0, 0);
  srv_db_close(h);
}

typedef struct recovered {
  int64_t cleaned[8];
  int ncleaned;
} recovered;

/* The scheduler's lane choice at recovery: technique "moved" now runs on the CPU lane, "refused"
 * has no lane here; anything else keeps its lane. */
static int pick_lane(void *user, const char *technique, const char *backend_requested,
                     srv_lane stored, srv_lane *lane, obs_err *err) {
  (void)user, (void)backend_requested;
  if (!strcmp(technique, "refused"))
    return obs_err_set(err, OBS_EUNSUPPORTED, "no lane for technique refused");
  *lane = !strcmp(technique, "moved") ? SRV_LANE_CPU : stored;
  return 0;
}

static void note_clean(void *user, int64_t id) {
  recovered *r = user;
  if (r->ncleaned < 8) r->cleaned[r->ncleaned++] = id;
}

static void test_recover(void **state) {
  store *s = *state;
  int64_t left = insert(s->a, "ssao", 2), cancelled = insert(s->a, "ssao", 1);
  int64_t other = insert(s->a, "ssao", 0);
  int att = 0, other_att = 0;
  assert_int_equal(claim(s->a, &att), left);
  assert_int_equal(claim(s->a, &att), cancelled);
  assert_int_equal(claim(s->b, &other_att), other);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, cancelled, &res, &E));
  int64_t moved = insert_vulkan(s->a, "moved", 0), refused = insert_vulkan(s->a, "refused", 0);
  srv_db_close(s->a); /* node-a dies with two jobs running */
  s->a = open_node(s, "node-a", 30);
  recovered r = {0};
  OK(srv_db_recover(s->a, pick_lane, note_clean, &r, &E));
  srv_job j = get(s->b, left);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_int_equal(j.attempts, 1);
  srv_job_free(&j);
  assert_int_equal(state_of(s->b, cancelled), SRV_CANCELLED);
  j = get(s->b, refused);
  if (s->pg) { /* a shared queue's jobs keep their lanes: whichever node has the lane claims */
    assert_int_equal(j.state, SRV_QUEUED);
    assert_int_equal(j.lane, SRV_LANE_VULKAN);
  } else { /* the one daemon's lanes decide */
    assert_int_equal(j.state, SRV_FAILED);
    assert_non_null(j.error);
    assert_non_null(strstr(j.error, "no lane for technique refused"));
  }
  srv_job_free(&j);
  int found = 0;
  for (int i = 0; i < r.ncleaned; i++) found += r.cleaned[i] == left;
  assert_int_equal(found, 1);
  if (s->pg) { /* another node's running job is that node's */
    j = get(s->b, other);
    assert_int_equal(j.state, SRV_RUNNING);
    assert_string_equal(j.node, "node-b");
    srv_job_free(&j);
    succeed(s->b, other, other_att, NULL, 0, 0);
  }
  assert_int_equal(claim(s->a, &att), left);
  assert_int_equal(att, 2); /* the interrupted attempt counts */
  int64_t next = claim(s->a, NULL);
  if (next == other) next = claim(s->a, NULL);
  if (s->pg) {
    assert_int_equal(next, 0);
    srv_job vj;
    OK(srv_db_claim(s->a, SRV_LANE_VULKAN, &vj, &E));
    assert_int_equal(vj.id, moved);
    srv_job_free(&vj);
  } else {
    assert_int_equal(next, moved);
  }
}

/* ---- comparisons ---------------------------------------------------------------------------- */

/* A comparison of two candidates (ssao, hbao) against one rt_ao reference, plus a further
 * measurement of the first candidate ("common"): candidate rows 0, 1, 2. */
static int64_t insert_comparison(srv_db *db, const char *label) {
  srv_new_job ref = job_of("rt_ao", 0);
  ref.spp = 1024;
  srv_new_candidate cand[2] = {
      {.job = job_of("ssao", 0), .reference = 0, .technique = "ssao", .backend = "cpu",
       .params = "{\"radius\":0.5}", .reference_params = "{}", .response = "{}"},
      {.job = job_of("hbao", 0), .reference = 0, .technique = "hbao", .backend = "cpu",
       .params = "{}", .reference_params = "{}", .response = "{}"}};
  srv_new_measure m = {.candidate = 0, .reference = 0, .role = "common",
                       .reference_params = "{}", .response = "{}"};
  srv_new_comparison c = {.label = label, .scene = "cornell_box.json", .request = "{}",
                          .width = 32, .height = 24, .repeats = 1, .references = &ref,
                          .nreferences = 1, .candidates = cand, .ncandidates = 2,
                          .measures = &m, .nmeasures = 1};
  int64_t id = 0;
  OK(srv_db_insert_comparison(db, &c, &id, &E));
  assert_true(id > 0);
  return id;
}

static void test_comparison(void **state) {
  store *s = *state;
  int64_t older = insert_comparison(s->a, "older"), cmp = insert_comparison(s->a, "cmp");
  json_t *r = query(s->b, SRV_Q_COMPARISONS, 0, 10, 2);
  assert_int_equal(json_array_size(r), 2);
  assert_int_equal(col_int(r, 0, "id"), cmp);
  assert_int_equal(col_int(r, 1, "id"), older);
  json_decref(r);
  r = query(s->b, SRV_Q_COMPARISONS, cmp, 10, 2);
  assert_int_equal(json_array_size(r), 1);
  assert_int_equal(col_int(r, 0, "id"), older);
  json_decref(r);
  json_t *cands = query(s->b, SRV_Q_CANDIDATES, cmp, 0, 1);
  assert_int_equal(json_array_size(cands), 3);
  int64_t ref = col_int(cands, 0, "reference_job"), c0 = col_int(cands, 0, "job");
  int64_t c1 = col_int(cands, 1, "job");
  for (size_t i = 0; i < 3; i++) {
    assert_int_equal(col_int(cands, i, "idx"), (int64_t)i);
    assert_int_equal(col_int(cands, i, "reference_job"), ref);
    assert_string_equal(col_str(cands, i, "state"), "queued");
  }
  assert_string_equal(col_str(cands, 0, "role"), "own");
  assert_string_equal(col_str(cands, 1, "technique"), "hbao");
  assert_string_equal(col_str(cands, 2, "role"), "common");
  assert_int_equal(col_int(cands, 2, "job"), c0);
  json_decref(cands);
  srv_job j = get(s->b, c1);
  assert_int_equal(j.comparison, cmp);
  srv_job_free(&j);
  r = query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  assert_string_equal(col_str(r, 0, "label"), "cmp");
  assert_int_equal(col_int(r, 0, "candidates"), 2);
  assert_int_equal(col_int(r, 0, "active"), 3);
  json_decref(r);
  int64_t *ids = NULL;
  int nids = 0;
  RC(OBS_EINVAL, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &E));
  assert_int_equal(state_of(s->a, ref), SRV_QUEUED);

  /* Run the older comparison's three jobs out of the way (cancelled), then this one's. */
  for (int i = 0; i < 3; i++) {
    int att = 0;
    int64_t id = claim(s->a, &att);
    OK(srv_db_finish(s->a, id, att, SRV_CANCELLED, "not needed", 0, &E));
  }
  r = query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  int att[3] = {0};
  assert_int_equal(claim(s->a, &att[0]), ref); /* references first */
  assert_int_equal(claim(s->a, &att[1]), c0);
  assert_int_equal(claim(s->a, &att[2]), c1);
  succeed(s->a, ref, att[0], NULL, 0, 0);
  succeed(s->a, c0, att[1], NULL, 0, 0);
  OK(srv_db_finish(s->a, c1, att[2], SRV_FAILED, "broke", 0.5, &E));
  RC(OBS_EUNSUPPORTED, srv_db_delete(s->b, ref, &E)); /* comparisons keep their jobs */
  r = query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 2);
  assert_int_equal(col_int(r, 0, "comparison"), cmp);
  assert_int_equal(col_int(r, 0, "idx"), 0);
  assert_int_equal(col_int(r, 1, "idx"), 2);
  assert_int_equal(col_int(r, 1, "job"), c0);
  json_decref(r);
  r = query(s->b, SRV_Q_METRICS_PENDING, c1, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);

  srv_output err_map = {.name = "error_ssao", .size = 77, .content_type = "image/png"};
  memset(err_map.sha256, 'e', 64);
  OK(srv_db_set_metrics(s->b, cmp, 0, c0, "{\"rmse\":0.5}", NULL, &err_map, 1, &E));
  OK(srv_db_set_metrics(s->b, cmp, 0, c0, "{\"rmse\":9}", NULL, NULL, 0, &E));
  cands = query(s->b, SRV_Q_CANDIDATES, cmp, 0, 1);
  json_t *m = json_loads(col_str(cands, 0, "metrics"), 0, NULL);
  assert_non_null(m);
  assert_true(json_number_value(json_object_get(m, "rmse")) == 0.5); /* stored once */
  json_decref(m);
  assert_string_equal(col_str(cands, 1, "state"), "failed");
  json_decref(cands);
  srv_output o;
  OK(srv_db_get_output(s->b, c0, "error_ssao", &o, &E));
  assert_int_equal(o.size, 77);
  r = query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(col_int(r, 0, "active"), 0);
  assert_int_equal(col_int(r, 0, "measured"), 1);
  assert_int_equal(col_int(r, 0, "broken"), 1);
  assert_int_equal(col_int(r, 0, "measuring"), 1);
  json_decref(r);
  /* Row 2 still awaits its figures: deleting would pull the jobs from under them. */
  RC(OBS_EINVAL, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &E));
  OK(srv_db_set_metrics(s->b, cmp, 2, c0, NULL, "no common reference", NULL, 0, &E));
  r = query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  OK(srv_db_delete_comparison(s->b, cmp, &ids, &nids, &E));
  assert_int_equal(nids, 3);
  int64_t want[3] = {ref, c0, c1};
  for (int i = 0; i < 3; i++) {
    int hit = 0;
    for (int k = 0; k < nids; k++) hit += ids[k] == want[i];
    assert_int_equal(hit, 1);
    RC(0, srv_db_job_exists(s->a, want[i], NULL, &E));
  }
  free(ids);
  r = query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  RC(OBS_ENOTFOUND, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &E));
  r = query(s->b, SRV_Q_COMPARISON, older, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  json_decref(r);
}

/* ---- the admission limits' reads ------------------------------------------------------------ */

static void test_limits(void **state) {
  store *s = *state;
  int64_t done = insert(s->a, "ssao", 9);
  int att = 0;
  assert_int_equal(claim(s->a, &att), done);
  succeed(s->a, done, att, NULL, 0, 0);
  OK(srv_db_set_job_client(s->a, done, 0, "alice", &E)); /* finished: no load */
  srv_new_job j1 = job_of("ssao", 0), j2 = job_of("ssao", 0), j3 = job_of("ssao", 0);
  j1.work = 100, j1.repeats = 2, j1.warmup = 1;
  j2.work = 50, j2.ranks = 4;
  j3.work = 10;
  int64_t id1, id2, id3;
  OK(srv_db_insert_job(s->a, &j1, &id1, &E));
  OK(srv_db_insert_job(s->a, &j2, &id2, &E));
  OK(srv_db_insert_job(s->a, &j3, &id3, &E));
  OK(srv_db_set_job_client(s->a, id1, 0, "alice", &E));
  OK(srv_db_set_job_client(s->a, id2, 0, "alice", &E));
  OK(srv_db_set_job_client(s->a, id3, 0, "bob", &E));
  assert_int_equal(claim(s->b, &att), id1); /* running still loads the queue */
  srv_load mine, total;
  OK(srv_db_queued(s->b, "alice", &mine, &total, &E));
  assert_true(mine.work == 100 * 3 + 50);
  assert_true(mine.jobs == 1 + 4);
  assert_true(mine.bytes == (double)(srv_job_stored_bytes(&j1) + srv_job_stored_bytes(&j2)));
  assert_true(total.work == 100 * 3 + 50 + 10);
  assert_true(total.jobs == 6);
  assert_true(total.bytes == mine.bytes + (double)srv_job_stored_bytes(&j3));
  OK(srv_db_queued(s->b, "nobody", &mine, &total, &E));
  assert_true(mine.work == 0 && mine.jobs == 0 && mine.bytes == 0);
  srv_load load;
  srv_state st;
  OK(srv_db_job_load(s->b, id2, &load, &st, &E));
  assert_true(load.work == 50 && load.jobs == 4);
  assert_true(load.bytes == (double)srv_job_stored_bytes(&j2));
  assert_int_equal(st, SRV_QUEUED);
  OK(srv_db_job_load(s->b, id1, &load, &st, &E));
  assert_true(load.work == 300);
  assert_int_equal(st, SRV_RUNNING);
  RC(OBS_ENOTFOUND, srv_db_job_load(s->b, id3 + 1000, &load, &st, &E));
  /* A comparison's client is every one of its jobs'. */
  int64_t cmp = insert_comparison(s->a, "limits");
  OK(srv_db_set_job_client(s->a, 0, cmp, "carol", &E));
  OK(srv_db_queued(s->b, "carol", &mine, &total, &E));
  assert_true(mine.jobs == 3);
  assert_true(mine.work == 3 * 32.0 * 24 * 4);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void test_run_rates(void **state) {
  store *s = *state;
  int64_t m = 0, m_again = 0, other = 0;
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &m, &E));
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &m_again, &E));
  OK(srv_db_machine(s->a, "Other CPU", 4, "llvmpipe", "software", &other, &E));
  assert_int_equal(m, m_again);
  assert_true(other != m);
  static const double works[4] = {1000, 2000, 10, 1000};
  static const srv_run runs[4][2] = {{{0, 0, 0, 10}, {0, 0, 0, 12}}, {{0, 0, 0, 40}},
                                     {{0, 0, 0, 5}}, {{0, 0, 0, 7}}};
  static const int nruns[4] = {2, 1, 1, 1};
  for (int i = 0; i < 4; i++) {
    srv_new_job nj = job_of("rt_ao", 0);
    nj.work = works[i];
    int64_t id;
    int att = 0;
    OK(srv_db_insert_job(s->a, &nj, &id, &E));
    assert_int_equal(claim(s->a, &att), id);
    succeed(s->a, id, att, runs[i], nruns[i], i == 3 ? other : m);
  }
  double *rates = NULL;
  size_t n = 0;
  OK(srv_db_run_rates(s->b, "rt_ao", "cpu", m, 100, &rates, &n, &E));
  assert_int_equal(n, 3); /* not the small job, not the other machine's */
  qsort(rates, n, sizeof *rates, cmp_double);
  assert_true(fabs(rates[0] - 10.0 / 1000) < 1e-12);
  assert_true(fabs(rates[1] - 12.0 / 1000) < 1e-12);
  assert_true(fabs(rates[2] - 40.0 / 2000) < 1e-12);
  free(rates);
  OK(srv_db_run_rates(s->b, "rt_ao", "vulkan", m, 0, &rates, &n, &E));
  assert_int_equal(n, 0);
  free(rates);
}

/* ---- blobs, retention, wake-ups ------------------------------------------------------------- */

static void test_blobs(void **state) {
  store *s = *state;
  static const char sha[] = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
  unsigned char data[3000];
  uint32_t seed = 7;
  for (size_t i = 0; i < sizeof data; i++) data[i] = (unsigned char)obs_test_rand(&seed);
  data[10] = 0; /* bytes, not text */
  void *got = NULL;
  size_t n = 0;
  if (!s->pg) { /* a SQLite store's outputs are local files */
    OK(srv_db_put_blob(s->a, sha, data, sizeof data, &E));
    RC(OBS_ENOTFOUND, srv_db_get_blob(s->b, sha, &got, &n, &E));
    assert_int_equal(srv_db_results_shared(s->a), 0);
    return;
  }
  RC(OBS_ENOTFOUND, srv_db_get_blob(s->b, sha, &got, &n, &E));
  OK(srv_db_put_blob(s->a, sha, data, sizeof data, &E));
  OK(srv_db_put_blob(s->b, sha, data, sizeof data, &E)); /* idempotent */
  OK(srv_db_get_blob(s->b, sha, &got, &n, &E));
  assert_int_equal(n, sizeof data);
  assert_memory_equal(got, data, sizeof data);
  free(got);
}

static int64_t finish_one(srv_db *db, int64_t id) {
  int att = 0;
  int64_t got = claim(db, &att);
  if (got != id) fail_msg("claimed %lld, expected %lld", (long long)got, (long long)id);
  succeed(db, id, att, NULL, 0, 0);
  return id;
}

/* The comparison's jobs: reference, candidate 0, candidate 1. */
static void comparison_jobs(srv_db *db, int64_t cmp, int64_t out[3]) {
  json_t *c = query(db, SRV_Q_CANDIDATES, cmp, 0, 1);
  out[0] = col_int(c, 0, "reference_job");
  out[1] = col_int(c, 0, "job");
  out[2] = col_int(c, 1, "job");
  json_decref(c);
}

/* Stores figures for every candidate row of comparison `cmp` that awaits them, so that nothing of
 * it is still being measured. */
static void measure_all(srv_db *db, int64_t cmp) {
  json_t *p = query(db, SRV_Q_METRICS_PENDING, 0, 0, 1);
  for (size_t i = 0; i < json_array_size(p); i++)
    if (col_int(p, i, "comparison") == cmp)
      OK(srv_db_set_metrics(db, cmp, (int)col_int(p, i, "idx"), col_int(p, i, "job"), "{}",
                            NULL, NULL, 0, &E));
  json_decref(p);
}

static int contains(const int64_t *ids, int n, int64_t id) {
  int hit = 0;
  for (int i = 0; i < n; i++) hit += ids[i] == id;
  return hit;
}

static void test_prune(void **state) {
  store *s = *state;
  int64_t *ids = NULL;
  int nids = -1;
  obs_err_clear(&E);
  if (srv_db_prune(s->a, 0, 0, &ids, &nids, &E) == OBS_EUNSUPPORTED) {
    printf("skipped: srv_db_prune returns OBS_EUNSUPPORTED on this store (%s)\n",
           obs_err_message(&E));
    skip();
  }
  assert_int_equal(nids, 0);
  free(ids);
  /* Finished in this order: C1's three jobs, j1, j2, C2's reference, j3, C2's candidates. */
  int64_t c1 = insert_comparison(s->a, "c1"), c1j[3];
  comparison_jobs(s->a, c1, c1j);
  for (int i = 0; i < 3; i++) finish_one(s->a, c1j[i]);
  measure_all(s->a, c1);
  int64_t j1 = finish_one(s->a, insert(s->a, "ssao", 0));
  int64_t j2 = finish_one(s->a, insert(s->a, "ssao", 0));
  int64_t c2 = insert_comparison(s->a, "c2"), c2j[3];
  comparison_jobs(s->a, c2, c2j);
  finish_one(s->a, c2j[0]);
  int64_t j3 = insert(s->a, "ssao", 0);
  int att[2] = {0};
  assert_int_equal(claim(s->a, &att[0]), c2j[1]);
  assert_int_equal(claim(s->a, &att[1]), c2j[2]);
  finish_one(s->a, j3);
  succeed(s->a, c2j[1], att[0], NULL, 0, 0);
  succeed(s->a, c2j[2], att[1], NULL, 0, 0);
  measure_all(s->a, c2);

  OK(srv_db_prune(s->b, 3, 0, &ids, &nids, &E));
  /* Beyond the newest three: C1 whole and j1, j2; C2's reference is too, but not all of C2. */
  assert_int_equal(nids, 5);
  for (int i = 0; i < 3; i++) assert_int_equal(contains(ids, nids, c1j[i]), 1);
  assert_int_equal(contains(ids, nids, j1), 1);
  assert_int_equal(contains(ids, nids, j2), 1);
  free(ids);
  for (int i = 0; i < 3; i++) {
    RC(0, srv_db_job_exists(s->a, c1j[i], NULL, &E));
    RC(1, srv_db_job_exists(s->a, c2j[i], NULL, &E));
  }
  RC(0, srv_db_job_exists(s->a, j1, NULL, &E));
  RC(1, srv_db_job_exists(s->a, j3, NULL, &E));
  json_t *r = query(s->b, SRV_Q_COMPARISON, c1, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);

  /* Age: everything finished is older than a few milliseconds, the queued job is not finished,
   * and a comparison with a queued job stays whole. */
  int64_t c3 = insert_comparison(s->a, "c3"), c3j[3];
  comparison_jobs(s->a, c3, c3j);
  finish_one(s->a, c3j[0]);
  int64_t waiting = insert(s->a, "ssao", 0);
  sleep_ms(300);
  OK(srv_db_prune(s->b, 0, 1e-6 /* 86 ms */, &ids, &nids, &E));
  assert_int_equal(nids, 4);
  assert_int_equal(contains(ids, nids, j3), 1);
  for (int i = 0; i < 3; i++) assert_int_equal(contains(ids, nids, c2j[i]), 1);
  free(ids);
  RC(1, srv_db_job_exists(s->a, waiting, NULL, &E));
  for (int i = 0; i < 3; i++) RC(1, srv_db_job_exists(s->a, c3j[i], NULL, &E));
  int64_t counts[SRV_NSTATES];
  OK(srv_db_counts(s->a, counts, &E));
  assert_int_equal(counts[SRV_SUCCEEDED], 1);
  assert_int_equal(counts[SRV_QUEUED], 3);
}

/* Drains what earlier statements notified, so the next wake-up is the one a test causes. */
static void drain(srv_db *db) {
  int what = 0;
  for (int i = 0; i < 50; i++) {
    obs_err_clear(&E);
    int rc = srv_db_wait(db, 200, &what, &E);
    if (rc < 0) fail_msg("wait -> %d: %s", rc, obs_err_message(&E));
    if (rc == 0) return;
  }
  fail_msg("the wake-ups never stopped");
}

static void test_wait(void **state) {
  store *s = *state;
  int what = -1;
  if (!s->pg) { /* no other node: the scheduler's own notify wakes its workers */
    double t0 = now_ms();
    RC(0, srv_db_wait(s->a, 300, &what, &E));
    assert_true(now_ms() - t0 >= 290);
    assert_int_equal(what, 0);
    return;
  }
  drain(s->a);
  int64_t id = insert(s->b, "ssao", 0);
  RC(1, srv_db_wait(s->a, 5000, &what, &E));
  assert_true(what & SRV_WAKE_JOBS);
  drain(s->a);
  int att = 0;
  assert_int_equal(claim(s->a, &att), id);
  drain(s->a);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, id, &res, &E));
  what = 0;
  RC(1, srv_db_wait(s->a, 5000, &what, &E));
  assert_true(what & SRV_WAKE_CANCEL);
  drain(s->a);
  insert_comparison(s->b, "wake");
  what = 0;
  RC(1, srv_db_wait(s->a, 5000, &what, &E));
  assert_true(what & SRV_WAKE_JOBS);
  drain(s->a);
  RC(0, srv_db_wait(s->a, 200, &what, &E));
}

int main(void) {
#define T(f) cmocka_unit_test_setup_teardown(f, setup, teardown)
  const struct CMUnitTest tests[] = {
      T(test_insert_claim_succeed),
      T(test_finish_keeps_progress),
      T(test_requeue_does_not_count),
      T(test_cancel),
      T(test_retry),
      T(test_delete_and_counts),
      T(test_priorities_fifo_and_lanes),
      T(test_list_filters_and_paging),
      T(test_attempt_guard),
      T(test_heartbeat),
      T(test_two_nodes_claim_each_job_once),
      T(test_reap),
      T(test_exclusion),
      T(test_recover),
      T(test_comparison),
      T(test_limits),
      T(test_run_rates),
      T(test_blobs),
      T(test_prune),
      T(test_wait),
  };
  int rc = cmocka_run_group_tests(tests, NULL, NULL);
  obs_err_free(&E);
  return rc;
}
