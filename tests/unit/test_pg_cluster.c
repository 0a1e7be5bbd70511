/* The PostgreSQL store shared by several nodes (pg_fixture.h; skipped without
 * OBSCURA_TEST_PG_URL): the admission lock orders nodes, a claim never hands one job to two
 * nodes, an expired lease (by the database's clock) is reaped and the late finish refused, a node
 * failing a job three times is excluded and max_attempts ends it, heartbeats and NOTIFY carry a
 * cancel to the running node, a restarted node requeues what its previous boot ran, and a lost
 * connection or listener is replaced without the caller seeing it. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pg_fixture.h"

typedef struct admitter {
  srv_db *db;
  _Atomic int inside;
} admitter;

static void *admit(void *arg) {
  admitter *a = arg;
  assert_int_equal(srv_db_admit_lock(a->db, NULL), 0);
  a->inside = 1;
  srv_db_admit_unlock(a->db);
  return NULL;
}

/* One node admits at a time, and its section can read and insert through the pool meanwhile. */
static void test_admission_lock(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  assert_int_equal(srv_db_admit_lock(a, NULL), 0);
  srv_load mine, total;
  assert_int_equal(srv_db_queued(a, "x", &mine, &total, NULL), 0);
  pg_insert(a, 50, "rt_ao");
  admitter other = {b, 0};
  pthread_t t;
  pthread_create(&t, NULL, admit, &other);
  usleep(300000);
  assert_int_equal(other.inside, 0); /* beta waits while alpha holds it */
  srv_db_admit_unlock(a);
  pthread_join(t, NULL);
  assert_int_equal(other.inside, 1);
  srv_db_close(b);
}

/* ---- several nodes --------------------------------------------------------------------------- */

typedef struct claimer {
  srv_db *pg;
  int64_t got[200];
  int n;
} claimer;

static void *claim_all(void *arg) {
  claimer *c = arg;
  for (;;) {
    srv_job j;
    int rc = srv_db_claim(c->pg, SRV_LANE_CPU, &j, NULL);
    if (rc) break;
    c->got[c->n++] = j.id;
    srv_job_free(&j);
  }
  return NULL;
}

static void test_two_nodes_claim(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  enum { N = 120 };
  for (int i = 0; i < N; i++) pg_insert(i % 2 ? a : b, 10 + i % 7, "rt_ao");
  claimer ca = {a, {0}, 0}, cb = {b, {0}, 0};
  pthread_t ta, tb;
  pthread_create(&ta, NULL, claim_all, &ca);
  pthread_create(&tb, NULL, claim_all, &cb);
  pthread_join(ta, NULL);
  pthread_join(tb, NULL);
  /* Every job exactly once, each held by the node that claimed it. */
  assert_int_equal(ca.n + cb.n, N);
  static unsigned char seen[N + 1];
  memset(seen, 0, sizeof seen);
  for (int i = 0; i < ca.n; i++) seen[ca.got[i]]++;
  for (int i = 0; i < cb.n; i++) seen[cb.got[i]]++;
  for (int i = 1; i <= N; i++) assert_int_equal(seen[i], 1);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs WHERE state = 'running' AND attempts = 1"), N);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs WHERE node = 'alpha' AND worker = 'alpha/b1'"),
                   ca.n);
  /* A node cannot end the other's job. */
  int64_t theirs = cb.n ? cb.got[0] : 0;
  if (theirs) assert_int_equal(srv_db_finish(a, theirs, 1, SRV_FAILED, "x", 0, NULL), OBS_ECONFLICT);
  srv_db_close(b);
}

static void test_lease_reaped(void **state) {
  NEED_PG();
  srv_db_close(*state);
  srv_db *a = *state = pg_open_node("alpha", "b1", 1), *b = pg_open_node("beta", "b1", 0);
  int64_t id = pg_insert(a, 50, "rt_ao");
  int att;
  assert_true(pg_claim(a, &att) == id);
  int held, cancel;
  int64_t ids[1] = {id};
  int atts[1] = {att};
  assert_int_equal(srv_db_heartbeat(a, ids, atts, 1, &held, &cancel, NULL), 0);
  assert_true(held == 1 && cancel == 0);
  int rq, fl;
  assert_int_equal(srv_db_reap(b, &rq, &fl, NULL), 0);
  assert_true(rq == 0 && fl == 0); /* the lease is still running */
  /* The node stalls past its lease (the database's clock decides). */
  while (pg_sql_int("SELECT count(*) FROM jobs WHERE lease_expires_at < now()") == 0) usleep(100000);
  assert_int_equal(srv_db_reap(b, &rq, &fl, NULL), 0);
  assert_true(rq == 1 && fl == 0);
  assert_int_equal(srv_db_reap(b, &rq, &fl, NULL), 0);
  assert_true(rq == 0 && fl == 0); /* idempotent */
  /* The late node's result and heartbeat are refused. */
  obs_err e = OBS_ERR_INIT;
  assert_int_equal(srv_db_finish_success(a, id, att, "cpu", "{}", NULL, 0, NULL, 0, 0, &e),
                   OBS_ECONFLICT);
  assert_non_null(strstr(obs_err_message(&e), "no longer held"));
  obs_err_free(&e);
  assert_int_equal(srv_db_heartbeat(a, ids, atts, 1, &held, &cancel, NULL), 0);
  assert_int_equal(held, 0);
  srv_job j;
  assert_int_equal(srv_db_get_job(a, id, &j, NULL), 0);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_non_null(strstr(j.error, "lease of node alpha expired"));
  srv_job_free(&j);
  /* Back-off: 2 s x 0.75..1.25 after the first attempt, by the database's clock. */
  int64_t wait_ms = pg_sql_int("SELECT (extract(epoch FROM run_after - now()) * 1000)::bigint FROM jobs");
  assert_true(wait_ms > 1000 && wait_ms <= 2500);
  assert_int_equal(pg_claim(b, NULL), 0);
  assert_int_equal(pg_sql_int("SELECT failures FROM job_node_failures WHERE node = 'alpha'"), 1);
  srv_db_close(b);
}

/* A lease lost `times` times by node pg on job id, without waiting for leases or back-off. */
static void lose_lease(srv_db *pg, int64_t id, int times) {
  char q[200];
  for (int i = 0; i < times; i++) {
    int att;
    assert_true(pg_claim(pg, &att) == id);
    snprintf(q, sizeof q, "UPDATE jobs SET lease_expires_at = now() - interval '1 s' WHERE id = %lld",
             (long long)id);
    pg_sql(q);
    int rq, fl;
    assert_int_equal(srv_db_reap(pg, &rq, &fl, NULL), 0);
    assert_int_equal(rq + fl, 1);
    pg_sql("UPDATE jobs SET run_after = now() WHERE state = 'queued'");
  }
}

static void test_exclusion_and_max_attempts(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  int64_t id = pg_insert(a, 50, "rt_ao");
  pg_sql("UPDATE jobs SET max_attempts = 10");
  lose_lease(a, id, 3);
  /* Node alpha failed it three times: it no longer sees it; beta does. */
  assert_int_equal(pg_claim(a, NULL), 0);
  int att;
  assert_true(pg_claim(b, &att) == id);
  assert_int_equal(att, 4);
  srv_db_close(b);
  /* At max_attempts the reaper fails the job, saying why. */
  int64_t other = pg_insert(a, 50, "rt_ao");
  lose_lease(a, other, 2);
  int rq, fl;
  assert_true(pg_claim(a, &att) == other);
  assert_int_equal(att, 3);
  pg_sql("UPDATE jobs SET lease_expires_at = now() - interval '1 s' WHERE state = 'running' AND "
      "node = 'alpha'");
  assert_int_equal(srv_db_reap(a, &rq, &fl, NULL), 0);
  assert_true(rq == 0 && fl == 1);
  srv_job j;
  assert_int_equal(srv_db_get_job(a, other, &j, NULL), 0);
  assert_int_equal(j.state, SRV_FAILED);
  assert_string_equal(j.error, "lease of node alpha expired 3 times");
  srv_job_free(&j);
}

static void test_heartbeat_cancel_and_wait(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  int what = 0;
  /* The first wait opens the listener and reports a look at the queue (what it missed). */
  assert_int_equal(srv_db_wait(a, 0, &what, NULL), 1);
  assert_int_equal(what, SRV_WAKE_JOBS);
  assert_int_equal(srv_db_wait(a, 50, &what, NULL), 0);
  int64_t id = pg_insert(b, 50, "rt_ao"); /* another node's submission wakes this one */
  assert_int_equal(srv_db_wait(a, 10000, &what, NULL), 1);
  assert_int_equal(what, SRV_WAKE_JOBS);
  int att;
  assert_true(pg_claim(a, &att) == id);
  srv_cancel_result res;
  assert_int_equal(srv_db_cancel(b, id, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  do assert_int_equal(srv_db_wait(a, 10000, &what, NULL), 1);
  while (what == SRV_WAKE_JOBS);
  assert_int_equal(what, SRV_WAKE_CANCEL);
  int held, cancel;
  assert_int_equal(srv_db_heartbeat(a, &id, &att, 1, &held, &cancel, NULL), 0);
  assert_true(held == 1 && cancel == 1);
  /* A job no longer running is not held. */
  assert_int_equal(srv_db_finish(a, id, att, SRV_CANCELLED, "cancelled by request", 0, NULL), 0);
  assert_int_equal(srv_db_heartbeat(a, &id, &att, 1, &held, &cancel, NULL), 0);
  assert_int_equal(held, 0);
  srv_db_close(b);
}

typedef struct sink {
  int64_t ids[4];
  int n;
} sink;

static void clean(void *user, int64_t id) {
  sink *s = user;
  if (s->n < 4) s->ids[s->n] = id;
  s->n++;
}

static void test_recover_previous_boot(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  int64_t mine = pg_insert(a, 60, "rt_ao"), theirs = pg_insert(a, 50, "rt_ao");
  int att;
  assert_true(pg_claim(a, &att) == mine);
  assert_true(pg_claim(b, &att) == theirs);
  srv_db_close(a);
  /* alpha restarts: what its previous boot ran goes back to the queue, beta's stays. */
  srv_db *a2 = pg_open_node("alpha", "b2", 0);
  *state = a2;
  sink cleaned = {{0}, 0};
  assert_int_equal(srv_db_recover(a2, NULL, clean, &cleaned, NULL), 0);
  assert_int_equal(cleaned.n, 1);
  assert_true(cleaned.ids[0] == mine);
  assert_int_equal(pg_state_of(a2, mine), SRV_QUEUED);
  assert_int_equal(pg_state_of(a2, theirs), SRV_RUNNING);
  srv_job j;
  assert_int_equal(srv_db_get_job(a2, mine, &j, NULL), 0);
  assert_string_equal(j.error, "attempt 1 was interrupted by a daemon crash; requeued");
  srv_job_free(&j);
  assert_int_equal(srv_db_recover(a2, NULL, clean, &cleaned, NULL), 0);
  assert_int_equal(cleaned.n, 1); /* nothing more to recover */
  srv_db_close(b);
}

static void test_reconnect(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t id = pg_insert(pg, 50, "rt_ao");
  int what;
  assert_int_equal(srv_db_wait(pg, 0, &what, NULL), 1);
  pg_sql("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name LIKE "
      "'obscurad alpha/%'");
  srv_job j;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_get_job(pg, id, &j, &e);
  if (rc) fail_msg("after the server ended the session: %s", obs_err_message(&e));
  obs_err_free(&e);
  srv_job_free(&j);
  assert_true(pg_claim(pg, NULL) == id);
  int rcw = srv_db_wait(pg, 2000, &what, NULL);
  if (!(rcw < 0 || (rcw == 1 && what == SRV_WAKE_JOBS))) fail_msg("wait: %d what %d", rcw, what);
  if (rcw < 0) assert_int_equal(srv_db_wait(pg, 0, &what, NULL), 1); /* reconnected and listening */
  assert_string_equal(srv_db_path(pg), pg_url);
  /* A password never shows; an unreachable server is the environment's fault. */
  const char *at = strchr(pg_url, '@');
  assert_non_null(at);
  char with_pw[512], shown[512];
  snprintf(with_pw, sizeof with_pw, "%.*s:s3cret%s", (int)(at - pg_url), pg_url, at);
  snprintf(shown, sizeof shown, "%.*s:***%s", (int)(at - pg_url), pg_url, at);
  srv_node n = pg_node("gamma", "b1", 0);
  srv_db *other = NULL;
  assert_int_equal(srv_db_open(&other, with_pw, 1, &n, NULL), 0);
  assert_string_equal(srv_db_path(other), shown);
  srv_db_close(other);
  obs_err e2 = OBS_ERR_INIT;
  assert_int_equal(srv_db_open(&other, "postgresql://postgres:pw@127.0.0.1:1/obscura", 1, &n, &e2),
                   OBS_ETRANSIENT);
  assert_non_null(strstr(obs_err_message(&e2), "cannot connect"));
  assert_null(strstr(obs_err_message(&e2), ":pw@"));
  obs_err_free(&e2);
}

/* The server restarts (every session ends, prepared statements and LISTENs with them): the pool
 * reconnects and prepares again, the listener comes back and hears the next submission. Needs
 * the fixture's directory (OBSCURA_TEST_PG_DIR) to restart it. */
static void test_server_restart(void **state) {
  NEED_PG();
  const char *dir = getenv("OBSCURA_TEST_PG_DIR");
  if (!dir || !*dir) skip();
  srv_db *a = *state, *b = pg_open_node("beta", "b1", 0);
  int64_t id = pg_insert(a, 50, "rt_ao");
  int what;
  assert_int_equal(srv_db_wait(a, 0, &what, NULL), 1);
  char cmd[1200];
  snprintf(cmd, sizeof cmd, "'%s' restart '%s'", obs_test_src("tests/pg/pg.sh"), dir);
  assert_int_equal(system(cmd), 0);
  PQreset(pg_admin);
  srv_job j;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_get_job(a, id, &j, &e)) fail_msg("after a restart: %s", obs_err_message(&e));
  obs_err_free(&e);
  srv_job_free(&j);
  assert_true(pg_claim(b, NULL) == id);
  /* The listener: lost (reported once), then back; a submission wakes it again. */
  int rc = 0;
  for (int tries = 0; tries < 100 && rc == 0; tries++) rc = srv_db_wait(a, 100, &what, NULL);
  assert_int_not_equal(rc, 0);
  if (rc < 0) assert_int_equal(srv_db_wait(a, 0, &what, NULL), 1);
  pg_insert(b, 50, "rt_ao");
  do assert_int_equal(srv_db_wait(a, 10000, &what, NULL), 1);
  while (what != SRV_WAKE_JOBS);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs"), 2);
  srv_db_close(b);
}

int main(void) {
  if (pg_fixture_start()) return 1;
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_setup_teardown(test_admission_lock, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_two_nodes_claim, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_lease_reaped, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_exclusion_and_max_attempts, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_heartbeat_cancel_and_wait, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_recover_previous_boot, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_reconnect, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_server_restart, pg_setup, pg_teardown),
  };
  int rc = cmocka_run_group_tests(tests, NULL, NULL);
  pg_fixture_stop();
  return rc;
}
