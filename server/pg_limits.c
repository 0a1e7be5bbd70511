/* The PostgreSQL store's reads behind the admission limits (limits.c): the active jobs' load per
 * client and in total (summed over the partial index of active jobs, never the history), what
 * one job adds, the client of a job, and stored run rates. */
#include <stdlib.h>
#include <string.h>

#include "pg_internal.h"

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
