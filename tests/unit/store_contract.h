/* The store contract suite's shared parts (test_store_contract.c, store_contract_*.c): the store
 * under test with its two nodes, the checks that print the store's message on failure, the
 * helpers every case uses, and the cases of the other files. */
#ifndef OBS_STORE_CONTRACT_H
#define OBS_STORE_CONTRACT_H

#include "testutil.h"
#include "obscurad.h"

/* One test's store: OBSCURA_TEST_STORE unset gives a fresh SQLite file, a postgresql:// URL a
 * fresh database on that server (created by sc_setup, dropped by sc_teardown). */
typedef struct store {
  char where[1200]; /* the SQLite file or this test's PostgreSQL URL */
  char dbname[80];  /* PostgreSQL: this test's database */
  int pg;
  srv_db *a, *b;   /* nodes "node-a" and "node-b" on the same store, 30 s leases */
  srv_db *more[2]; /* further handles a case opens (sc_open_node), closed at teardown too */
} store;

/* The error of the last call OK or RC checked. */
extern obs_err contract_err;

#define OK(call)                                                                        \
  do {                                                                                  \
    obs_err_clear(&contract_err);                                                       \
    int rc_ = (call);                                                                   \
    if (rc_ != 0) fail_msg("%s -> %d: %s", #call, rc_, obs_err_message(&contract_err)); \
  } while (0)
#define RC(want, call)                                                                        \
  do {                                                                                        \
    obs_err_clear(&contract_err);                                                             \
    int rc_ = (call);                                                                         \
    if (rc_ != (want))                                                                        \
      fail_msg("%s -> %d (%s), want %d", #call, rc_, obs_err_message(&contract_err), (want)); \
  } while (0)

int sc_setup(void **state);
int sc_teardown(void **state);
/* Another handle on the store as node `name` (a new boot of it when the name is taken). */
srv_db *sc_open_node(const store *s, const char *name, int lease_seconds);

/* A small CPU job of `technique` (its work is width x height x spp). */
srv_new_job sc_job_of(const char *technique, int priority);
int64_t sc_insert(srv_db *db, const char *technique, int priority);
int64_t sc_insert_vulkan(srv_db *db, const char *technique, int priority);
/* Claims the next CPU job: its id and *attempt, or 0 when none is ready. */
int64_t sc_claim(srv_db *db, int *attempt);
/* Claims job `id` (the next one) and records its success. */
int64_t sc_finish_one(srv_db *db, int64_t id);
srv_job sc_get(srv_db *db, int64_t id);
srv_state sc_state_of(srv_db *db, int64_t id);
/* Records the success of attempt `attempt` with one output, "ao". */
void sc_succeed(srv_db *db, int64_t id, int attempt, const srv_run *runs, int nruns,
                int64_t machine);
/* srv_db_query with up to two integer arguments. */
json_t *sc_query(srv_db *db, srv_query q, int64_t a1, int64_t a2, int nargs);
int64_t sc_col_int(json_t *rows, size_t i, const char *col);
const char *sc_col_str(json_t *rows, size_t i, const char *col);
/* A comparison of two candidates (ssao, hbao) against one rt_ao reference, plus a further
 * measurement of the first candidate ("common"): candidate rows 0, 1, 2. */
int64_t sc_insert_comparison(srv_db *db, const char *label);
/* Its jobs: reference, candidate 0, candidate 1. */
void sc_comparison_jobs(srv_db *db, int64_t cmp, int64_t out[3]);
/* Stores figures for every candidate row of `cmp` that awaits them. */
void sc_measure_all(srv_db *db, int64_t cmp);
/* How many times `id` is among ids[0..n). */
int sc_contains(const int64_t *ids, int n, int64_t id);
double sc_now_ms(void);
void sc_sleep_ms(int ms);

/* store_contract_nodes.c: leases, recovery, blobs, wake-ups. */
void test_reap_and_exclusion(void **state);
void test_recover(void **state);
void test_blobs(void **state);
void test_wait(void **state);
/* store_contract_records.c: comparisons, the limits' reads, run rates, retention. */
void test_comparison_queries(void **state);
void test_comparison_metrics(void **state);
void test_limits(void **state);
void test_run_rates(void **state);
void test_prune(void **state);

#endif
