/* The store contract suite (test_store_contract.c), what several nodes on one store rely on:
 * expired leases reaped behind a back-off and at last failed, the per-node exclusion, a restarted
 * node's recovery of its previous boot, content-addressed blobs and wake-ups. The one-daemon SQLite
 * store answers some of these by contract with "nothing to do": those cases check that answer. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "store_contract.h"

/* ---- leases: the reaper, the per-node exclusion, recovery ----------------------------------- */

/* PostgreSQL: `holder` (a 1 s lease) claims job `id` and never heartbeats, max_attempts times; each
 * expiry is reaped by another node: requeued behind a back-off with the attempt counted, the late
 * holder refused, and at the last attempt the job fails naming the node. */
static void expire_until_failed(store *s, srv_db *holder, int64_t id) {
  for (int attempt = 1; attempt <= SRV_MAX_ATTEMPTS; attempt++) {
    int att = 0;
    int64_t got = 0;
    double t0 = sc_now_ms();
    while (!(got = sc_claim(holder, &att)) && sc_now_ms() - t0 < 20000) sc_sleep_ms(100);
    assert_int_equal(got, id);
    assert_int_equal(att, attempt);
    /* Reaped by another node once the lease has lapsed: nothing before, and the first reap after
     * takes it (reaping is polled, so the case waits out the lease and no more). */
    int requeued = 0, failed = 0;
    t0 = sc_now_ms();
    while (!requeued && !failed) {
      sc_sleep_ms(100);
      OK(srv_db_reap(s->b, &requeued, &failed, &contract_err));
      if (sc_now_ms() - t0 < 900) assert_int_equal(requeued + failed, 0);
      assert_true(sc_now_ms() - t0 < 20000);
    }
    srv_job j = sc_get(s->a, id);
    if (attempt < SRV_MAX_ATTEMPTS) {
      assert_int_equal(requeued, 1);
      assert_int_equal(failed, 0);
      assert_int_equal(j.state, SRV_QUEUED);
      assert_int_equal(j.attempts, attempt);
      /* Backed off: run_after lies ahead, so no node can claim it yet. */
      assert_int_equal(sc_claim(s->b, NULL), 0);
      RC(OBS_ECONFLICT,
         srv_db_finish_success(holder, id, att, "cpu", "{}", NULL, 0, NULL, 0, 0, &contract_err));
      int held = -1, cancel = -1;
      OK(srv_db_heartbeat(holder, &id, &att, 1, &held, &cancel, &contract_err));
      assert_int_equal(held, 0);
      assert_int_equal(sc_state_of(s->a, id), SRV_QUEUED);
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

/* Reaped to failure by another node, then excluded: node-h, which let the lease of the job lapse
 * three times, never claims it again, in this boot or the next (the node counts, not the boot);
 * another node does. One case, since the exclusion needs the three lapses the reaper case waits
 * out. */
void test_reap_and_exclusion(void **state) {
  store *s = *state;
  srv_db *h = s->more[0] = sc_open_node(s, "node-h", 1);
  int64_t id = sc_insert(s->a, "ssao", 0);
  if (!s->pg) {
    /* One daemon owns a SQLite file: its leases never expire while it lives. */
    int att = 0;
    assert_int_equal(sc_claim(h, &att), id);
    sc_sleep_ms(1500);
    int requeued = -1, failed = -1;
    RC(0, srv_db_reap(s->b, &requeued, &failed, &contract_err));
    assert_int_equal(requeued, 0);
    assert_int_equal(failed, 0);
    assert_int_equal(sc_state_of(s->a, id), SRV_RUNNING);
    sc_succeed(h, id, att, NULL, 0, 0);
    printf(
        "exclusion skipped on SQLite: no failure of a node can be recorded through the store "
        "interface there (its reap never expires a lease), so it is checked on PostgreSQL\n");
    return;
  }
  expire_until_failed(s, h, id);
  srv_state st;
  OK(srv_db_retry(s->a, id, &st, &contract_err));
  assert_int_equal(sc_state_of(s->a, id), SRV_QUEUED);
  assert_int_equal(sc_claim(h, NULL), 0);                  /* node-h failed it three times */
  srv_db *h2 = s->more[1] = sc_open_node(s, "node-h", 30); /* its next boot: the node counts */
  assert_int_equal(sc_claim(h2, NULL), 0);
  int att = 0;
  assert_int_equal(sc_claim(s->b, &att), id);
  sc_succeed(s->b, id, att, NULL, 0, 0);
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

void test_recover(void **state) {
  store *s = *state;
  int64_t left = sc_insert(s->a, "ssao", 2), cancelled = sc_insert(s->a, "ssao", 1);
  int64_t other = sc_insert(s->a, "ssao", 0);
  int att = 0, other_att = 0;
  assert_int_equal(sc_claim(s->a, &att), left);
  assert_int_equal(sc_claim(s->a, &att), cancelled);
  assert_int_equal(sc_claim(s->b, &other_att), other);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, cancelled, &res, &contract_err));
  int64_t moved = sc_insert_vulkan(s->a, "moved", 0),
          refused = sc_insert_vulkan(s->a, "refused", 0);
  srv_db_close(s->a); /* node-a dies with two jobs running */
  s->a = NULL;
  s->a = sc_open_node(s, "node-a", 30);
  recovered r = {0};
  OK(srv_db_recover(s->a, pick_lane, note_clean, &r, &contract_err));
  srv_job j = sc_get(s->b, left);
  assert_int_equal(j.state, SRV_QUEUED);
  assert_int_equal(j.attempts, 1);
  srv_job_free(&j);
  assert_int_equal(sc_state_of(s->b, cancelled), SRV_CANCELLED);
  j = sc_get(s->b, refused);
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
    j = sc_get(s->b, other);
    assert_int_equal(j.state, SRV_RUNNING);
    assert_string_equal(j.node, "node-b");
    srv_job_free(&j);
    sc_succeed(s->b, other, other_att, NULL, 0, 0);
  }
  assert_int_equal(sc_claim(s->a, &att), left);
  assert_int_equal(att, 2); /* the interrupted attempt counts */
  int64_t next = sc_claim(s->a, NULL);
  if (next == other) next = sc_claim(s->a, NULL);
  if (s->pg) {
    assert_int_equal(next, 0);
    srv_job vj;
    OK(srv_db_claim(s->a, SRV_LANE_VULKAN, &vj, &contract_err));
    assert_int_equal(vj.id, moved);
    srv_job_free(&vj);
  } else {
    assert_int_equal(next, moved);
  }
}

/* ---- blobs and wake-ups ------------------------------------------------------------------- */

void test_blobs(void **state) {
  store *s = *state;
  static const char sha[] = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
  unsigned char data[3000];
  uint32_t seed = 7;
  for (size_t i = 0; i < sizeof data; i++) data[i] = (unsigned char)obs_test_rand(&seed);
  data[10] = 0; /* bytes, not text */
  void *got = NULL;
  size_t n = 0;
  if (!s->pg) { /* a SQLite store's outputs are local files */
    OK(srv_db_put_blob(s->a, sha, data, sizeof data, &contract_err));
    RC(OBS_ENOTFOUND, srv_db_get_blob(s->b, sha, &got, &n, &contract_err));
    assert_int_equal(srv_db_results_shared(s->a), 0);
    return;
  }
  RC(OBS_ENOTFOUND, srv_db_get_blob(s->b, sha, &got, &n, &contract_err));
  OK(srv_db_put_blob(s->a, sha, data, sizeof data, &contract_err));
  OK(srv_db_put_blob(s->b, sha, data, sizeof data, &contract_err)); /* idempotent */
  OK(srv_db_get_blob(s->b, sha, &got, &n, &contract_err));
  assert_int_equal(n, sizeof data);
  assert_memory_equal(got, data, sizeof data);
  free(got);
}

/* Drains what earlier statements notified, so the next wake-up is the one a test causes. */
static void sc_drain(srv_db *db) {
  int what = 0;
  for (int i = 0; i < 50; i++) {
    obs_err_clear(&contract_err);
    int rc = srv_db_wait(db, 200, &what, &contract_err);
    if (rc < 0) fail_msg("wait -> %d: %s", rc, obs_err_message(&contract_err));
    if (rc == 0) return;
  }
  fail_msg("the wake-ups never stopped");
}

void test_wait(void **state) {
  store *s = *state;
  int what = -1;
  if (!s->pg) { /* no other node: the scheduler's own notify wakes its workers */
    double t0 = sc_now_ms();
    RC(0, srv_db_wait(s->a, 300, &what, &contract_err));
    assert_true(sc_now_ms() - t0 >= 290);
    assert_int_equal(what, 0);
    return;
  }
  sc_drain(s->a);
  int64_t id = sc_insert(s->b, "ssao", 0);
  RC(1, srv_db_wait(s->a, 5000, &what, &contract_err));
  assert_true(what & SRV_WAKE_JOBS);
  sc_drain(s->a);
  int att = 0;
  assert_int_equal(sc_claim(s->a, &att), id);
  sc_drain(s->a);
  srv_cancel_result res;
  OK(srv_db_cancel(s->b, id, &res, &contract_err));
  what = 0;
  RC(1, srv_db_wait(s->a, 5000, &what, &contract_err));
  assert_true(what & SRV_WAKE_CANCEL);
  sc_drain(s->a);
  sc_insert_comparison(s->b, "wake");
  what = 0;
  RC(1, srv_db_wait(s->a, 5000, &what, &contract_err));
  assert_true(what & SRV_WAKE_JOBS);
  sc_drain(s->a);
  RC(0, srv_db_wait(s->a, 200, &what, &contract_err));
}
