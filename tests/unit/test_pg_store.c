/* The PostgreSQL store (server/pg*.c) through srv_db_* against a real server (pg_fixture.h; the
 * CTest fixture pg starts a throwaway one with tests/pg/pg.sh; without OBSCURA_TEST_PG_URL every
 * case skips): jobs' states and transitions and the list statements, the limits' reads,
 * comparisons and the srv_query rows (the same columns, JSON kinds and row counts as the SQLite
 * store's), blobs, and retention that keeps comparisons whole. Several nodes: test_pg_cluster.c. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pg_fixture.h"

static void test_jobs(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t low = pg_insert(pg, 10, "rt_ao"), high = pg_insert(pg, 90, "ssao"), mid = pg_insert(pg, 50, "rt_ao");
  srv_job j;
  assert_int_equal(srv_db_get_job(pg, high, &j, NULL), 0);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_string_equal(j.label, "a \"quoted\" label with \\ and , {braces}");
  assert_string_equal(j.technique, "ssao");
  assert_int_equal(j.repeats, 2);
  assert_true(j.created_ms > 1600000000000LL);
  assert_int_equal(j.comparison, 0);
  assert_null(j.backend);
  srv_job_free(&j);
  assert_int_equal(srv_db_get_job(pg, 999999, &j, NULL), OBS_ENOTFOUND);

  /* Lists: newest first, a page and its key, filters, ascending. */
  srv_job_filter f = {.limit = 2};
  srv_job *jobs;
  int n;
  assert_int_equal(srv_db_list_jobs(pg, &f, &jobs, &n, NULL), 0);
  assert_int_equal(n, 3); /* limit + 1: there is a next page */
  assert_true(jobs[0].id == mid && jobs[1].id == high);
  srv_jobs_free(jobs, n);
  f.after = high;
  assert_int_equal(srv_db_list_jobs(pg, &f, &jobs, &n, NULL), 0);
  assert_int_equal(n, 1);
  assert_true(jobs[0].id == low);
  srv_jobs_free(jobs, n);
  srv_job_filter ft = {.technique = "rt_ao", .ascending = 1, .limit = 10};
  assert_int_equal(srv_db_list_jobs(pg, &ft, &jobs, &n, NULL), 0);
  assert_int_equal(n, 2);
  assert_true(jobs[0].id == low && jobs[1].id == mid);
  srv_jobs_free(jobs, n);

  /* Every combination of filters and order (each its own statement) answers and filters. */
  for (int v = 0; v < 16; v++) {
    srv_job_filter fv = {.has_state = v & 1, .state = SRV_QUEUED,
                         .technique = v & 2 ? "rt_ao" : NULL, .backend = v & 4 ? "auto" : NULL,
                         .ascending = (v & 8) != 0, .limit = 10};
    assert_int_equal(srv_db_list_jobs(pg, &fv, &jobs, &n, NULL), 0);
    assert_int_equal(n, v & 2 ? 2 : 3);
    assert_true(v & 8 ? jobs[0].id < jobs[1].id : jobs[0].id > jobs[1].id);
    srv_jobs_free(jobs, n);
  }

  /* The claim takes the highest priority first. */
  int att = 0;
  assert_true(pg_claim(pg, &att) == high);
  assert_int_equal(att, 1);
  assert_int_equal(srv_db_set_backend(pg, high, "cpu", NULL), 0);
  assert_int_equal(srv_db_get_job(pg, high, &j, NULL), 0);
  assert_string_equal(j.node, "alpha"); /* the node that runs it, kept after it ends */
  assert_string_equal(j.backend, "cpu");
  srv_job_free(&j);
  int64_t counts[SRV_NSTATES];
  assert_int_equal(srv_db_counts(pg, counts, NULL), 0);
  assert_true(counts[SRV_QUEUED] == 2 && counts[SRV_RUNNING] == 1);
  srv_job_filter fr = {.has_state = 1, .state = SRV_RUNNING, .backend = "cpu", .limit = 10};
  assert_int_equal(srv_db_list_jobs(pg, &fr, &jobs, &n, NULL), 0);
  assert_true(n == 1 && jobs[0].id == high);
  srv_jobs_free(jobs, n);

  /* Success with outputs, runs and the machine. */
  int64_t machine = 0;
  assert_int_equal(srv_db_machine(pg, "Test CPU", 8, NULL, NULL, &machine, NULL), 0);
  int64_t again = 0;
  assert_int_equal(srv_db_machine(pg, "Test CPU", 8, NULL, NULL, &again, NULL), 0);
  assert_true(machine > 0 && again == machine);
  srv_output outs[2] = {{"ao", 100, "", "image/x-exr"}, {"preview", 20, "", "image/png"}};
  memset(outs[0].sha256, 'a', 64);
  memset(outs[1].sha256, 'b', 64);
  srv_run runs[2] = {{1, 2, 3, 6}, {1, 3, 3, 7}};
  obs_err e = OBS_ERR_INIT;
  assert_int_equal(srv_db_finish_success(pg, high, 2, "cpu", "{}", outs, 2, runs, 2, machine, &e),
                   OBS_ECONFLICT); /* not this attempt */
  assert_non_null(strstr(obs_err_message(&e), "no longer held by this node"));
  obs_err_free(&e);
  assert_int_equal(srv_db_finish_success(pg, high, 1, "cpu", "{\"ok\":1}", outs, 2, runs, 2,
                                         machine, NULL), 0);
  assert_int_equal(srv_db_get_job(pg, high, &j, NULL), 0);
  assert_int_equal(j.state, SRV_SUCCEEDED);
  assert_int_equal(j.noutputs, 2);
  assert_string_equal(j.outputs[0].name, "ao");
  assert_int_equal(j.outputs[1].size, 20);
  assert_true(j.finished_ms >= j.started_ms && j.started_ms >= j.created_ms);
  assert_true(j.progress == 1.0);
  srv_job_free(&j);
  srv_output o;
  assert_int_equal(srv_db_get_output(pg, high, "preview", &o, NULL), 0);
  assert_string_equal(o.content_type, "image/png");
  assert_int_equal(srv_db_get_output(pg, high, "nope", &o, NULL), OBS_ENOTFOUND);
  json_t *rows;
  srv_arg arg = {SRV_ARG_INT, high, 0, NULL};
  assert_int_equal(srv_db_query(pg, SRV_Q_JOB_RUNS, &arg, 1, &rows, NULL), 0);
  assert_int_equal(json_array_size(rows), 2);
  assert_true(json_real_value(json_object_get(json_array_get(rows, 1), "total_ms")) == 7.0);
  json_decref(rows);

  /* Failure, retry, cancel of a queued and of a running job, deletion. */
  int a2 = 0;
  assert_true(pg_claim(pg, &a2) == mid);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_FAILED, "boom", 0.25, NULL), 0);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_FAILED, "again", 0.5, NULL), OBS_ECONFLICT);
  srv_state st;
  assert_int_equal(srv_db_retry(pg, high, &st, NULL), OBS_EINVAL);
  assert_int_equal(st, SRV_SUCCEEDED);
  assert_int_equal(srv_db_retry(pg, 999999, &st, NULL), OBS_ENOTFOUND);
  assert_int_equal(srv_db_retry(pg, mid, &st, NULL), 0);
  assert_int_equal(pg_state_of(pg, mid), SRV_QUEUED);
  srv_cancel_result res;
  assert_int_equal(srv_db_cancel(pg, low, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_DONE);
  assert_int_equal(pg_state_of(pg, low), SRV_CANCELLED);
  assert_int_equal(srv_db_cancel(pg, low, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_FINISHED);
  assert_int_equal(srv_db_cancel(pg, 999999, &res, NULL), OBS_ENOTFOUND);
  assert_true(pg_claim(pg, &a2) == mid);
  assert_int_equal(a2, 2);
  assert_int_equal(srv_db_delete(pg, mid, NULL), OBS_EINVAL); /* running */
  assert_int_equal(srv_db_requeue(pg, mid, a2, NULL), 0);   /* the attempt does not count */
  assert_true(pg_claim(pg, &a2) == mid);
  assert_int_equal(a2, 2);
  assert_int_equal(srv_db_cancel(pg, mid, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  assert_int_equal(pg_state_of(pg, mid), SRV_RUNNING);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_CANCELLED, "cancelled by request", 0.1, NULL), 0);
  assert_int_equal(srv_db_delete(pg, low, NULL), 0);
  assert_int_equal(srv_db_delete(pg, low, NULL), OBS_ENOTFOUND);
  assert_int_equal(srv_db_job_exists(pg, low, NULL, NULL), 0);
  /* The counts the triggers keep agree with the rows. */
  assert_int_equal(srv_db_counts(pg, counts, NULL), 0);
  assert_true(counts[SRV_SUCCEEDED] == 1 && counts[SRV_CANCELLED] == 1 && counts[SRV_QUEUED] == 0 &&
              counts[SRV_RUNNING] == 0 && counts[SRV_FAILED] == 0);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs"), 2);
}

static void test_limits(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t a = pg_insert(pg, 50, "rt_ao"), b = pg_insert(pg, 50, "rt_ao");
  assert_int_equal(srv_db_set_job_client(pg, a, 0, "10.0.0.1", NULL), 0);
  srv_load mine, total, one;
  assert_int_equal(srv_db_queued(pg, "10.0.0.1", &mine, &total, NULL), 0);
  double work = 64.0 * 48 * 4 * 2; /* work x (repeats + warmup) */
  assert_true(mine.work == work && total.work == 2 * work);
  assert_true(mine.jobs == 1 && total.jobs == 2);
  assert_true(mine.bytes > 0 && total.bytes == 2 * mine.bytes);
  srv_state st;
  assert_int_equal(srv_db_job_load(pg, b, &one, &st, NULL), 0);
  assert_true(one.work == work && st == SRV_QUEUED);
  assert_int_equal(srv_db_job_load(pg, 999999, &one, &st, NULL), OBS_ENOTFOUND);
  /* A finished job no longer counts. */
  int att;
  assert_true(pg_claim(pg, &att) == a);
  int64_t m;
  assert_int_equal(srv_db_machine(pg, "Test CPU", 4, NULL, NULL, &m, NULL), 0);
  srv_run run = {0, 30, 0, 30};
  assert_int_equal(srv_db_set_backend(pg, a, "cpu", NULL), 0);
  assert_int_equal(srv_db_finish_success(pg, a, att, "cpu", "{}", NULL, 0, &run, 1, m, NULL), 0);
  assert_int_equal(srv_db_queued(pg, "10.0.0.1", &mine, &total, NULL), 0);
  assert_true(mine.work == 0 && total.jobs == 1);
  double *rates;
  size_t n;
  assert_int_equal(srv_db_run_rates(pg, "rt_ao", "cpu", m, 1, &rates, &n, NULL), 0);
  assert_int_equal(n, 1);
  assert_true(rates[0] == 30.0 / (64.0 * 48 * 4));
  free(rates);
}

/* ---- comparisons: the rows of every srv_query, shaped like the SQLite store's ---------------- */

static void new_comparison(srv_new_comparison *c, srv_new_job *refs, srv_new_candidate *cands,
                           srv_new_measure *ms) {
  memset(c, 0, sizeof *c);
  refs[0] = pg_new_job(50, "rt_ao");
  for (int i = 0; i < 2; i++) {
    memset(&cands[i], 0, sizeof cands[i]);
    cands[i].job = pg_new_job(50, i ? "hbao" : "ssao");
    cands[i].technique = i ? "hbao" : "ssao";
    cands[i].backend = "cpu";
    cands[i].params = "{\"radius\": 1}";
    cands[i].reference_params = "{}";
    cands[i].response = "identity";
  }
  memset(ms, 0, sizeof *ms);
  ms->candidate = 1;
  ms->role = "common";
  ms->reference_params = "{}";
  ms->response = "identity";
  c->label = "sweep";
  c->scene = "inline";
  c->request = "{\"budget_ms\": 250, \"techniques\": []}";
  c->width = 64;
  c->height = 48;
  c->repeats = 2;
  c->references = refs;
  c->nreferences = 1;
  c->candidates = cands;
  c->ncandidates = 2;
  c->measures = ms;
  c->nmeasures = 1;
}

/* The JSON kind of each column of a query's first row, "name:kind,..." sorted by insertion. */
static void shape(json_t *rows, char *out, size_t n) {
  out[0] = '\0';
  json_t *row = json_array_get(rows, 0);
  const char *k;
  json_t *v;
  size_t len = 0;
  json_object_foreach(row, k, v) {
    len += (size_t)snprintf(out + len, n - len, "%s:%d,", k, json_is_null(v) ? -1 : (int)json_typeof(v));
    if (len >= n) break;
  }
}

static void test_comparison(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  srv_new_comparison c;
  srv_new_job refs[1];
  srv_new_candidate cands[2];
  srv_new_measure ms;
  new_comparison(&c, refs, cands, &ms);
  int64_t id = 0;
  obs_err e = OBS_ERR_INIT;
  assert_int_equal(srv_db_insert_comparison(pg, &c, &id, &e), 0);
  obs_err_free(&e);
  assert_true(id > 0);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs WHERE comparison IS NOT NULL"), 3);
  /* The reference has the lowest id, and the candidates point at it. */
  int64_t ref = pg_sql_int("SELECT min(id) FROM jobs");
  assert_int_equal(pg_sql_int("SELECT count(*) FROM comparison_candidates WHERE reference_job = "
                           "(SELECT min(id) FROM jobs)"), 3);
  assert_int_equal(pg_sql_int("SELECT job FROM comparison_candidates WHERE idx = 2"),
                   pg_sql_int("SELECT job FROM comparison_candidates WHERE idx = 1"));
  srv_job j;
  assert_int_equal(srv_db_get_job(pg, ref, &j, NULL), 0);
  assert_int_equal(j.comparison, id);
  srv_job_free(&j);
  assert_int_equal(srv_db_delete(pg, ref, NULL), OBS_EINVAL);
  int64_t *ids;
  int nids;
  assert_int_equal(srv_db_delete_comparison(pg, id, &ids, &nids, NULL), OBS_EINVAL);
  /* Run every job; metrics become pending per candidate. */
  int64_t m;
  assert_int_equal(srv_db_machine(pg, "Test CPU", 4, "llvmpipe", "software", &m, NULL), 0);
  srv_run run = {1, 2, 3, 6};
  srv_output out = {"ao", 10, "", "image/x-exr"};
  memset(out.sha256, 'c', 64);
  for (int k = 0; k < 3; k++) {
    int att;
    int64_t job = pg_claim(pg, &att);
    assert_true(job > 0);
    assert_int_equal(srv_db_finish_success(pg, job, att, "cpu", "{\"s\":1}", &out, 1, &run, 1, m,
                                           NULL), 0);
  }
  assert_int_equal(srv_db_delete(pg, ref, NULL), OBS_EUNSUPPORTED);
  json_t *rows;
  srv_arg zero = {SRV_ARG_INT, 0, 0, NULL};
  assert_int_equal(srv_db_query(pg, SRV_Q_METRICS_PENDING, &zero, 1, &rows, NULL), 0);
  assert_int_equal(json_array_size(rows), 3);
  json_decref(rows);
  assert_int_equal(srv_db_delete_comparison(pg, id, &ids, &nids, NULL), OBS_EINVAL);
  srv_output err_img = {"error", 5, "", "image/png"};
  memset(err_img.sha256, 'd', 64);
  int64_t cand0 = pg_sql_int("SELECT job FROM comparison_candidates WHERE idx = 0");
  for (int k = 0; k < 3; k++)
    assert_int_equal(srv_db_set_metrics(pg, id, k, cand0, k == 2 ? NULL : "{\"rmse\": 0.1}",
                                        k == 2 ? "no common output" : NULL, &err_img, 1, NULL), 0);
  /* Stored once: a second write changes nothing. */
  assert_int_equal(srv_db_set_metrics(pg, id, 0, cand0, "{\"rmse\": 9}", NULL, NULL, 0, NULL), 0);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM comparison_candidates WHERE metrics LIKE '%9%'"), 0);

  /* Every query answers, with the columns and kinds the SQLite store's rows have. */
  static const struct {
    srv_query q;
    const char *shape;
  } expect[] = {
      {SRV_Q_COMPARISON, "id:3,label:2,scene:2,width:3,height:3,repeats:3,created_ms:3,notes:-1,"
                         "budget_ms:3,active:3,broken:3,measured:3,candidates:3,measuring:3,"},
      {SRV_Q_CANDIDATES, "idx:3,job:3,reference_job:3,technique:2,backend:2,params:2,"
                         "reference_params:2,response:2,role:2,output:-1,metrics:2,"
                         "metrics_error:-1,state:2,progress:4,ref_state:2,ref_progress:4,"
                         "ref_summary:2,ref_technique:2,"},
      {SRV_Q_COMPARISON_RUNS, "job:3,run:3,build_ms:4,render_ms:4,post_ms:4,total_ms:4,"
                              "cpu_model:2,cores:3,vulkan_device:2,vulkan_kind:2,host:2,"},
      {SRV_Q_COMPARISON_OUTPUTS, "job:3,name:2,"},
      {SRV_Q_JOB_COMPARISON, "comparison:3,"},
      {SRV_Q_JOB_RUNS, "total_ms:4,"},
      {SRV_Q_JOB_DOC, "doc:2,scene:2,scene_name:-1,label:2,priority:3,"},
      {SRV_Q_JOB_MACHINE, "cpu_model:2,cores:3,vulkan_device:2,vulkan_kind:2,"},
      {SRV_Q_JOB_CHOICE, "choice:-1,"},
      {SRV_Q_MACHINE, "cpu_model:2,cores:3,vulkan_device:2,vulkan_kind:2,"},
  };
  char got[1024];
  for (size_t k = 0; k < sizeof expect / sizeof expect[0]; k++) {
    int64_t arg = expect[k].q == SRV_Q_COMPARISON || expect[k].q == SRV_Q_CANDIDATES ||
                          expect[k].q == SRV_Q_COMPARISON_RUNS ||
                          expect[k].q == SRV_Q_COMPARISON_OUTPUTS
                      ? id
                  : expect[k].q == SRV_Q_MACHINE ? m
                                                 : ref;
    srv_arg a = {SRV_ARG_INT, arg, 0, NULL};
    assert_int_equal(srv_db_query(pg, expect[k].q, &a, 1, &rows, NULL), 0);
    assert_true(json_array_size(rows) >= 1);
    shape(rows, got, sizeof got);
    if (strcmp(got, expect[k].shape)) fail_msg("query %d: %s, not %s", expect[k].q, got, expect[k].shape);
    json_decref(rows);
  }
  assert_int_equal(srv_db_query(pg, SRV_Q_COMPARISON, &(srv_arg){SRV_ARG_INT, id, 0, NULL}, 1,
                                &rows, NULL), 0);
  json_t *row = json_array_get(rows, 0);
  assert_int_equal(json_integer_value(json_object_get(row, "budget_ms")), 250);
  assert_int_equal(json_integer_value(json_object_get(row, "measured")), 2);
  assert_int_equal(json_integer_value(json_object_get(row, "candidates")), 2);
  assert_int_equal(json_integer_value(json_object_get(row, "active")), 0);
  json_decref(rows);
  srv_arg page[2] = {{SRV_ARG_INT, 0, 0, NULL}, {SRV_ARG_INT, 10, 0, NULL}};
  assert_int_equal(srv_db_query(pg, SRV_Q_COMPARISONS, page, 2, &rows, NULL), 0);
  shape(rows, got, sizeof got);
  assert_string_equal(got, "id:3,label:2,scene:2,created_ms:3,active:3,broken:3,measured:3,"
                           "candidates:3,measuring:3,");
  json_decref(rows);
  assert_int_equal(srv_db_query(pg, SRV_Q_BUDGET, NULL, 0, &rows, NULL), 0);
  assert_int_equal(json_array_size(rows), 2); /* own + common rows with metrics */
  shape(rows, got, sizeof got);
  assert_string_equal(got, "comparison:3,scene:2,idx:3,job:3,technique:2,backend:2,params:2,"
                           "metrics:2,role:2,reference_params:2,response:2,"
                           "reference_technique:2,pixels:3,vulkan_kind:2,");
  json_decref(rows);
  srv_arg auto_args[4] = {{SRV_ARG_TEXT, 0, 0, "ssao"}, {SRV_ARG_REAL, 0, 64.0 * 48 * 4, NULL},
                          {SRV_ARG_TEXT, 0, 0, "software"}, {SRV_ARG_INT, m, 0, NULL}};
  assert_int_equal(srv_db_query(pg, SRV_Q_AUTO_RUNS, auto_args, 4, &rows, NULL), 0);
  assert_int_equal(json_array_size(rows), 1);
  shape(rows, got, sizeof got);
  assert_string_equal(got, "backend:2,total_ms:4,");
  json_decref(rows);

  assert_int_equal(srv_db_delete_comparison(pg, id, &ids, &nids, NULL), 0);
  assert_int_equal(nids, 3);
  free(ids);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs"), 0);
  assert_int_equal(srv_db_delete_comparison(pg, id, &ids, &nids, NULL), OBS_ENOTFOUND);
}

/* The rows of every srv_query after one comparison ran, as "query: column:kind,..." lines. */
static void query_shapes(srv_db *db, char *out, size_t n) {
  srv_new_comparison c;
  srv_new_job refs[1];
  srv_new_candidate cands[2];
  srv_new_measure ms;
  new_comparison(&c, refs, cands, &ms);
  int64_t id = 0, m = 0, ref = 0, cand0 = 0;
  assert_int_equal(srv_db_insert_comparison(db, &c, &id, NULL), 0);
  assert_int_equal(srv_db_machine(db, "Test CPU", 4, "llvmpipe", "software", &m, NULL), 0);
  srv_run run = {1, 2, 3, 6};
  srv_output o = {"ao", 10, "", "image/x-exr"};
  memset(o.sha256, 'c', 64);
  for (int k = 0; k < 3; k++) {
    int att;
    int64_t job = pg_claim(db, &att);
    assert_true(job > 0);
    if (!ref) ref = job; /* the reference is inserted, hence claimed, first */
    else if (!cand0) cand0 = job;
    assert_int_equal(srv_db_finish_success(db, job, att, "cpu", "{}", &o, 1, &run, 1, m, NULL), 0);
  }
  for (int k = 0; k < 3; k++)
    assert_int_equal(srv_db_set_metrics(db, id, k, cand0, k == 2 ? NULL : "{\"rmse\": 0.1}",
                                        k == 2 ? "none" : NULL, NULL, 0, NULL), 0);
  srv_arg by_cmp = {SRV_ARG_INT, id, 0, NULL}, by_job = {SRV_ARG_INT, ref, 0, NULL},
          by_machine = {SRV_ARG_INT, m, 0, NULL}, page[2] = {{SRV_ARG_INT, 0, 0, NULL},
                                                             {SRV_ARG_INT, 10, 0, NULL}},
          pending = {SRV_ARG_INT, 0, 0, NULL},
          autos[4] = {{SRV_ARG_TEXT, 0, 0, "ssao"}, {SRV_ARG_REAL, 0, 64.0 * 48 * 4, NULL},
                      {SRV_ARG_TEXT, 0, 0, "software"}, {SRV_ARG_INT, m, 0, NULL}};
  const struct {
    srv_query q;
    const srv_arg *args;
    int nargs;
  } qs[] = {{SRV_Q_COMPARISON, &by_cmp, 1},       {SRV_Q_CANDIDATES, &by_cmp, 1},
            {SRV_Q_COMPARISON_RUNS, &by_cmp, 1},  {SRV_Q_COMPARISON_OUTPUTS, &by_cmp, 1},
            {SRV_Q_COMPARISONS, page, 2},         {SRV_Q_JOB_COMPARISON, &by_job, 1},
            {SRV_Q_AUTO_RUNS, autos, 4},          {SRV_Q_BUDGET, NULL, 0},
            {SRV_Q_JOB_RUNS, &by_job, 1},         {SRV_Q_JOB_DOC, &by_job, 1},
            {SRV_Q_JOB_MACHINE, &by_job, 1},      {SRV_Q_JOB_CHOICE, &by_job, 1},
            {SRV_Q_MACHINE, &by_machine, 1},      {SRV_Q_METRICS_PENDING, &pending, 1}};
  size_t len = 0;
  out[0] = '\0';
  for (size_t k = 0; k < sizeof qs / sizeof qs[0]; k++) {
    json_t *rows;
    obs_err e = OBS_ERR_INIT;
    if (srv_db_query(db, qs[k].q, qs[k].args, qs[k].nargs, &rows, &e))
      fail_msg("query %d: %s", (int)qs[k].q, obs_err_message(&e));
    char one[1024];
    shape(rows, one, sizeof one);
    len += (size_t)snprintf(out + len, n - len, "%d (%zu rows): %s\n", (int)qs[k].q,
                            json_array_size(rows), one);
    json_decref(rows);
  }
  assert_true(len < n);
}

/* One contract: the same calls give rows of the same columns, kinds and counts on both stores. */
static void test_rows_match_sqlite(void **state) {
  NEED_PG();
  srv_db *sq = NULL;
  srv_node n = pg_node("alpha", "b1", 0);
  obs_err e = OBS_ERR_INIT;
  const char *path = obs_test_path(obs_test_tmpdir("pg_rows"), "jobs.db");
  if (srv_db_open(&sq, path, 1, &n, &e)) fail_msg("%s", obs_err_message(&e));
  static char from_pg[8192], from_sq[8192];
  query_shapes(*state, from_pg, sizeof from_pg);
  query_shapes(sq, from_sq, sizeof from_sq);
  srv_db_close(sq);
  if (strcmp(from_pg, from_sq))
    fail_msg("PostgreSQL rows:\n%s\nSQLite rows:\n%s", from_pg, from_sq);
}

static void test_blobs(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  unsigned char data[3000];
  for (size_t i = 0; i < sizeof data; i++) data[i] = (unsigned char)(i * 7);
  char sha[65];
  memset(sha, 'e', 64);
  sha[64] = '\0';
  assert_int_equal(srv_db_put_blob(pg, sha, data, sizeof data, NULL), 0);
  assert_int_equal(srv_db_put_blob(pg, sha, data, sizeof data, NULL), 0); /* idempotent */
  void *back;
  size_t n;
  assert_int_equal(srv_db_get_blob(pg, sha, &back, &n, NULL), 0);
  assert_int_equal(n, sizeof data);
  assert_memory_equal(back, data, n);
  free(back);
  sha[0] = 'f';
  assert_int_equal(srv_db_get_blob(pg, sha, &back, &n, NULL), OBS_ENOTFOUND);
  assert_int_equal(srv_db_put_blob(pg, "../x", data, 1, NULL), OBS_EINVAL);
  assert_int_equal(srv_db_put_blob(pg, sha, "", 0, NULL), 0);
  assert_int_equal(srv_db_get_blob(pg, sha, &back, &n, NULL), 0);
  assert_int_equal(n, 0);
  free(back);
  assert_int_equal(srv_db_results_shared(pg), 1);
}

static void finish_all(srv_db *pg) {
  int att;
  int64_t id;
  while ((id = pg_claim(pg, &att)) > 0)
    assert_int_equal(srv_db_finish_success(pg, id, att, "cpu", "{}", NULL, 0, NULL, 0, 0, NULL), 0);
}

static void test_prune(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  srv_new_comparison c;
  srv_new_job refs[1];
  srv_new_candidate cands[2];
  srv_new_measure ms;
  new_comparison(&c, refs, cands, &ms);
  c.nmeasures = 0;
  int64_t cmp;
  for (int i = 0; i < 3; i++) pg_insert(pg, 50, "rt_ao");          /* jobs 1..3 */
  assert_int_equal(srv_db_insert_comparison(pg, &c, &cmp, NULL), 0); /* jobs 4..6 */
  for (int i = 0; i < 2; i++) pg_insert(pg, 50, "rt_ao");          /* jobs 7, 8 */
  finish_all(pg);
  for (int k = 0; k < 2; k++)
    assert_int_equal(srv_db_set_metrics(pg, cmp, k, 5 + k, "{}", NULL, NULL, 0, NULL), 0);
  int64_t active = pg_insert(pg, 50, "rt_ao");                     /* job 9 stays queued */
  int64_t *ids;
  int n;
  /* Keep the newest 5 (5..9): 1..3 go; the comparison has job 4 past but 5, 6 not: kept whole. */
  assert_int_equal(srv_db_prune(pg, 5, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 3);
  for (int i = 0; i < n; i++) assert_true(ids[i] >= 1 && ids[i] <= 3);
  free(ids);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM jobs WHERE comparison IS NOT NULL"), 3);
  /* Keep the newest 2 (8, 9): the comparison is now past as a whole and goes with its jobs. */
  assert_int_equal(srv_db_prune(pg, 2, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 4); /* 4, 5, 6 and 7 */
  free(ids);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM comparisons"), 0);
  assert_int_equal(pg_sql_int("SELECT count(*) FROM comparison_candidates"), 0);
  /* Age: everything finished before now; the queued job is never pruned. */
  pg_sql("UPDATE jobs SET finished_ms = finished_ms - 3 * 86400000 WHERE finished_ms IS NOT NULL");
  assert_int_equal(srv_db_prune(pg, 0, 1, &ids, &n, NULL), 0);
  assert_int_equal(n, 1);
  free(ids);
  assert_int_equal(pg_state_of(pg, active), SRV_QUEUED);
  assert_int_equal(srv_db_prune(pg, 0, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 0);
  free(ids);
  assert_int_equal(srv_db_prune(pg, -1, 0, &ids, &n, NULL), OBS_EINVAL);
  int64_t counts[SRV_NSTATES];
  assert_int_equal(srv_db_counts(pg, counts, NULL), 0);
  assert_true(counts[SRV_QUEUED] == 1 && counts[SRV_SUCCEEDED] == 0);
}

int main(void) {
  if (pg_fixture_start()) return 1;
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_setup_teardown(test_jobs, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_limits, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_comparison, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_rows_match_sqlite, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_blobs, pg_setup, pg_teardown),
      cmocka_unit_test_setup_teardown(test_prune, pg_setup, pg_teardown),
  };
  int rc = cmocka_run_group_tests(tests, NULL, NULL);
  pg_fixture_stop();
  return rc;
}
