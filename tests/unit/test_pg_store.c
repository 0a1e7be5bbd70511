/* The PostgreSQL store (server/pg*.c) against a real server: the URL comes from
 * OBSCURA_TEST_PG_URL (the CTest fixture starts a throwaway server with tests/pg/pg.sh); without
 * it every test skips. Jobs' states and transitions, comparisons and the srv_query rows (the same
 * columns and JSON kinds as the SQLite store's), the limits' reads, and what several nodes sharing
 * one queue rely on: a claim never hands one job to two nodes, an expired lease is reaped and the
 * late finish refused, a node failing a job three times is excluded, heartbeats carry cancels,
 * NOTIFY wakes a waiting node, blobs round-trip, retention keeps comparisons whole, and a lost
 * connection is replaced without the caller seeing it. */
#include <libpq-fe.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "obscurad.h"
#include "testutil.h"

static const char *url;
static PGconn *admin; /* the test's own connection, to set up what no API call does */

static void sql(const char *q) {
  PGresult *r = PQexec(admin, q);
  ExecStatusType st = PQresultStatus(r);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK)
    fail_msg("%s: %s", q, PQerrorMessage(admin));
  PQclear(r);
}

static int64_t sql_int(const char *q) {
  PGresult *r = PQexec(admin, q);
  if (PQresultStatus(r) != PGRES_TUPLES_OK || PQntuples(r) != 1)
    fail_msg("%s: %s", q, PQerrorMessage(admin));
  int64_t v = PQgetisnull(r, 0, 0) ? -1 : strtoll(PQgetvalue(r, 0, 0), NULL, 10);
  PQclear(r);
  return v;
}

/* A node with a known boot, so that its worker id is known too. */
static srv_node node_named(const char *name, const char *boot, int lease_seconds) {
  srv_node n;
  memset(&n, 0, sizeof n);
  n.lease_seconds = lease_seconds;
  snprintf(n.name, sizeof n.name, "%s", name);
  snprintf(n.boot, sizeof n.boot, "%s", boot);
  snprintf(n.worker, sizeof n.worker, "%s/%s", name, boot);
  return n;
}

static srv_db *open_node_lease(const char *name, const char *boot, int lease_seconds) {
  srv_node n = node_named(name, boot, lease_seconds);
  srv_db *pg = NULL;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_open(&pg, url, 2, &n, &e);
  if (rc) fail_msg("srv_db_open: %s", obs_err_message(&e));
  obs_err_free(&e);
  return pg;
}

static srv_db *open_node(const char *name, const char *boot) {
  return open_node_lease(name, boot, 0);
}

/* Every test starts from an empty store (the schema stays: it was migrated once). */
static int setup(void **state) {
  if (!url) return 0;
  sql("TRUNCATE jobs, comparisons, comparison_candidates, outputs, runs, machines, "
      "job_node_failures, blobs, job_counts RESTART IDENTITY CASCADE");
  *state = open_node("alpha", "b1");
  return 0;
}

static int teardown(void **state) {
  srv_db_close(*state);
  return 0;
}

#define NEED_PG()                                                                                 \
  do {                                                                                            \
    if (!url) skip();                                                                             \
  } while (0)

static srv_new_job new_job(int priority, const char *technique) {
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

static int64_t insert(srv_db *pg, int priority, const char *technique) {
  srv_new_job nj = new_job(priority, technique);
  int64_t id = 0;
  obs_err e = OBS_ERR_INIT;
  assert_int_equal(srv_db_insert_job(pg, &nj, &id, &e), 0);
  obs_err_free(&e);
  assert_true(id > 0);
  return id;
}

/* Claims the next CPU job: its id (attempt in *attempt), or 0 when none is queued. */
static int64_t claim(srv_db *pg, int *attempt) {
  srv_job j;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_claim(pg, SRV_LANE_CPU, &j, &e);
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

static srv_state state_of(srv_db *pg, int64_t id) {
  srv_state st = SRV_NSTATES;
  assert_int_equal(srv_db_job_exists(pg, id, &st, NULL), 1);
  return st;
}

static void test_jobs(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t low = insert(pg, 10, "rt_ao"), high = insert(pg, 90, "ssao"), mid = insert(pg, 50, "rt_ao");
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
  assert_true(claim(pg, &att) == high);
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
  assert_true(claim(pg, &a2) == mid);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_FAILED, "boom", 0.25, NULL), 0);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_FAILED, "again", 0.5, NULL), OBS_ECONFLICT);
  srv_state st;
  assert_int_equal(srv_db_retry(pg, high, &st, NULL), OBS_EINVAL);
  assert_int_equal(st, SRV_SUCCEEDED);
  assert_int_equal(srv_db_retry(pg, 999999, &st, NULL), OBS_ENOTFOUND);
  assert_int_equal(srv_db_retry(pg, mid, &st, NULL), 0);
  assert_int_equal(state_of(pg, mid), SRV_QUEUED);
  srv_cancel_result res;
  assert_int_equal(srv_db_cancel(pg, low, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_DONE);
  assert_int_equal(state_of(pg, low), SRV_CANCELLED);
  assert_int_equal(srv_db_cancel(pg, low, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_FINISHED);
  assert_int_equal(srv_db_cancel(pg, 999999, &res, NULL), OBS_ENOTFOUND);
  assert_true(claim(pg, &a2) == mid);
  assert_int_equal(a2, 2);
  assert_int_equal(srv_db_delete(pg, mid, NULL), OBS_EINVAL); /* running */
  assert_int_equal(srv_db_requeue(pg, mid, a2, NULL), 0);   /* the attempt does not count */
  assert_true(claim(pg, &a2) == mid);
  assert_int_equal(a2, 2);
  assert_int_equal(srv_db_cancel(pg, mid, &res, NULL), 0);
  assert_int_equal(res, SRV_CANCEL_RUNNING);
  assert_int_equal(state_of(pg, mid), SRV_RUNNING);
  assert_int_equal(srv_db_finish(pg, mid, a2, SRV_CANCELLED, "cancelled by request", 0.1, NULL), 0);
  assert_int_equal(srv_db_delete(pg, low, NULL), 0);
  assert_int_equal(srv_db_delete(pg, low, NULL), OBS_ENOTFOUND);
  assert_int_equal(srv_db_job_exists(pg, low, NULL, NULL), 0);
  /* The counts the triggers keep agree with the rows. */
  assert_int_equal(srv_db_counts(pg, counts, NULL), 0);
  assert_true(counts[SRV_SUCCEEDED] == 1 && counts[SRV_CANCELLED] == 1 && counts[SRV_QUEUED] == 0 &&
              counts[SRV_RUNNING] == 0 && counts[SRV_FAILED] == 0);
  assert_int_equal(sql_int("SELECT count(*) FROM jobs"), 2);
}

static void test_limits(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t a = insert(pg, 50, "rt_ao"), b = insert(pg, 50, "rt_ao");
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
  assert_true(claim(pg, &att) == a);
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
  srv_db *a = *state, *b = open_node("beta", "b1");
  assert_int_equal(srv_db_admit_lock(a, NULL), 0);
  srv_load mine, total;
  assert_int_equal(srv_db_queued(a, "x", &mine, &total, NULL), 0);
  insert(a, 50, "rt_ao");
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

/* ---- comparisons: the rows of every srv_query, shaped like the SQLite store's ---------------- */

static void new_comparison(srv_new_comparison *c, srv_new_job *refs, srv_new_candidate *cands,
                           srv_new_measure *ms) {
  memset(c, 0, sizeof *c);
  refs[0] = new_job(50, "rt_ao");
  for (int i = 0; i < 2; i++) {
    memset(&cands[i], 0, sizeof cands[i]);
    cands[i].job = new_job(50, i ? "hbao" : "ssao");
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
  assert_int_equal(sql_int("SELECT count(*) FROM jobs WHERE comparison IS NOT NULL"), 3);
  /* The reference has the lowest id, and the candidates point at it. */
  int64_t ref = sql_int("SELECT min(id) FROM jobs");
  assert_int_equal(sql_int("SELECT count(*) FROM comparison_candidates WHERE reference_job = "
                           "(SELECT min(id) FROM jobs)"), 3);
  assert_int_equal(sql_int("SELECT job FROM comparison_candidates WHERE idx = 2"),
                   sql_int("SELECT job FROM comparison_candidates WHERE idx = 1"));
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
    int64_t job = claim(pg, &att);
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
  int64_t cand0 = sql_int("SELECT job FROM comparison_candidates WHERE idx = 0");
  for (int k = 0; k < 3; k++)
    assert_int_equal(srv_db_set_metrics(pg, id, k, cand0, k == 2 ? NULL : "{\"rmse\": 0.1}",
                                        k == 2 ? "no common output" : NULL, &err_img, 1, NULL), 0);
  /* Stored once: a second write changes nothing. */
  assert_int_equal(srv_db_set_metrics(pg, id, 0, cand0, "{\"rmse\": 9}", NULL, NULL, 0, NULL), 0);
  assert_int_equal(sql_int("SELECT count(*) FROM comparison_candidates WHERE metrics LIKE '%9%'"), 0);

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
                              "cpu_model:2,cores:3,vulkan_device:2,vulkan_kind:2,"},
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
  srv_arg auto_args[3] = {{SRV_ARG_TEXT, 0, 0, "ssao"}, {SRV_ARG_REAL, 0, 64.0 * 48 * 4, NULL},
                          {SRV_ARG_TEXT, 0, 0, "software"}};
  assert_int_equal(srv_db_query(pg, SRV_Q_AUTO_RUNS, auto_args, 3, &rows, NULL), 0);
  assert_int_equal(json_array_size(rows), 1);
  shape(rows, got, sizeof got);
  assert_string_equal(got, "backend:2,total_ms:4,");
  json_decref(rows);

  assert_int_equal(srv_db_delete_comparison(pg, id, &ids, &nids, NULL), 0);
  assert_int_equal(nids, 3);
  free(ids);
  assert_int_equal(sql_int("SELECT count(*) FROM jobs"), 0);
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
    int64_t job = claim(db, &att);
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
          autos[3] = {{SRV_ARG_TEXT, 0, 0, "ssao"}, {SRV_ARG_REAL, 0, 64.0 * 48 * 4, NULL},
                      {SRV_ARG_TEXT, 0, 0, "software"}};
  const struct {
    srv_query q;
    const srv_arg *args;
    int nargs;
  } qs[] = {{SRV_Q_COMPARISON, &by_cmp, 1},       {SRV_Q_CANDIDATES, &by_cmp, 1},
            {SRV_Q_COMPARISON_RUNS, &by_cmp, 1},  {SRV_Q_COMPARISON_OUTPUTS, &by_cmp, 1},
            {SRV_Q_COMPARISONS, page, 2},         {SRV_Q_JOB_COMPARISON, &by_job, 1},
            {SRV_Q_AUTO_RUNS, autos, 3},          {SRV_Q_BUDGET, NULL, 0},
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
  srv_node n = node_named("alpha", "b1", 0);
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
  srv_db *a = *state, *b = open_node("beta", "b1");
  enum { N = 120 };
  for (int i = 0; i < N; i++) insert(i % 2 ? a : b, 10 + i % 7, "rt_ao");
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
  assert_int_equal(sql_int("SELECT count(*) FROM jobs WHERE state = 'running' AND attempts = 1"), N);
  assert_int_equal(sql_int("SELECT count(*) FROM jobs WHERE node = 'alpha' AND worker = 'alpha/b1'"),
                   ca.n);
  /* A node cannot end the other's job. */
  int64_t theirs = cb.n ? cb.got[0] : 0;
  if (theirs) assert_int_equal(srv_db_finish(a, theirs, 1, SRV_FAILED, "x", 0, NULL), OBS_ECONFLICT);
  srv_db_close(b);
}

static void test_lease_reaped(void **state) {
  NEED_PG();
  srv_db_close(*state);
  srv_db *a = *state = open_node_lease("alpha", "b1", 1), *b = open_node("beta", "b1");
  int64_t id = insert(a, 50, "rt_ao");
  int att;
  assert_true(claim(a, &att) == id);
  int held, cancel;
  int64_t ids[1] = {id};
  int atts[1] = {att};
  assert_int_equal(srv_db_heartbeat(a, ids, atts, 1, &held, &cancel, NULL), 0);
  assert_true(held == 1 && cancel == 0);
  int rq, fl;
  assert_int_equal(srv_db_reap(b, &rq, &fl, NULL), 0);
  assert_true(rq == 0 && fl == 0); /* the lease is still running */
  /* The node stalls past its lease (the database's clock decides). */
  while (sql_int("SELECT count(*) FROM jobs WHERE lease_expires_at < now()") == 0) usleep(100000);
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
  int64_t wait_ms = sql_int("SELECT (extract(epoch FROM run_after - now()) * 1000)::bigint FROM jobs");
  assert_true(wait_ms > 1000 && wait_ms <= 2500);
  assert_int_equal(claim(b, NULL), 0);
  assert_int_equal(sql_int("SELECT failures FROM job_node_failures WHERE node = 'alpha'"), 1);
  srv_db_close(b);
}

/* A lease lost `times` times by node pg on job id, without waiting for leases or back-off. */
static void lose_lease(srv_db *pg, int64_t id, int times) {
  char q[200];
  for (int i = 0; i < times; i++) {
    int att;
    assert_true(claim(pg, &att) == id);
    snprintf(q, sizeof q, "UPDATE jobs SET lease_expires_at = now() - interval '1 s' WHERE id = %lld",
             (long long)id);
    sql(q);
    int rq, fl;
    assert_int_equal(srv_db_reap(pg, &rq, &fl, NULL), 0);
    assert_int_equal(rq + fl, 1);
    sql("UPDATE jobs SET run_after = now() WHERE state = 'queued'");
  }
}

static void test_exclusion_and_max_attempts(void **state) {
  NEED_PG();
  srv_db *a = *state, *b = open_node("beta", "b1");
  int64_t id = insert(a, 50, "rt_ao");
  sql("UPDATE jobs SET max_attempts = 10");
  lose_lease(a, id, 3);
  /* Node alpha failed it three times: it no longer sees it; beta does. */
  assert_int_equal(claim(a, NULL), 0);
  int att;
  assert_true(claim(b, &att) == id);
  assert_int_equal(att, 4);
  srv_db_close(b);
  /* At max_attempts the reaper fails the job, saying why. */
  int64_t other = insert(a, 50, "rt_ao");
  lose_lease(a, other, 2);
  int rq, fl;
  assert_true(claim(a, &att) == other);
  assert_int_equal(att, 3);
  sql("UPDATE jobs SET lease_expires_at = now() - interval '1 s' WHERE state = 'running' AND "
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
  srv_db *a = *state, *b = open_node("beta", "b1");
  int what = 0;
  /* The first wait opens the listener and reports a look at the queue (what it missed). */
  assert_int_equal(srv_db_wait(a, 0, &what, NULL), 1);
  assert_int_equal(what, SRV_WAKE_JOBS);
  assert_int_equal(srv_db_wait(a, 50, &what, NULL), 0);
  int64_t id = insert(b, 50, "rt_ao"); /* another node's submission wakes this one */
  assert_int_equal(srv_db_wait(a, 10000, &what, NULL), 1);
  assert_int_equal(what, SRV_WAKE_JOBS);
  int att;
  assert_true(claim(a, &att) == id);
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
  srv_db *a = *state, *b = open_node("beta", "b1");
  int64_t mine = insert(a, 60, "rt_ao"), theirs = insert(a, 50, "rt_ao");
  int att;
  assert_true(claim(a, &att) == mine);
  assert_true(claim(b, &att) == theirs);
  srv_db_close(a);
  /* alpha restarts: what its previous boot ran goes back to the queue, beta's stays. */
  srv_db *a2 = open_node("alpha", "b2");
  *state = a2;
  sink cleaned = {{0}, 0};
  assert_int_equal(srv_db_recover(a2, NULL, clean, &cleaned, NULL), 0);
  assert_int_equal(cleaned.n, 1);
  assert_true(cleaned.ids[0] == mine);
  assert_int_equal(state_of(a2, mine), SRV_QUEUED);
  assert_int_equal(state_of(a2, theirs), SRV_RUNNING);
  srv_job j;
  assert_int_equal(srv_db_get_job(a2, mine, &j, NULL), 0);
  assert_string_equal(j.error, "attempt 1 was interrupted by a daemon crash; requeued");
  srv_job_free(&j);
  assert_int_equal(srv_db_recover(a2, NULL, clean, &cleaned, NULL), 0);
  assert_int_equal(cleaned.n, 1); /* nothing more to recover */
  srv_db_close(b);
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
  while ((id = claim(pg, &att)) > 0)
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
  for (int i = 0; i < 3; i++) insert(pg, 50, "rt_ao");          /* jobs 1..3 */
  assert_int_equal(srv_db_insert_comparison(pg, &c, &cmp, NULL), 0); /* jobs 4..6 */
  for (int i = 0; i < 2; i++) insert(pg, 50, "rt_ao");          /* jobs 7, 8 */
  finish_all(pg);
  for (int k = 0; k < 2; k++)
    assert_int_equal(srv_db_set_metrics(pg, cmp, k, 5 + k, "{}", NULL, NULL, 0, NULL), 0);
  int64_t active = insert(pg, 50, "rt_ao");                     /* job 9 stays queued */
  int64_t *ids;
  int n;
  /* Keep the newest 5 (5..9): 1..3 go; the comparison has job 4 past but 5, 6 not: kept whole. */
  assert_int_equal(srv_db_prune(pg, 5, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 3);
  for (int i = 0; i < n; i++) assert_true(ids[i] >= 1 && ids[i] <= 3);
  free(ids);
  assert_int_equal(sql_int("SELECT count(*) FROM jobs WHERE comparison IS NOT NULL"), 3);
  /* Keep the newest 2 (8, 9): the comparison is now past as a whole and goes with its jobs. */
  assert_int_equal(srv_db_prune(pg, 2, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 4); /* 4, 5, 6 and 7 */
  free(ids);
  assert_int_equal(sql_int("SELECT count(*) FROM comparisons"), 0);
  assert_int_equal(sql_int("SELECT count(*) FROM comparison_candidates"), 0);
  /* Age: everything finished before now; the queued job is never pruned. */
  sql("UPDATE jobs SET finished_ms = finished_ms - 3 * 86400000 WHERE finished_ms IS NOT NULL");
  assert_int_equal(srv_db_prune(pg, 0, 1, &ids, &n, NULL), 0);
  assert_int_equal(n, 1);
  free(ids);
  assert_int_equal(state_of(pg, active), SRV_QUEUED);
  assert_int_equal(srv_db_prune(pg, 0, 0, &ids, &n, NULL), 0);
  assert_int_equal(n, 0);
  free(ids);
  assert_int_equal(srv_db_prune(pg, -1, 0, &ids, &n, NULL), OBS_EINVAL);
  int64_t counts[SRV_NSTATES];
  assert_int_equal(srv_db_counts(pg, counts, NULL), 0);
  assert_true(counts[SRV_QUEUED] == 1 && counts[SRV_SUCCEEDED] == 0);
}

/* The server ends the daemon's sessions (a restart, a failover): the next calls reconnect,
 * prepare their statements again and answer, and the listener comes back. */
static void test_reconnect(void **state) {
  NEED_PG();
  srv_db *pg = *state;
  int64_t id = insert(pg, 50, "rt_ao");
  int what;
  assert_int_equal(srv_db_wait(pg, 0, &what, NULL), 1);
  sql("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name LIKE "
      "'obscurad alpha/%'");
  srv_job j;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_get_job(pg, id, &j, &e);
  if (rc) fail_msg("after the server ended the session: %s", obs_err_message(&e));
  obs_err_free(&e);
  srv_job_free(&j);
  assert_true(claim(pg, NULL) == id);
  int rcw = srv_db_wait(pg, 2000, &what, NULL);
  if (!(rcw < 0 || (rcw == 1 && what == SRV_WAKE_JOBS))) fail_msg("wait: %d what %d", rcw, what);
  if (rcw < 0) assert_int_equal(srv_db_wait(pg, 0, &what, NULL), 1); /* reconnected and listening */
  assert_string_equal(srv_db_path(pg), url);
  /* A password never shows; an unreachable server is the environment's fault. */
  const char *at = strchr(url, '@');
  assert_non_null(at);
  char with_pw[512], shown[512];
  snprintf(with_pw, sizeof with_pw, "%.*s:s3cret%s", (int)(at - url), url, at);
  snprintf(shown, sizeof shown, "%.*s:***%s", (int)(at - url), url, at);
  srv_node n = node_named("gamma", "b1", 0);
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

int main(void) {
  url = getenv("OBSCURA_TEST_PG_URL");
  if (url && !*url) url = NULL;
  if (url) {
    admin = PQconnectdb(url);
    if (PQstatus(admin) != CONNECTION_OK) {
      fprintf(stderr, "OBSCURA_TEST_PG_URL=%s: %s", url, PQerrorMessage(admin));
      return 1;
    }
    PQclear(PQexec(admin, "SET client_min_messages = warning"));
    sql("DROP SCHEMA public CASCADE; CREATE SCHEMA public");
    /* Two daemons starting together both migrate: the advisory lock makes it once. */
    srv_node n = node_named("migrate", "b0", 0);
    srv_db *p1 = NULL, *p2 = NULL;
    obs_err e = OBS_ERR_INIT;
    if (srv_db_open(&p1, url, 1, &n, &e) || srv_db_open(&p2, url, 1, &n, &e)) {
      fprintf(stderr, "srv_db_open: %s\n", obs_err_message(&e));
      return 1;
    }
    srv_db_close(p1);
    srv_db_close(p2);
  }
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_setup_teardown(test_jobs, setup, teardown),
      cmocka_unit_test_setup_teardown(test_limits, setup, teardown),
      cmocka_unit_test_setup_teardown(test_admission_lock, setup, teardown),
      cmocka_unit_test_setup_teardown(test_comparison, setup, teardown),
      cmocka_unit_test_setup_teardown(test_rows_match_sqlite, setup, teardown),
      cmocka_unit_test_setup_teardown(test_two_nodes_claim, setup, teardown),
      cmocka_unit_test_setup_teardown(test_lease_reaped, setup, teardown),
      cmocka_unit_test_setup_teardown(test_exclusion_and_max_attempts, setup, teardown),
      cmocka_unit_test_setup_teardown(test_heartbeat_cancel_and_wait, setup, teardown),
      cmocka_unit_test_setup_teardown(test_recover_previous_boot, setup, teardown),
      cmocka_unit_test_setup_teardown(test_blobs, setup, teardown),
      cmocka_unit_test_setup_teardown(test_prune, setup, teardown),
      cmocka_unit_test_setup_teardown(test_reconnect, setup, teardown),
  };
  int rc = cmocka_run_group_tests(tests, NULL, NULL);
  PQfinish(admin);
  return rc;
}
