/* obscurad's PostgreSQL store, the admission lock: a session advisory lock that one node holds
 * while it checks the queue's caps and inserts, so the caps hold over every node's submissions.
 * A session lock rather than a transaction's: the check and the insert run on pooled
 * connections, so the lock lives on a connection of its own (holding a pooled one could starve a
 * pool of one); if the node dies the server ends its session and the lock goes with it. */
#include <libpq-fe.h>
#include <pthread.h>

#include "pg_internal.h"

/* Any constant: the one advisory lock obscurad holds for long (pg_locks shows it as objid 2029). */
#define ADMIT_LOCK "2029"

/* Waiting for another node is bounded by the statement timeout. */
int srv_pg_admit_lock(struct srv_pg *pg, obs_err *err) {
  pthread_mutex_lock(&pg->amu);
  int rc = 0;
  for (int attempt = 0; attempt < 2; attempt++) {
    obs_err e = OBS_ERR_INIT;
    if (pg->admit && PQstatus(pg->admit) != CONNECTION_OK) {
      PQfinish(pg->admit);
      pg->admit = NULL;
    }
    if (!pg->admit) pg->admit = srv_pgi_connect(pg, &e);
    rc = pg->admit ? 0 : OBS_ETRANSIENT;
    if (!rc) {
      PGresult *r = PQexec(pg->admit, "SELECT pg_advisory_lock(" ADMIT_LOCK ")");
      if (PQresultStatus(r) != PGRES_TUPLES_OK)
        rc = obs_err_set(&e, OBS_ETRANSIENT, "database %s: the admission lock: %s", pg->shown,
                         PQerrorMessage(pg->admit));
      PQclear(r);
    }
    /* A session lost under the lock is replaced once; a timeout is not waited twice. */
    int again = rc && attempt == 0 && (!pg->admit || PQstatus(pg->admit) != CONNECTION_OK);
    if (rc && !again) obs_err_set(err, rc, "%s", obs_err_message(&e));
    obs_err_free(&e);
    if (!again) break;
  }
  if (rc) pthread_mutex_unlock(&pg->amu);
  return rc;
}

void srv_pg_admit_unlock(struct srv_pg *pg) {
  /* A lost session released the lock with it. */
  if (pg->admit && PQstatus(pg->admit) == CONNECTION_OK)
    PQclear(PQexec(pg->admit, "SELECT pg_advisory_unlock(" ADMIT_LOCK ")"));
  pthread_mutex_unlock(&pg->amu);
}
