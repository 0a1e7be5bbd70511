/* The PostgreSQL store's side of the admission limits (limits.c): the lock that orders every
 * node's admissions, the active jobs' load per client and in total (summed over the partial index
 * of active jobs, never the history), what one job adds, the client of a job, and stored run
 * rates. */
#include <stdlib.h>
#include <string.h>

#include "pg_internal.h"

/* pg_advisory_lock's key for admission: one per store, shared by every node. */
#define ADMIT_LOCK "7283190442"

/* The lock is a session's: it lives on a connection of its own (not the pool's, whose every
 * connection the section's reads and inserts may need), and goes with the session if the node
 * dies. Waiting for another node is bounded by the statement timeout. */
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

int srv_pg_queued(struct srv_pg *pg, const char *client, srv_load *mine, srv_load *total,
                  obs_err *err) {
  memset(mine, 0, sizeof *mine);
  memset(total, 0, sizeof *total);
  const char *v[] = {client};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_QUEUED, 1, v, &r, err);
  if (rc) return rc;
  total->work = srv_pgi_real(r, 0, 0);
  total->jobs = srv_pgi_real(r, 0, 1);
  total->bytes = srv_pgi_real(r, 0, 2);
  mine->work = srv_pgi_real(r, 0, 3);
  mine->jobs = srv_pgi_real(r, 0, 4);
  mine->bytes = srv_pgi_real(r, 0, 5);
  PQclear(r);
  return 0;
}

int srv_pg_job_load(struct srv_pg *pg, int64_t id, srv_load *load, srv_state *state,
                    obs_err *err) {
  memset(load, 0, sizeof *load);
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, id)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_JOB_LOAD, 1, v, &r, err);
  if (rc) return rc;
  if (PQntuples(r) == 0) {
    rc = OBS_ENOTFOUND;
  } else {
    load->work = srv_pgi_real(r, 0, 0);
    load->jobs = srv_pgi_real(r, 0, 1);
    load->bytes = srv_pgi_real(r, 0, 2);
    if (srv_state_parse(PQgetvalue(r, 0, 3), state)) *state = SRV_FAILED;
  }
  PQclear(r);
  return rc;
}

int srv_pg_set_job_client(struct srv_pg *pg, int64_t job, int64_t comparison, const char *client,
                          obs_err *err) {
  char sj[24], sc[24];
  /* Comparison ids start at 1: 0 matches no job's comparison. */
  const char *v[] = {srv_pgi_i64(sj, job), srv_pgi_i64(sc, comparison), client};
  return srv_pgi_one(pg, PGS_SET_CLIENT, 3, v, NULL, err);
}

int srv_pg_run_rates(struct srv_pg *pg, const char *technique, const char *backend,
                     int64_t machine, double min_work, double **rates, size_t *n, obs_err *err) {
  *rates = NULL;
  *n = 0;
  char sm[24], sw[32];
  const char *v[] = {technique, backend, srv_pgi_i64(sm, machine), srv_pgi_f64(sw, min_work)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_RUN_RATES, 4, v, &r, err);
  if (rc) return rc;
  double *out = malloc(((size_t)PQntuples(r) + 1) * sizeof *out);
  if (!out) {
    PQclear(r);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  for (int i = 0; i < PQntuples(r); i++) {
    double x = srv_pgi_real(r, i, 0);
    if (!PQgetisnull(r, i, 0) && x >= 0 && x < 1e30) out[(*n)++] = x;
  }
  PQclear(r);
  *rates = out;
  return 0;
}
