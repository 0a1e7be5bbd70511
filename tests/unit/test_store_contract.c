/* The store's contract (server/db.h), one suite for both implementations: every test opens the
 * store named by OBSCURA_TEST_STORE (unset: a fresh SQLite file; a postgresql:// URL: a fresh
 * database created on that server for the test and dropped after it) with two nodes on it, and
 * checks what the interface promises through the interface alone. This file: jobs' states and
 * transitions, listing and keyset paging, the attempt guard, heartbeats and two nodes claiming at
 * once; store_contract_nodes.c the leases, recovery, blobs and wake-ups; store_contract_records.c
 * comparisons, the limits' reads, run rates and retention. Where the contract answers differently
 * for the one-daemon SQLite store (reap, wait, blobs), the case says so and checks that answer. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "store_contract.h"

/* ---- states and transitions ----------------------------------------------------------------- */

static void test_insert_claim_succeed(void **state) {
  store *s = *state;
  srv_new_job nj = sc_job_of("rt_ao", 3);
  nj.backend_reason = "asked for";
  nj.notes = "[\"radius\"]";
  nj.scene_name = "box";
  nj.repeats = 2;
  nj.warmup = 1;
  int64_t id = 0;
  OK(srv_db_insert_job(s->a, &nj, &id, &contract_err));
  srv_job j = sc_get(s->a, id);
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
  RC(1, srv_db_job_exists(s->a, id, &st, &contract_err));
  assert_int_equal(st, SRV_QUEUED);
  RC(0, srv_db_job_exists(s->a, id + 1000, &st, &contract_err));
  RC(OBS_ENOTFOUND, srv_db_get_job(s->a, id + 1000, &j, &contract_err));

  OK(srv_db_claim(s->a, SRV_LANE_CPU, &j, &contract_err));
  assert_int_equal(j.id, id);
  assert_int_equal(j.state, SRV_RUNNING);
  assert_int_equal(j.attempts, 1);
  assert_string_equal(j.node, "node-a");
  assert_string_equal(j.doc, nj.doc);
  assert_true(j.started_ms >= j.created_ms);
  srv_job_free(&j);
  OK(srv_db_set_backend(s->a, id, "cpu", &contract_err));

  int64_t machine = 0;
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &machine, &contract_err));
  srv_output outs[2] = {{.name = "ao", .size = 100, .content_type = "image/png"},
                        {.name = "stderr", .size = 200, .content_type = "image/x-exr"}};
  memset(outs[0].sha256, 'a', 64);
  memset(outs[1].sha256, 'b', 64);
  srv_run runs[2] = {{1, 10, 2, 13}, {1, 11, 2, 14}};
  OK(srv_db_finish_success(s->a, id, 1, "cpu", "{\"summary\":1}", outs, 2, runs, 2, machine,
                           &contract_err));
  j = sc_get(s->b, id);
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
  OK(srv_db_get_output(s->b, id, "stderr", &o, &contract_err));
  assert_int_equal(o.size, 200);
  assert_string_equal(o.sha256, outs[1].sha256);
  RC(OBS_ENOTFOUND, srv_db_get_output(s->b, id, "nothing", &o, &contract_err));
  json_t *r = sc_query(s->b, SRV_Q_JOB_RUNS, id, 0, 1);
  assert_int_equal(json_array_size(r), 2);
  assert_true(json_number_value(json_object_get(json_array_get(r, 1), "total_ms")) == 14.0);
  json_decref(r);
  r = sc_query(s->b, SRV_Q_JOB_MACHINE, id, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  assert_string_equal(sc_col_str(r, 0, "cpu_model"), "Contract CPU");
  json_decref(r);
}

static void test_finish_keeps_progress(void **state) {
  store *s = *state;
  int64_t f = sc_insert(s->a, "ssao", 0), c = sc_insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), f);
  OK(srv_db_finish(s->a, f, att, SRV_FAILED, "renderer said no", 0.25, &contract_err));
  assert_int_equal(sc_claim(s->a, &att), c);
  OK(srv_db_finish(s->a, c, att, SRV_CANCELLED, "cancelled by request", 0.5, &contract_err));
  srv_job j = sc_get(s->a, f);
  assert_int_equal(j.state, SRV_FAILED);
  assert_string_equal(j.error, "renderer said no");
  assert_true(j.progress == 0.25);
  assert_true(j.finished_ms > 0);
  srv_job_free(&j);
  j = sc_get(s->a, c);
  assert_int_equal(j.state, SRV_CANCELLED);
  assert_true(j.progress == 0.5);
  srv_job_free(&j);
}

static void test_requeue_does_not_count(void **state) {
  store *s = *state;
  int64_t id = sc_insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), id);
  assert_int_equal(att, 1);
  OK(srv_db_requeue(s->a, id, att, &contract_err));
  srv_job j = sc_get(s->a, id);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_int_equal(j.attempts, 0);
  srv_job_free(&j);
  assert_int_equal(sc_claim(s->b, &att), id);
  assert_int_equal(att, 1);
  j = sc_get(s->a, id);
  assert_string_equal(j.node, "node-b");
  srv_job_free(&j);
}

static void test_cancel(void **state) {
  store *s = *state;
  int64_t run = sc_insert(s->a, "ssao", 1), q = sc_insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), run);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, q, &res, &contract_err));
  assert_int_equal(res, SRV_CANCEL_DONE);
  srv_job j = sc_get(s->a, q);
  assert_int_equal(j.state, SRV_CANCELLED);
  assert_true(j.finished_ms > 0);
  srv_job_free(&j);
  OK(srv_db_cancel(s->b, run, &res, &contract_err));
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  j = sc_get(s->a, run);
  assert_int_equal(j.state, SRV_RUNNING); /* the node that runs it stops it */
  assert_int_equal(j.cancel_requested, 1);
  srv_job_free(&j);
  OK(srv_db_cancel(s->b, q, &res, &contract_err));
  assert_int_equal(res, SRV_CANCEL_FINISHED);
  RC(OBS_ENOTFOUND, srv_db_cancel(s->b, q + 1000, &res, &contract_err));
}

static void test_retry(void **state) {
  store *s = *state;
  int64_t f = sc_insert(s->a, "ssao", 0), ok = sc_insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), f);
  OK(srv_db_finish(s->a, f, att, SRV_FAILED, "broke", 0.5, &contract_err));
  assert_int_equal(sc_claim(s->a, &att), ok);
  sc_succeed(s->a, ok, att, NULL, 0, 0);
  srv_state st = SRV_QUEUED;
  OK(srv_db_retry(s->b, f, &st, &contract_err));
  srv_job j = sc_get(s->a, f);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_null(j.error);
  assert_int_equal(j.cancel_requested, 0);
  assert_int_equal(j.finished_ms, 0);
  srv_job_free(&j);
  assert_int_equal(sc_claim(s->a, &att), f); /* the same row runs again */
  RC(OBS_EINVAL, srv_db_retry(s->b, ok, &st, &contract_err));
  assert_int_equal(st, SRV_SUCCEEDED);
  RC(OBS_EINVAL, srv_db_retry(s->b, f, &st, &contract_err));
  assert_int_equal(st, SRV_RUNNING);
  RC(OBS_ENOTFOUND, srv_db_retry(s->b, f + 1000, &st, &contract_err));
  /* A cancelled job comes back too. */
  OK(srv_db_finish(s->a, f, att, SRV_CANCELLED, "cancelled by request", 0.1, &contract_err));
  OK(srv_db_retry(s->b, f, &st, &contract_err));
  assert_int_equal(sc_state_of(s->a, f), SRV_QUEUED);
}

static void test_delete_and_counts(void **state) {
  store *s = *state;
  int64_t ids[6];
  for (int i = 0; i < 6; i++) ids[i] = sc_insert(s->a, "ssao", 0);
  int att[4];
  for (int i = 0; i < 4; i++) assert_int_equal(sc_claim(s->a, &att[i]), ids[i]);
  sc_succeed(s->a, ids[0], att[0], NULL, 0, 0);
  OK(srv_db_finish(s->a, ids[1], att[1], SRV_FAILED, "x", 0, &contract_err));
  OK(srv_db_finish(s->a, ids[2], att[2], SRV_CANCELLED, "y", 0, &contract_err));
  int64_t counts[SRV_NSTATES];
  OK(srv_db_counts(s->b, counts, &contract_err));
  assert_int_equal(counts[SRV_QUEUED], 2);
  assert_int_equal(counts[SRV_RUNNING], 1);
  assert_int_equal(counts[SRV_SUCCEEDED], 1);
  assert_int_equal(counts[SRV_FAILED], 1);
  assert_int_equal(counts[SRV_CANCELLED], 1);
  RC(OBS_EINVAL, srv_db_delete(s->b, ids[3], &contract_err)); /* running */
  RC(OBS_EINVAL, srv_db_delete(s->b, ids[4], &contract_err)); /* queued */
  assert_int_equal(sc_state_of(s->a, ids[3]), SRV_RUNNING);
  assert_int_equal(sc_state_of(s->a, ids[4]), SRV_QUEUED);
  for (int i = 0; i < 3; i++) {
    OK(srv_db_delete(s->b, ids[i], &contract_err));
    RC(0, srv_db_job_exists(s->a, ids[i], NULL, &contract_err));
    srv_output o;
    RC(OBS_ENOTFOUND, srv_db_get_output(s->a, ids[i], "ao", &o, &contract_err));
  }
  RC(OBS_ENOTFOUND, srv_db_delete(s->b, ids[0], &contract_err));
  OK(srv_db_counts(s->b, counts, &contract_err));
  assert_int_equal(counts[SRV_QUEUED] + counts[SRV_RUNNING], 3);
  assert_int_equal(counts[SRV_SUCCEEDED] + counts[SRV_FAILED] + counts[SRV_CANCELLED], 0);
}

static void test_priorities_fifo_and_lanes(void **state) {
  store *s = *state;
  int64_t vid = sc_insert_vulkan(s->a, "ssao", 9);
  int64_t low = sc_insert(s->a, "ssao", 0), hi1 = sc_insert(s->a, "ssao", 5);
  int64_t hi2 = sc_insert(s->a, "ssao", 5), mid = sc_insert(s->a, "ssao", 1);
  assert_int_equal(sc_claim(s->a, NULL), hi1);
  assert_int_equal(sc_claim(s->b, NULL), hi2);
  assert_int_equal(sc_claim(s->a, NULL), mid);
  assert_int_equal(sc_claim(s->b, NULL), low);
  assert_int_equal(sc_claim(s->a, NULL), 0); /* the Vulkan job is not the CPU lane's */
  srv_job j;
  OK(srv_db_claim(s->a, SRV_LANE_VULKAN, &j, &contract_err));
  assert_int_equal(j.id, vid);
  srv_job_free(&j);
}

/* ---- listing and keyset paging -------------------------------------------------------------- */

/* Pages through the filter's jobs `limit` at a time: their ids in order into out (count returned).
 */
static int page_all(srv_db *db, srv_job_filter f, int64_t *out, int cap) {
  int total = 0;
  for (int pages = 0; pages < 100; pages++) {
    srv_job *jobs = NULL;
    int n = 0;
    OK(srv_db_list_jobs(db, &f, &jobs, &n, &contract_err));
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
  for (int i = 0; i < 9; i++) ids[i] = sc_insert(s->a, i % 3 ? "ssao" : "hbao", 0);
  int64_t vid = sc_insert_vulkan(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), ids[0]);
  sc_succeed(s->a, ids[0], att, NULL, 0, 0);

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
  OK(srv_db_list_jobs(s->b, &one, &jobs, &n, &contract_err));
  assert_int_equal(n, 3);
  srv_jobs_free(jobs, n);
  one.after = ids[1];
  OK(srv_db_list_jobs(s->b, &one, &jobs, &n, &contract_err));
  assert_int_equal(n, 1);
  assert_int_equal(jobs[0].id, ids[0]);
  assert_int_equal(jobs[0].noutputs, 1);
  srv_jobs_free(jobs, n);
}

/* ---- the attempt guard, heartbeats, two nodes claiming -------------------------------------- */

static void expect_unchanged_running(srv_db *db, int64_t id, const char *node) {
  srv_job j = sc_get(db, id);
  assert_int_equal(j.state, SRV_RUNNING);
  assert_int_equal(j.attempts, 1);
  assert_string_equal(j.node, node);
  assert_int_equal(j.noutputs, 0);
  assert_null(j.error);
  srv_job_free(&j);
}

static void test_attempt_guard(void **state) {
  store *s = *state;
  int64_t id = sc_insert(s->a, "ssao", 0);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), id);
  srv_output o = {.name = "ao", .size = 1, .content_type = "image/png"};
  memset(o.sha256, 'c', 64);
  RC(OBS_ECONFLICT,
     srv_db_finish_success(s->a, id, att + 1, "cpu", "{}", &o, 1, NULL, 0, 0, &contract_err));
  RC(OBS_ECONFLICT, srv_db_finish(s->a, id, att + 1, SRV_FAILED, "late", 0.5, &contract_err));
  RC(OBS_ECONFLICT, srv_db_requeue(s->a, id, att + 1, &contract_err));
  expect_unchanged_running(s->b, id, "node-a");
  /* Another node, right attempt: not its job. */
  RC(OBS_ECONFLICT,
     srv_db_finish_success(s->b, id, att, "cpu", "{}", &o, 1, NULL, 0, 0, &contract_err));
  RC(OBS_ECONFLICT, srv_db_finish(s->b, id, att, SRV_FAILED, "not mine", 0.5, &contract_err));
  RC(OBS_ECONFLICT, srv_db_requeue(s->b, id, att, &contract_err));
  expect_unchanged_running(s->a, id, "node-a");
  /* The same node name after a restart (another boot) does not hold it either. */
  srv_db *a2 = s->more[0] = sc_open_node(s, "node-a", 30);
  RC(OBS_ECONFLICT, srv_db_finish(a2, id, att, SRV_FAILED, "previous boot's", 0.5, &contract_err));
  expect_unchanged_running(s->a, id, "node-a");
  sc_succeed(s->a, id, att, NULL, 0, 0);
  RC(OBS_ECONFLICT, srv_db_finish(s->a, id, att, SRV_FAILED, "after the end", 0.5, &contract_err));
  RC(OBS_ECONFLICT, srv_db_requeue(s->a, id, att, &contract_err));
  assert_int_equal(sc_state_of(s->b, id), SRV_SUCCEEDED);
}

static void test_heartbeat(void **state) {
  store *s = *state;
  int64_t mine = sc_insert(s->a, "ssao", 0), theirs = sc_insert(s->a, "ssao", 0);
  int am = 0, at = 0;
  assert_int_equal(sc_claim(s->a, &am), mine);
  assert_int_equal(sc_claim(s->b, &at), theirs);
  int64_t ids[2] = {mine, theirs};
  int atts[2] = {am, at};
  int held[2] = {-1, -1}, cancel[2] = {-1, -1};
  OK(srv_db_heartbeat(s->a, ids, atts, 2, held, cancel, &contract_err));
  assert_int_equal(held[0], 1);
  assert_int_equal(held[1], 0);
  assert_int_equal(cancel[0], 0);
  int wrong = am + 1;
  OK(srv_db_heartbeat(s->a, ids, &wrong, 1, held, cancel, &contract_err));
  assert_int_equal(held[0], 0); /* another attempt of the job is not held */
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, mine, &res, &contract_err));
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  OK(srv_db_heartbeat(s->a, ids, atts, 1, held, cancel, &contract_err));
  assert_int_equal(held[0], 1);
  assert_int_equal(cancel[0], 1);
  OK(srv_db_finish(s->a, mine, am, SRV_CANCELLED, "cancelled by request", 0.3, &contract_err));
  OK(srv_db_heartbeat(s->a, ids, atts, 1, held, cancel, &contract_err));
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
  for (int i = 0; i < N; i++) ids[i] = sc_insert(s->a, "ssao", i % 3);
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
    srv_job j = sc_get(s->a, ids[i]);
    assert_int_equal(j.state, SRV_RUNNING);
    assert_int_equal(j.attempts, 1);
    srv_job_free(&j);
  }
}

int main(void) {
#define T(f) cmocka_unit_test_setup_teardown(f, sc_setup, sc_teardown)
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
      T(test_reap_and_exclusion),
      T(test_recover),
      T(test_comparison_queries),
      T(test_comparison_metrics),
      T(test_limits),
      T(test_run_rates),
      T(test_blobs),
      T(test_prune),
      T(test_wait),
  };
  int rc = cmocka_run_group_tests(tests, NULL, NULL);
  obs_err_free(&contract_err);
  return rc;
}
