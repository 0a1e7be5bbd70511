/* The store contract suite (test_store_contract.c), the records beyond one job: comparisons with
 * their candidate rows, metrics and named queries, the admission limits' sums, stored run rates and
 * retention that keeps comparisons whole. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "store_contract.h"

/* ---- comparisons ---------------------------------------------------------------------------- */

/* A comparison's rows as the queries show them, and its deletion refused while its jobs run. */
void test_comparison_queries(void **state) {
  store *s = *state;
  int64_t older = sc_insert_comparison(s->a, "older"), cmp = sc_insert_comparison(s->a, "cmp");
  json_t *r = sc_query(s->b, SRV_Q_COMPARISONS, 0, 10, 2);
  assert_int_equal(json_array_size(r), 2);
  assert_int_equal(sc_col_int(r, 0, "id"), cmp);
  assert_int_equal(sc_col_int(r, 1, "id"), older);
  json_decref(r);
  r = sc_query(s->b, SRV_Q_COMPARISONS, cmp, 10, 2);
  assert_int_equal(json_array_size(r), 1);
  assert_int_equal(sc_col_int(r, 0, "id"), older);
  json_decref(r);
  json_t *cands = sc_query(s->b, SRV_Q_CANDIDATES, cmp, 0, 1);
  assert_int_equal(json_array_size(cands), 3);
  int64_t ref = sc_col_int(cands, 0, "reference_job"), c0 = sc_col_int(cands, 0, "job");
  int64_t c1 = sc_col_int(cands, 1, "job");
  for (size_t i = 0; i < 3; i++) {
    assert_int_equal(sc_col_int(cands, i, "idx"), (int64_t)i);
    assert_int_equal(sc_col_int(cands, i, "reference_job"), ref);
    assert_string_equal(sc_col_str(cands, i, "state"), "queued");
  }
  assert_string_equal(sc_col_str(cands, 0, "role"), "own");
  assert_string_equal(sc_col_str(cands, 1, "technique"), "hbao");
  assert_string_equal(sc_col_str(cands, 2, "role"), "common");
  assert_int_equal(sc_col_int(cands, 2, "job"), c0);
  json_decref(cands);
  srv_job j = sc_get(s->b, c1);
  assert_int_equal(j.comparison, cmp);
  srv_job_free(&j);
  r = sc_query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  assert_string_equal(sc_col_str(r, 0, "label"), "cmp");
  assert_int_equal(sc_col_int(r, 0, "candidates"), 2);
  assert_int_equal(sc_col_int(r, 0, "active"), 3);
  json_decref(r);
  int64_t *ids = NULL;
  int nids = 0;
  RC(OBS_EINVAL, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &contract_err));
  assert_int_equal(sc_state_of(s->a, ref), SRV_QUEUED);
  RC(1, srv_db_job_exists(s->a, c1, NULL, &contract_err));
  json_t *q = sc_query(s->b, SRV_Q_JOB_COMPARISON, c0, 0, 1);
  assert_int_equal(json_array_size(q), 1);
  assert_int_equal(sc_col_int(q, 0, "comparison"), cmp);
  json_decref(q);
}

/* Metrics once both jobs of a candidate succeed, stored once; a comparison deleted whole once
 * nothing of it runs or waits for figures. */
void test_comparison_metrics(void **state) {
  store *s = *state;
  int64_t older = sc_insert_comparison(s->a, "older"), cmp = sc_insert_comparison(s->a, "cmp");
  int64_t jobs[3];
  sc_comparison_jobs(s->b, cmp, jobs);
  int64_t ref = jobs[0], c0 = jobs[1], c1 = jobs[2];
  int64_t *ids = NULL;
  int nids = 0;
  /* Run the older comparison's three jobs out of the way (cancelled), then this one's. */
  for (int i = 0; i < 3; i++) {
    int att = 0;
    int64_t id = sc_claim(s->a, &att);
    OK(srv_db_finish(s->a, id, att, SRV_CANCELLED, "not needed", 0, &contract_err));
  }
  json_t *r = sc_query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  int att[3] = {0};
  assert_int_equal(sc_claim(s->a, &att[0]), ref); /* references first */
  assert_int_equal(sc_claim(s->a, &att[1]), c0);
  assert_int_equal(sc_claim(s->a, &att[2]), c1);
  sc_succeed(s->a, ref, att[0], NULL, 0, 0);
  sc_succeed(s->a, c0, att[1], NULL, 0, 0);
  OK(srv_db_finish(s->a, c1, att[2], SRV_FAILED, "broke", 0.5, &contract_err));
  RC(OBS_EUNSUPPORTED, srv_db_delete(s->b, ref, &contract_err)); /* comparisons keep their jobs */
  r = sc_query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 2);
  assert_int_equal(sc_col_int(r, 0, "comparison"), cmp);
  assert_int_equal(sc_col_int(r, 0, "idx"), 0);
  assert_int_equal(sc_col_int(r, 1, "idx"), 2);
  assert_int_equal(sc_col_int(r, 1, "job"), c0);
  json_decref(r);
  r = sc_query(s->b, SRV_Q_METRICS_PENDING, c1, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);

  srv_output err_map = {.name = "error_ssao", .size = 77, .content_type = "image/png"};
  memset(err_map.sha256, 'e', 64);
  OK(srv_db_set_metrics(s->b, cmp, 0, c0, "{\"rmse\":0.5}", NULL, &err_map, 1, &contract_err));
  OK(srv_db_set_metrics(s->b, cmp, 0, c0, "{\"rmse\":9}", NULL, NULL, 0, &contract_err));
  json_t *cands = sc_query(s->b, SRV_Q_CANDIDATES, cmp, 0, 1);
  json_t *m = json_loads(sc_col_str(cands, 0, "metrics"), 0, NULL);
  assert_non_null(m);
  assert_true(json_number_value(json_object_get(m, "rmse")) == 0.5); /* stored once */
  json_decref(m);
  assert_string_equal(sc_col_str(cands, 1, "state"), "failed");
  json_decref(cands);
  srv_output o;
  OK(srv_db_get_output(s->b, c0, "error_ssao", &o, &contract_err));
  assert_int_equal(o.size, 77);
  r = sc_query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(sc_col_int(r, 0, "active"), 0);
  assert_int_equal(sc_col_int(r, 0, "measured"), 1);
  assert_int_equal(sc_col_int(r, 0, "broken"), 1);
  assert_int_equal(sc_col_int(r, 0, "measuring"), 1);
  json_decref(r);
  /* Row 2 still awaits its figures: deleting would pull the jobs from under them. */
  RC(OBS_EINVAL, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &contract_err));
  OK(srv_db_set_metrics(s->b, cmp, 2, c0, NULL, "no common reference", NULL, 0, &contract_err));
  r = sc_query(s->b, SRV_Q_METRICS_PENDING, 0, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  OK(srv_db_delete_comparison(s->b, cmp, &ids, &nids, &contract_err));
  assert_int_equal(nids, 3);
  int64_t want[3] = {ref, c0, c1};
  for (int i = 0; i < 3; i++) {
    int hit = 0;
    for (int k = 0; k < nids; k++) hit += ids[k] == want[i];
    assert_int_equal(hit, 1);
    RC(0, srv_db_job_exists(s->a, want[i], NULL, &contract_err));
  }
  free(ids);
  r = sc_query(s->b, SRV_Q_COMPARISON, cmp, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);
  RC(OBS_ENOTFOUND, srv_db_delete_comparison(s->b, cmp, &ids, &nids, &contract_err));
  r = sc_query(s->b, SRV_Q_COMPARISON, older, 0, 1);
  assert_int_equal(json_array_size(r), 1);
  json_decref(r);
}

/* ---- the admission limits' reads ------------------------------------------------------------ */

void test_limits(void **state) {
  store *s = *state;
  int64_t done = sc_insert(s->a, "ssao", 9);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), done);
  sc_succeed(s->a, done, att, NULL, 0, 0);
  OK(srv_db_set_job_client(s->a, done, 0, "alice", &contract_err)); /* finished: no load */
  srv_new_job j1 = sc_job_of("ssao", 0), j2 = sc_job_of("ssao", 0), j3 = sc_job_of("ssao", 0);
  j1.work = 100, j1.repeats = 2, j1.warmup = 1;
  j2.work = 50, j2.ranks = 4;
  j3.work = 10;
  int64_t id1, id2, id3;
  OK(srv_db_insert_job(s->a, &j1, &id1, &contract_err));
  OK(srv_db_insert_job(s->a, &j2, &id2, &contract_err));
  OK(srv_db_insert_job(s->a, &j3, &id3, &contract_err));
  OK(srv_db_set_job_client(s->a, id1, 0, "alice", &contract_err));
  OK(srv_db_set_job_client(s->a, id2, 0, "alice", &contract_err));
  OK(srv_db_set_job_client(s->a, id3, 0, "bob", &contract_err));
  assert_int_equal(sc_claim(s->b, &att), id1); /* running still loads the queue */
  srv_load mine, total;
  OK(srv_db_queued(s->b, "alice", &mine, &total, &contract_err));
  assert_true(mine.work == 100 * 3 + 50);
  assert_true(mine.jobs == 1 + 4);
  assert_true(mine.bytes == (double)(srv_job_stored_bytes(&j1) + srv_job_stored_bytes(&j2)));
  assert_true(total.work == 100 * 3 + 50 + 10);
  assert_true(total.jobs == 6);
  assert_true(total.bytes == mine.bytes + (double)srv_job_stored_bytes(&j3));
  OK(srv_db_queued(s->b, "nobody", &mine, &total, &contract_err));
  assert_true(mine.work == 0 && mine.jobs == 0 && mine.bytes == 0);
  srv_load load;
  srv_state st;
  OK(srv_db_job_load(s->b, id2, &load, &st, &contract_err));
  assert_true(load.work == 50 && load.jobs == 4);
  assert_true(load.bytes == (double)srv_job_stored_bytes(&j2));
  assert_int_equal(st, SRV_QUEUED);
  OK(srv_db_job_load(s->b, id1, &load, &st, &contract_err));
  assert_true(load.work == 300);
  assert_int_equal(st, SRV_RUNNING);
  RC(OBS_ENOTFOUND, srv_db_job_load(s->b, id3 + 1000, &load, &st, &contract_err));
  /* A comparison's client is every one of its jobs'. */
  int64_t cmp = sc_insert_comparison(s->a, "limits");
  OK(srv_db_set_job_client(s->a, 0, cmp, "carol", &contract_err));
  OK(srv_db_queued(s->b, "carol", &mine, &total, &contract_err));
  assert_true(mine.jobs == 3);
  assert_true(mine.work == 3 * 32.0 * 24 * 4);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

void test_run_rates(void **state) {
  store *s = *state;
  int64_t m = 0, m_again = 0, other = 0;
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &m, &contract_err));
  OK(srv_db_machine(s->a, "Contract CPU", 8, NULL, NULL, &m_again, &contract_err));
  OK(srv_db_machine(s->a, "Other CPU", 4, "llvmpipe", "software", &other, &contract_err));
  assert_int_equal(m, m_again);
  assert_true(other != m);
  static const double works[4] = {1000, 2000, 10, 1000};
  static const srv_run runs[4][2] = {
      {{0, 0, 0, 10}, {0, 0, 0, 12}}, {{0, 0, 0, 40}}, {{0, 0, 0, 5}}, {{0, 0, 0, 7}}};
  static const int nruns[4] = {2, 1, 1, 1};
  for (int i = 0; i < 4; i++) {
    srv_new_job nj = sc_job_of("rt_ao", 0);
    nj.work = works[i];
    int64_t id;
    int att = 0;
    OK(srv_db_insert_job(s->a, &nj, &id, &contract_err));
    assert_int_equal(sc_claim(s->a, &att), id);
    sc_succeed(s->a, id, att, runs[i], nruns[i], i == 3 ? other : m);
  }
  double *rates = NULL;
  size_t n = 0;
  OK(srv_db_run_rates(s->b, "rt_ao", "cpu", m, 100, &rates, &n, &contract_err));
  assert_int_equal(n, 3); /* not the small job, not the other machine's */
  qsort(rates, n, sizeof *rates, cmp_double);
  assert_true(fabs(rates[0] - 10.0 / 1000) < 1e-12);
  assert_true(fabs(rates[1] - 12.0 / 1000) < 1e-12);
  assert_true(fabs(rates[2] - 40.0 / 2000) < 1e-12);
  free(rates);
  OK(srv_db_run_rates(s->b, "rt_ao", "vulkan", m, 0, &rates, &n, &contract_err));
  assert_int_equal(n, 0);
  free(rates);
}

/* ---- retention ---------------------------------------------------------------------------- */

void test_prune(void **state) {
  store *s = *state;
  int64_t *ids = NULL;
  int nids = -1;
  obs_err_clear(&contract_err);
  if (srv_db_prune(s->a, 0, 0, &ids, &nids, &contract_err) == OBS_EUNSUPPORTED) {
    printf("skipped: srv_db_prune returns OBS_EUNSUPPORTED on this store (%s)\n",
           obs_err_message(&contract_err));
    skip();
  }
  assert_int_equal(nids, 0);
  free(ids);
  /* Finished in this order: C1's three jobs, j1, j2, C2's reference, j3, C2's candidates. */
  int64_t c1 = sc_insert_comparison(s->a, "c1"), c1j[3];
  sc_comparison_jobs(s->a, c1, c1j);
  for (int i = 0; i < 3; i++) sc_finish_one(s->a, c1j[i]);
  sc_measure_all(s->a, c1);
  int64_t j1 = sc_finish_one(s->a, sc_insert(s->a, "ssao", 0));
  int64_t j2 = sc_finish_one(s->a, sc_insert(s->a, "ssao", 0));
  int64_t c2 = sc_insert_comparison(s->a, "c2"), c2j[3];
  sc_comparison_jobs(s->a, c2, c2j);
  sc_finish_one(s->a, c2j[0]);
  int64_t j3 = sc_insert(s->a, "ssao", 0);
  int att[2] = {0};
  assert_int_equal(sc_claim(s->a, &att[0]), c2j[1]);
  assert_int_equal(sc_claim(s->a, &att[1]), c2j[2]);
  sc_finish_one(s->a, j3);
  sc_succeed(s->a, c2j[1], att[0], NULL, 0, 0);
  sc_succeed(s->a, c2j[2], att[1], NULL, 0, 0);
  sc_measure_all(s->a, c2);

  OK(srv_db_prune(s->b, 3, 0, &ids, &nids, &contract_err));
  /* Beyond the newest three: C1 whole and j1, j2; C2's reference is too, but not all of C2. */
  assert_int_equal(nids, 5);
  for (int i = 0; i < 3; i++) assert_int_equal(sc_contains(ids, nids, c1j[i]), 1);
  assert_int_equal(sc_contains(ids, nids, j1), 1);
  assert_int_equal(sc_contains(ids, nids, j2), 1);
  free(ids);
  for (int i = 0; i < 3; i++) {
    RC(0, srv_db_job_exists(s->a, c1j[i], NULL, &contract_err));
    RC(1, srv_db_job_exists(s->a, c2j[i], NULL, &contract_err));
  }
  RC(0, srv_db_job_exists(s->a, j1, NULL, &contract_err));
  RC(1, srv_db_job_exists(s->a, j3, NULL, &contract_err));
  json_t *r = sc_query(s->b, SRV_Q_COMPARISON, c1, 0, 1);
  assert_int_equal(json_array_size(r), 0);
  json_decref(r);

  /* Age: everything finished is older than a few milliseconds, the queued job is not finished,
   * and a comparison with a queued job stays whole. */
  int64_t c3 = sc_insert_comparison(s->a, "c3"), c3j[3];
  sc_comparison_jobs(s->a, c3, c3j);
  sc_finish_one(s->a, c3j[0]);
  int64_t waiting = sc_insert(s->a, "ssao", 0);
  sc_sleep_ms(300);
  OK(srv_db_prune(s->b, 0, 1e-6 /* 86 ms */, &ids, &nids, &contract_err));
  assert_int_equal(nids, 4);
  assert_int_equal(sc_contains(ids, nids, j3), 1);
  for (int i = 0; i < 3; i++) assert_int_equal(sc_contains(ids, nids, c2j[i]), 1);
  free(ids);
  RC(1, srv_db_job_exists(s->a, waiting, NULL, &contract_err));
  for (int i = 0; i < 3; i++) RC(1, srv_db_job_exists(s->a, c3j[i], NULL, &contract_err));
  int64_t counts[SRV_NSTATES];
  OK(srv_db_counts(s->a, counts, &contract_err));
  assert_int_equal(counts[SRV_SUCCEEDED], 1);
  assert_int_equal(counts[SRV_QUEUED], 3);
}
