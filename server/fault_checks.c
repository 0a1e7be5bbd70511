/* The maintenance thread's watch over the environment (obscurad.h, srv_faults_check): probes of
 * the faults due a retry, the database file's identity (deleted or replaced under the daemon:
 * written back) and its integrity (quick_check). */
#include <stdio.h>

#include "obscurad.h"

/* A deleted or replaced database file: refuse work, then write the open (unlinked) database
 * back. Returns 1 when it is settled (restored, or copied aside for an operator), 0 to retry. */
static int handle_lost(srv_app *app, srv_db_identity id, const char *detail) {
  const char *path = srv_db_path(app->db);
  const char *code = id == SRV_DB_DELETED    ? "ENOENT"
                     : id == SRV_DB_REPLACED ? "replaced"
                                             : "ENOENT";
  srv_fault_raise(SRV_FAULT_DB_LOST, path, code, detail, NULL);
  srv_db_refuse(app->db, detail);
  char where[4400], action[8192];
  obs_err e = OBS_ERR_INIT;
  int rc = srv_db_restore(app->db, id, where, sizeof where, &e);
  int settled = 1;
  if (rc == 0) {
    srv_log(
        "database: %s; wrote the open database back to %s and reopened it (every accepted "
        "job kept)",
        detail, where);
    srv_db_refuse(app->db, NULL);
    srv_fault_clear(SRV_FAULT_DB_LOST);
  } else if (rc == 1) {
    snprintf(action, sizeof action,
             "the daemon's own database was copied to %.1000s (refreshed again at shutdown): stop "
             "obscurad, move the file now at %.1000s aside, move %.1000s to %.1000s and start "
             "obscurad again; "
             "until then no work is accepted",
             where, path, where, path);
    srv_fault_raise(SRV_FAULT_DB_LOST, path, code, detail, action);
    srv_log("database: %s; %s", detail, action);
  } else {
    snprintf(action, sizeof action,
             "could not write the database back (%.1000s); make %.1000s's directory writable and "
             "give it "
             "space: the daemon retries, and a restart before that loses the jobs since the last "
             "write-back",
             obs_err_message(&e), path);
    srv_fault_raise(SRV_FAULT_DB_LOST, path, code, detail, action);
    srv_fault_probe_failed(SRV_FAULT_DB_LOST, NULL, NULL);
    srv_log("database: %s; %s", detail, action);
    settled = 0;
  }
  obs_err_free(&e);
  return settled;
}

/* A due probe's outcome: the fault stays raised with the probe's reason (rc != 0), or clears and
 * the error images postponed while it was raised become due. Returns 1 when it cleared. */
static int settle_probe(srv_fault_kind f, int rc, const char *code, obs_err *e, int *metrics_due) {
  int cleared = 0;
  if (rc) {
    srv_fault_probe_failed(f, code, obs_err_message(e));
  } else {
    srv_fault_clear(f);
    *metrics_due = 1;
    cleared = 1;
  }
  obs_err_clear(e);
  return cleared;
}

int srv_faults_check(struct srv_app *app, srv_fault_clock *mc, int *metrics_due) {
  int cleared = 0;
  char code[40] = "";
  obs_err e = OBS_ERR_INIT;
  if (srv_fault_due(SRV_FAULT_RESULTS))
    cleared |= settle_probe(SRV_FAULT_RESULTS,
                            srv_outputs_probe(app->results_dir, code, sizeof code, &e), code, &e,
                            metrics_due);
  if (srv_fault_due(SRV_FAULT_DB))
    cleared |= settle_probe(SRV_FAULT_DB, srv_db_probe(app->db, code, sizeof code, &e), code, &e,
                            metrics_due);
  double now = obs_now_ms();
  int lost = srv_fault_active(SRV_FAULT_DB_LOST);
  if ((!lost && now - mc->identity_ms >= 2000) ||
      (lost && !mc->lost_settled && srv_fault_due(SRV_FAULT_DB_LOST))) {
    mc->identity_ms = now;
    char detail[4400];
    srv_db_identity id = srv_db_check_identity(app->db, detail, sizeof detail);
    if (id != SRV_DB_SAME) {
      mc->lost_settled = handle_lost(app, id, detail);
      if (!srv_fault_active(SRV_FAULT_DB_LOST)) cleared = 1;
    } else if (lost) {
      srv_fault_clear(SRV_FAULT_DB_LOST);
      srv_db_refuse(app->db, NULL);
      cleared = 1;
    }
  }
  int corrupt_seen = srv_db_take_corrupt_flag(app->db);
  if (!srv_fault_active(SRV_FAULT_DB_CORRUPT) && !srv_fault_active(SRV_FAULT_DB_LOST) &&
      (corrupt_seen || now - mc->check_ms >= 1e3 * app->cfg.db_check_seconds)) {
    mc->check_ms = now;
    int rc = srv_db_quick_check(app->db, &e);
    if (rc == 1) {
      /* A corrupt file is not repaired by waiting: work stays refused until an operator acts. */
      srv_fault_raise(SRV_FAULT_DB_CORRUPT, srv_db_path(app->db), "SQLITE_CORRUPT",
                      obs_err_message(&e), NULL);
      srv_db_refuse(app->db, obs_err_message(&e));
    } else if (rc < 0) {
      srv_log("database check: %s", obs_err_message(&e));
    }
    obs_err_clear(&e);
  }
  obs_err_free(&e);
  return cleared;
}
