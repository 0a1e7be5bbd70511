/* The PostgreSQL store tests' fixture (pg_fixture.h). */
#include "pg_fixture.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *pg_url;
PGconn *pg_admin;

void pg_sql(const char *q) {
  PGresult *r = PQexec(pg_admin, q);
  ExecStatusType st = PQresultStatus(r);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK)
    fail_msg("%s: %s", q, PQerrorMessage(pg_admin));
  PQclear(r);
}

int64_t pg_sql_int(const char *q) {
  PGresult *r = PQexec(pg_admin, q);
  if (PQresultStatus(r) != PGRES_TUPLES_OK || PQntuples(r) != 1)
    fail_msg("%s: %s", q, PQerrorMessage(pg_admin));
  int64_t v = PQgetisnull(r, 0, 0) ? -1 : strtoll(PQgetvalue(r, 0, 0), NULL, 10);
  PQclear(r);
  return v;
}

srv_node pg_node(const char *name, const char *boot, int lease_seconds) {
  srv_node n;
  memset(&n, 0, sizeof n);
  n.lease_seconds = lease_seconds;
  snprintf(n.name, sizeof n.name, "%s", name);
  snprintf(n.boot, sizeof n.boot, "%s", boot);
  snprintf(n.worker, sizeof n.worker, "%s/%s", name, boot);
  return n;
}

srv_db *pg_open_node(const char *name, const char *boot, int lease_seconds) {
  srv_node n = pg_node(name, boot, lease_seconds);
  srv_db *db = NULL;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_open(&db, pg_url, 2, &n, &e);
  if (rc) fail_msg("srv_db_open: %s", obs_err_message(&e));
  obs_err_free(&e);
  return db;
}

/* Every case starts from an empty store (the schema stays: it was migrated once). */
int pg_setup(void **state) {
  if (!pg_url) return 0;
  pg_sql("TRUNCATE jobs, comparisons, comparison_candidates, outputs, runs, machines, "
         "job_node_failures, blobs, job_counts RESTART IDENTITY CASCADE");
  *state = pg_open_node("alpha", "b1", 0);
  return 0;
}

int pg_teardown(void **state) {
  srv_db_close(*state);
  return 0;
}

int pg_fixture_start(void) {
  pg_url = getenv("OBSCURA_TEST_PG_URL");
  if (pg_url && !*pg_url) pg_url = NULL;
  if (!pg_url) return 0;
  pg_admin = PQconnectdb(pg_url);
  if (PQstatus(pg_admin) != CONNECTION_OK) {
    fprintf(stderr, "OBSCURA_TEST_PG_URL=%s: %s", pg_url, PQerrorMessage(pg_admin));
    return 1;
  }
  PQclear(PQexec(pg_admin, "SET client_min_messages = warning"));
  PGresult *r = PQexec(pg_admin, "DROP SCHEMA public CASCADE; CREATE SCHEMA public");
  int ok = PQresultStatus(r) == PGRES_COMMAND_OK;
  PQclear(r);
  if (!ok) {
    fprintf(stderr, "resetting the schema: %s", PQerrorMessage(pg_admin));
    return 1;
  }
  /* Two daemons starting together both migrate: the advisory lock makes it once. */
  srv_node n = pg_node("migrate", "b0", 0);
  srv_db *p1 = NULL, *p2 = NULL;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_open(&p1, pg_url, 1, &n, &e) || srv_db_open(&p2, pg_url, 1, &n, &e)) {
    fprintf(stderr, "srv_db_open: %s\n", obs_err_message(&e));
    return 1;
  }
  srv_db_close(p1);
  srv_db_close(p2);
  return 0;
}

void pg_fixture_stop(void) { PQfinish(pg_admin); }

srv_new_job pg_new_job(int priority, const char *technique) {
  srv_new_job nj;
  memset(&nj, 0, sizeof nj);
  nj.priority = priority;
  nj.label = "a \"quoted\" label with \\ and , {braces}";
  nj.scene = "inline";
  nj.doc = "{\"camera\": {}, \"objects\": []}";
  nj.technique = technique;
  nj.backend_requested = "auto";
  nj.lane = SRV_LANE_CPU;
  nj.width = 64;
  nj.height = 48;
  nj.spp = 4;
  nj.repeats = 2;
  nj.work = 64 * 48 * 4;
  return nj;
}

int64_t pg_insert(srv_db *db, int priority, const char *technique) {
  srv_new_job nj = pg_new_job(priority, technique);
  int64_t id = 0;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_insert_job(db, &nj, &id, &e)) fail_msg("insert: %s", obs_err_message(&e));
  obs_err_free(&e);
  assert_true(id > 0);
  return id;
}

int64_t pg_claim(srv_db *db, int *attempt) {
  srv_job j;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_claim(db, SRV_LANE_CPU, &j, &e);
  if (rc < 0) fail_msg("claim: %s", obs_err_message(&e));
  obs_err_free(&e);
  if (rc == 1) return 0;
  assert_int_equal(j.state, SRV_RUNNING);
  assert_non_null(j.doc);
  int64_t id = j.id;
  if (attempt) *attempt = j.attempts;
  srv_job_free(&j);
  return id;
}

srv_state pg_state_of(srv_db *db, int64_t id) {
  srv_state st = SRV_NSTATES;
  assert_int_equal(srv_db_job_exists(db, id, &st, NULL), 1);
  return st;
}
