/* The store contract suite's store under test (store_contract.h): a fresh SQLite file, or a fresh
 * PostgreSQL database made with libpq on the server OBSCURA_TEST_STORE names, with nodes "node-a"
 * and "node-b" opened on it; and the helpers the cases share, which reach the store only through
 * srv_db. */
#include <libpq-fe.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "store_contract.h"

obs_err contract_err = OBS_ERR_INIT;

static const char *store_env(void) {
  const char *v = getenv("OBSCURA_TEST_STORE");
  return v && *v ? v : NULL;
}

static int is_pg(void) {
  const char *v = store_env();
  return v && (!strncmp(v, "postgresql://", 13) || !strncmp(v, "postgres://", 11));
}

srv_db *sc_open_node(const store *s, const char *name, int lease_seconds) {
  srv_node n;
  srv_node_init(&n, name, lease_seconds);
  srv_db *db = NULL;
  OK(srv_db_open(&db, s->where, 4, &n, &contract_err));
  return db;
}

static void no_notice(void *arg, const char *message) { (void)arg, (void)message; }

/* Runs one administrative statement on the server of `url` (creating or dropping this test's
 * database: the store itself is reached only through srv_db). */
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

int sc_setup(void **state) {
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
  s->a = sc_open_node(s, "node-a", 30);
  s->b = sc_open_node(s, "node-b", 30);
  *state = s;
  return 0;
}

int sc_teardown(void **state) {
  store *s = *state;
  srv_db_close(s->a);
  srv_db_close(s->b);
  for (int i = 0; i < 2; i++) srv_db_close(s->more[i]);
  if (s->pg) {
    char sql[200];
    snprintf(sql, sizeof sql, "DROP DATABASE IF EXISTS %s WITH (FORCE)", s->dbname);
    pg_admin(store_env(), sql);
  }
  free(s);
  return 0;
}

/* ---- helpers ------------------------------------------------------------------------------ */

srv_new_job sc_job_of(const char *technique, int priority) {
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

int64_t sc_insert(srv_db *db, const char *technique, int priority) {
  srv_new_job nj = sc_job_of(technique, priority);
  int64_t id = 0;
  OK(srv_db_insert_job(db, &nj, &id, &contract_err));
  assert_true(id > 0);
  return id;
}

int64_t sc_insert_vulkan(srv_db *db, const char *technique, int priority) {
  srv_new_job nj = sc_job_of(technique, priority);
  nj.backend_requested = "vulkan";
  nj.lane = SRV_LANE_VULKAN;
  int64_t id = 0;
  OK(srv_db_insert_job(db, &nj, &id, &contract_err));
  return id;
}

int64_t sc_claim(srv_db *db, int *attempt) {
  srv_job j;
  obs_err_clear(&contract_err);
  int rc = srv_db_claim(db, SRV_LANE_CPU, &j, &contract_err);
  if (rc < 0) fail_msg("claim -> %d: %s", rc, obs_err_message(&contract_err));
  if (rc == 1) return 0;
  int64_t id = j.id;
  if (attempt) *attempt = j.attempts;
  srv_job_free(&j);
  return id;
}

srv_job sc_get(srv_db *db, int64_t id) {
  srv_job j;
  OK(srv_db_get_job(db, id, &j, &contract_err));
  return j;
}

srv_state sc_state_of(srv_db *db, int64_t id) {
  srv_job j = sc_get(db, id);
  srv_state st = j.state;
  srv_job_free(&j);
  return st;
}

void sc_succeed(srv_db *db, int64_t id, int attempt, const srv_run *runs, int nruns,
                int64_t machine) {
  srv_output o = {.name = "ao", .size = 1234, .content_type = "image/png"};
  memset(o.sha256, 'a', 64);
  OK(srv_db_finish_success(db, id, attempt, "cpu", "{\"ok\":true}", &o, 1, runs, nruns, machine,
                           &contract_err));
}

json_t *sc_query(srv_db *db, srv_query q, int64_t a1, int64_t a2, int nargs) {
  srv_arg args[2] = {{.kind = SRV_ARG_INT, .i = a1}, {.kind = SRV_ARG_INT, .i = a2}};
  json_t *rows = NULL;
  OK(srv_db_query(db, q, args, nargs, &rows, &contract_err));
  assert_true(json_is_array(rows));
  return rows;
}

int64_t sc_col_int(json_t *rows, size_t i, const char *col) {
  json_t *v = json_object_get(json_array_get(rows, i), col);
  if (!json_is_integer(v)) fail_msg("row %zu column %s is not an integer", i, col);
  return json_integer_value(v);
}

const char *sc_col_str(json_t *rows, size_t i, const char *col) {
  json_t *v = json_object_get(json_array_get(rows, i), col);
  if (!json_is_string(v)) fail_msg("row %zu column %s is not a string", i, col);
  return json_string_value(v);
}

double sc_now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

void sc_sleep_ms(int ms) {
  struct timespec t = {ms / 1000, (long)(ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

int64_t sc_insert_comparison(srv_db *db, const char *label) {
  srv_new_job ref = sc_job_of("rt_ao", 0);
  ref.spp = 1024;
  srv_new_candidate cand[2] = {{.job = sc_job_of("ssao", 0),
                                .reference = 0,
                                .technique = "ssao",
                                .backend = "cpu",
                                .params = "{\"radius\":0.5}",
                                .reference_params = "{}",
                                .response = "{}"},
                               {.job = sc_job_of("hbao", 0),
                                .reference = 0,
                                .technique = "hbao",
                                .backend = "cpu",
                                .params = "{}",
                                .reference_params = "{}",
                                .response = "{}"}};
  srv_new_measure m = {
      .candidate = 0, .reference = 0, .role = "common", .reference_params = "{}", .response = "{}"};
  srv_new_comparison c = {.label = label,
                          .scene = "cornell_box.json",
                          .request = "{}",
                          .width = 32,
                          .height = 24,
                          .repeats = 1,
                          .references = &ref,
                          .nreferences = 1,
                          .candidates = cand,
                          .ncandidates = 2,
                          .measures = &m,
                          .nmeasures = 1};
  int64_t id = 0;
  OK(srv_db_insert_comparison(db, &c, &id, &contract_err));
  assert_true(id > 0);
  return id;
}

int64_t sc_finish_one(srv_db *db, int64_t id) {
  int att = 0;
  int64_t got = sc_claim(db, &att);
  if (got != id) fail_msg("claimed %lld, expected %lld", (long long)got, (long long)id);
  sc_succeed(db, id, att, NULL, 0, 0);
  return id;
}

void sc_comparison_jobs(srv_db *db, int64_t cmp, int64_t out[3]) {
  json_t *c = sc_query(db, SRV_Q_CANDIDATES, cmp, 0, 1);
  out[0] = sc_col_int(c, 0, "reference_job");
  out[1] = sc_col_int(c, 0, "job");
  out[2] = sc_col_int(c, 1, "job");
  json_decref(c);
}

void sc_measure_all(srv_db *db, int64_t cmp) {
  json_t *p = sc_query(db, SRV_Q_METRICS_PENDING, 0, 0, 1);
  for (size_t i = 0; i < json_array_size(p); i++)
    if (sc_col_int(p, i, "comparison") == cmp)
      OK(srv_db_set_metrics(db, cmp, (int)sc_col_int(p, i, "idx"), sc_col_int(p, i, "job"), "{}",
                            NULL, NULL, 0, &contract_err));
  json_decref(p);
}

int sc_contains(const int64_t *ids, int n, int64_t id) {
  int hit = 0;
  for (int i = 0; i < n; i++) hit += ids[i] == id;
  return hit;
}
