/* obscurad's PostgreSQL store, the admission lock: a session advisory lock that one node holds
 * while it checks the queue's caps and inserts, so the caps hold over every node's submissions.
 * A session lock rather than a transaction's: the check and the insert run on other pooled
 * connections; if the node dies the server ends its session and the lock goes with it. */
#include <libpq-fe.h>
#include <pthread.h>

#include "pg_internal.h"

/* Any constant: the one advisory lock obscurad takes (pg_locks shows it as objid 2029). */
#define ADMIT_KEY "2029"

int srv_pg_admit_lock(struct srv_pg *pg, obs_err *err) {
  pgc *c = srv_pgi_acquire(pg);
  if (!c) return obs_err_set(err, OBS_ETRANSIENT, "PostgreSQL %s cannot be reached", pg->shown);
  int rc = srv_pgi_simple(pg, c, "SELECT pg_advisory_lock(" ADMIT_KEY ")", err);
  if (rc) {
    srv_pgi_release(pg, c);
    return rc;
  }
  pg->admit = c;
  return 0;
}

void srv_pg_admit_unlock(struct srv_pg *pg) {
  pgc *c = pg->admit;
  if (!c) return;
  pg->admit = NULL;
  obs_err e = OBS_ERR_INIT;
  /* A lost connection released the lock with its session; a failed unlock is only logged. */
  if (srv_pgi_simple(pg, c, "SELECT pg_advisory_unlock(" ADMIT_KEY ")", &e))
    srv_log("PostgreSQL: admission lock not released: %s", obs_err_message(&e));
  obs_err_free(&e);
  srv_pgi_release(pg, c);
}
