/* obscurad's PostgreSQL store: the pool of connections (each with its timeouts, its name and its
 * prepared statements, reconnected and re-prepared after a loss), the runner that retries an
 * operation once on a fresh connection, the migrations of schema/pg.sql, and the parameter and
 * row helpers the other pg*.c files use. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pg_internal.h"

extern const char srv_pg_sql[];
extern const size_t srv_pg_sql_len;

/* Serialises the migrations of daemons starting together (pg_advisory_xact_lock's key). */
#define MIGRATION_LOCK "7283190441"

/* The server's notices and warnings go to the daemon's log, not to stderr unannounced. */
static void notice(void *arg, const char *msg) {
  const struct srv_pg *pg = arg;
  size_t len = strlen(msg);
  while (len && msg[len - 1] == '\n') len--;
  srv_log("database %s: %.*s", pg->shown, (int)len, msg);
}

PGconn *srv_pgi_connect(struct srv_pg *pg, obs_err *err) {
  /* Later keywords override the URL's: every connection carries its timeouts and its name. */
  const char *keys[] = {"dbname", "application_name", "options", "connect_timeout", NULL};
  const char *vals[] = {pg->url, pg->app,
                        "-c statement_timeout=10s -c idle_in_transaction_session_timeout=30s "
                        "-c client_min_messages=warning",
                        "5", NULL};
  PGconn *pq = PQconnectdbParams(keys, vals, 1);
  if (!pq || PQstatus(pq) != CONNECTION_OK) {
    obs_err_set(err, OBS_ETRANSIENT, "database %s: cannot connect: %s", pg->shown,
                pq ? PQerrorMessage(pq) : "out of memory");
    PQfinish(pq);
    return NULL;
  }
  PQsetNoticeProcessor(pq, notice, pg);
  return pq;
}

/* Connects c, or reconnects it after a loss (its statements prepared anew). */
static int ready(struct srv_pg *pg, pgc *c, obs_err *err) {
  if (c->pq && !c->broken && PQstatus(c->pq) == CONNECTION_OK) return 0;
  memset(c->prepared, 0, sizeof c->prepared);
  c->broken = 0;
  if (c->pq) {
    PQreset(c->pq);
    if (PQstatus(c->pq) == CONNECTION_OK) return 0;
    PQfinish(c->pq);
    c->pq = NULL;
  }
  c->pq = srv_pgi_connect(pg, err);
  return c->pq ? 0 : OBS_ETRANSIENT;
}

pgc *srv_pgi_acquire(struct srv_pg *pg) {
  pthread_mutex_lock(&pg->mu);
  for (;;) {
    for (int i = 0; i < pg->n; i++) {
      if (!pg->c[i].in_use) {
        pg->c[i].in_use = 1;
        pthread_mutex_unlock(&pg->mu);
        return &pg->c[i];
      }
    }
    pthread_cond_wait(&pg->cv, &pg->mu);
  }
}

void srv_pgi_release(struct srv_pg *pg, pgc *c) {
  pthread_mutex_lock(&pg->mu);
  c->in_use = 0;
  pthread_cond_signal(&pg->cv);
  pthread_mutex_unlock(&pg->mu);
}

/* A failed result as an error code: a lost connection (class 08, the server shutting down) marks
 * c broken; those, timeouts, deadlocks, serialization failures and a server short of resources
 * are the environment's (OBS_ETRANSIENT). */
static int fail(struct srv_pg *pg, pgc *c, const PGresult *r, const char *what, obs_err *err) {
  const char *state = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : NULL;
  int lost = PQstatus(c->pq) != CONNECTION_OK || !state || !strncmp(state, "08", 2) ||
             !strcmp(state, "57P01") || !strcmp(state, "57P02") || !strcmp(state, "57P03");
  if (lost) c->broken = 1;
  /* A statement that timed out would only time out again: not retried. */
  c->retry = lost || !strcmp(state, "40001") || !strcmp(state, "40P01");
  int transient = lost || !strcmp(state, "40001") || !strcmp(state, "40P01") ||
                  !strcmp(state, "57014") || !strcmp(state, "55P03") ||
                  !strcmp(state, "25P03") || !strncmp(state, "53", 2);
  const char *msg = r && PQresultErrorMessage(r)[0] ? PQresultErrorMessage(r) : PQerrorMessage(c->pq);
  size_t len = strlen(msg);
  while (len && msg[len - 1] == '\n') len--;
  return obs_err_set(err, transient ? OBS_ETRANSIENT : OBS_EIO, "database %s: %s: %.*s",
                     pg->shown, what, (int)len, msg);
}

int srv_pgi_exec(struct srv_pg *pg, pgc *c, int which, int n, const char *const *vals,
                 const int *lens, const int *fmts, int binres, PGresult **res, obs_err *err) {
  if (res) *res = NULL;
  char name[16];
  snprintf(name, sizeof name, "s%d", which);
  if (!c->prepared[which]) {
    PGresult *p = PQprepare(c->pq, name, srv_pgi_sql(which), 0, NULL);
    int ok = PQresultStatus(p) == PGRES_COMMAND_OK;
    int rc = ok ? 0 : fail(pg, c, p, "preparing a statement", err);
    PQclear(p);
    if (rc) return rc;
    c->prepared[which] = 1;
  }
  PGresult *r = PQexecPrepared(c->pq, name, n, vals, lens, fmts, binres);
  ExecStatusType st = PQresultStatus(r);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) {
    int rc = fail(pg, c, r, "statement", err);
    PQclear(r);
    return rc;
  }
  if (res) *res = r;
  else PQclear(r);
  return 0;
}

int srv_pgi_simple(struct srv_pg *pg, pgc *c, const char *sql, obs_err *err) {
  PGresult *r = PQexec(c->pq, sql);
  ExecStatusType st = PQresultStatus(r);
  int rc = st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK ? 0 : fail(pg, c, r, sql, err);
  PQclear(r);
  return rc;
}

int srv_pgi_run(struct srv_pg *pg, int txn, srv_pgi_op op, void *ctx, obs_err *err) {
  pgc *c = srv_pgi_acquire(pg);
  int rc = 0;
  for (int attempt = 0; attempt < 2; attempt++) {
    obs_err e = OBS_ERR_INIT;
    c->retry = 0;
    rc = ready(pg, c, &e);
    if (rc) c->retry = 1;
    if (!rc && txn) rc = srv_pgi_simple(pg, c, "BEGIN", &e);
    if (!rc) rc = op(pg, c, ctx, &e);
    if (!rc && txn) rc = srv_pgi_simple(pg, c, "COMMIT", &e);
    if (rc && txn && !c->broken && PQtransactionStatus(c->pq) != PQTRANS_IDLE)
      srv_pgi_simple(pg, c, "ROLLBACK", NULL);
    /* Only a lost connection, a deadlock or a serialization failure is worth a second try;
     * OBS_ENOTFOUND, OBS_ECONFLICT and the like are answers. */
    if (!rc || !c->retry || attempt == 1) {
      if (rc) obs_err_set(err, rc, "%s", obs_err_message(&e));
      obs_err_free(&e);
      break;
    }
    obs_err_free(&e);
  }
  srv_pgi_release(pg, c);
  return rc;
}

typedef struct one_ctx {
  int which, n;
  const char *const *vals;
  PGresult **res;
} one_ctx;

static int one_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  one_ctx *o = ctx;
  if (o->res && *o->res) {
    PQclear(*o->res);
    *o->res = NULL;
  }
  return srv_pgi_exec(pg, c, o->which, o->n, o->vals, NULL, NULL, 0, o->res, err);
}

int srv_pgi_one(struct srv_pg *pg, int which, int n, const char *const *vals, PGresult **res,
                obs_err *err) {
  if (res) *res = NULL;
  one_ctx o = {which, n, vals, res};
  return srv_pgi_run(pg, 0, one_op, &o, err);
}

int srv_pgi_refused(struct srv_pg *pg, obs_err *err) {
  pthread_mutex_lock(&pg->mu);
  int r = pg->refuse[0] != 0;
  if (r) obs_err_set(err, OBS_ETRANSIENT, "not accepting work: %s", pg->refuse);
  pthread_mutex_unlock(&pg->mu);
  return r ? OBS_ETRANSIENT : 0;
}

/* ---- parameters and rows --------------------------------------------------------------------- */

const char *srv_pgi_i64(char buf[24], int64_t v) {
  snprintf(buf, 24, "%lld", (long long)v);
  return buf;
}

const char *srv_pgi_f64(char buf[32], double v) {
  snprintf(buf, 32, "%.17g", v);
  return buf;
}

static void put(pgbuf *b, const char *s, size_t n) {
  if (b->oom) return;
  if (b->n + n + 2 > b->cap) {
    size_t cap = b->cap ? b->cap : 256;
    while (b->n + n + 2 > cap) cap *= 2;
    char *g = realloc(b->s, cap);
    if (!g) {
      b->oom = 1;
      return;
    }
    b->s = g;
    b->cap = cap;
  }
  memcpy(b->s + b->n, s, n);
  b->n += n;
  b->s[b->n] = '\0';
}

static void sep(pgbuf *b) {
  if (b->n > 1) put(b, ",", 1);
}

void srv_pgi_arr_open(pgbuf *b) {
  memset(b, 0, sizeof *b);
  put(b, "{", 1);
}

void srv_pgi_arr_i64(pgbuf *b, int64_t v) {
  char t[24];
  sep(b);
  put(b, t, strlen(srv_pgi_i64(t, v)));
}

void srv_pgi_arr_f64(pgbuf *b, double v) {
  char t[32];
  sep(b);
  put(b, t, strlen(srv_pgi_f64(t, v)));
}

/* Elements are double-quoted with " and \ escaped: any text survives, and NULL stays NULL. */
void srv_pgi_arr_text(pgbuf *b, const char *v) {
  sep(b);
  if (!v) {
    put(b, "NULL", 4);
    return;
  }
  put(b, "\"", 1);
  for (const char *p = v; *p;) {
    size_t run = strcspn(p, "\"\\");
    put(b, p, run);
    p += run;
    if (*p) {
      char esc[2] = {'\\', *p++};
      put(b, esc, 2);
    }
  }
  put(b, "\"", 1);
}

const char *srv_pgi_arr_close(pgbuf *b) {
  put(b, "}", 1);
  return b->oom ? NULL : b->s;
}

void srv_pgi_buf_free(pgbuf *b) {
  free(b->s);
  memset(b, 0, sizeof *b);
}

char *srv_pgi_str(const PGresult *r, int row, int col) {
  return PQgetisnull(r, row, col) ? NULL : strdup(PQgetvalue(r, row, col));
}

int64_t srv_pgi_int(const PGresult *r, int row, int col) {
  return PQgetisnull(r, row, col) ? 0 : strtoll(PQgetvalue(r, row, col), NULL, 10);
}

double srv_pgi_real(const PGresult *r, int row, int col) {
  return PQgetisnull(r, row, col) ? 0 : strtod(PQgetvalue(r, row, col), NULL);
}

/* ---- opening and migrations ------------------------------------------------------------------ */

/* Applies every "-- migration N" section of schema/pg.sql newer than the database, all in one
 * transaction under an advisory lock. */
static int migrate(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  (void)ctx;
  int rc = srv_pgi_simple(pg, c, "SELECT pg_advisory_xact_lock(" MIGRATION_LOCK ")", err);
  if (!rc)
    rc = srv_pgi_simple(pg, c,
                        "CREATE TABLE IF NOT EXISTS schema_migrations (version integer PRIMARY "
                        "KEY, applied_ms bigint NOT NULL)",
                        err);
  if (rc) return rc;
  PGresult *r = PQexec(c->pq, "SELECT coalesce(max(version), 0) FROM schema_migrations");
  if (PQresultStatus(r) != PGRES_TUPLES_OK) {
    rc = fail(pg, c, r, "reading schema_migrations", err);
    PQclear(r);
    return rc;
  }
  int64_t have = srv_pgi_int(r, 0, 0);
  PQclear(r);
  static const char marker[] = "\n-- migration ";
  int64_t latest = 0;
  const char *p = strstr(srv_pg_sql, marker);
  while (p && !rc) {
    const char *num = p + sizeof marker - 1;
    int64_t v = strtoll(num, NULL, 10);
    const char *body = strchr(num, '\n');
    const char *next = body ? strstr(body, marker) : NULL;
    if (v != latest + 1 || !body)
      return obs_err_set(err, OBS_EINTERNAL, "schema/pg.sql: migrations must be numbered 1, 2, ...");
    latest = v;
    if (v > have) {
      char *text = strndup(body, next ? (size_t)(next - body) : strlen(body));
      if (!text) return obs_err_set(err, OBS_ENOMEM, "out of memory");
      rc = srv_pgi_simple(pg, c, text, err);
      free(text);
      char put_sql[160];
      snprintf(put_sql, sizeof put_sql,
               "INSERT INTO schema_migrations (version, applied_ms) VALUES (%lld, "
               "(extract(epoch FROM clock_timestamp()) * 1000)::bigint)",
               (long long)v);
      if (!rc) rc = srv_pgi_simple(pg, c, put_sql, err);
      if (!rc) srv_log("database %s: applied migration %lld", pg->shown, (long long)v);
    }
    p = next;
  }
  if (!rc && have > latest)
    return obs_err_set(err, OBS_EINVAL,
                       "database %s is at schema version %lld, newer than this obscurad (%lld)",
                       pg->shown, (long long)have, (long long)latest);
  return rc;
}

/* The URL as shown in logs and the API: the password of user:password@ or ?password= as ***. */
static char *redact(const char *url) {
  size_t n = strlen(url);
  char *out = malloc(n + 4);
  if (!out) return NULL;
  const char *scheme = strstr(url, "://");
  const char *auth = scheme ? scheme + 3 : url;
  const char *at = strchr(auth, '@');
  const char *slash = strchr(auth, '/');
  const char *colon = at ? memchr(auth, ':', (size_t)(at - auth)) : NULL;
  if (at && (!slash || at < slash) && colon)
    snprintf(out, n + 4, "%.*s***%s", (int)(colon + 1 - url), url, at);
  else
    snprintf(out, n + 4, "%s", url);
  char *pw = strstr(out, "password=");
  if (pw) {
    pw += 9;
    char *end = pw + strcspn(pw, "&");
    memmove(pw + 3, end, strlen(end) + 1);
    memcpy(pw, "***", 3);
  }
  return out;
}

int srv_pg_open(struct srv_pg **out, const char *url, int nconn, const srv_node *node,
                obs_err *err) {
  *out = NULL;
  if (nconn < 1) nconn = 1;
  struct srv_pg *pg = calloc(1, sizeof *pg);
  if (!pg) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  pg->c = calloc((size_t)nconn, sizeof *pg->c);
  pg->url = strdup(url);
  pg->shown = redact(url);
  if (!pg->c || !pg->url || !pg->shown) {
    free(pg->c);
    free(pg->url);
    free(pg->shown);
    free(pg);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  pg->n = nconn;
  if (node) pg->node = *node;
  if (pg->node.lease_seconds <= 0) pg->node.lease_seconds = 30;
  snprintf(pg->app, sizeof pg->app, "obscurad %s", pg->node.worker);
  pthread_mutex_init(&pg->mu, NULL);
  pthread_cond_init(&pg->cv, NULL);
  pthread_mutex_init(&pg->lmu, NULL);
  pthread_mutex_init(&pg->amu, NULL);
  int rc = srv_pgi_run(pg, 1, migrate, NULL, err);
  if (rc) {
    srv_pg_close(pg);
    return rc;
  }
  *out = pg;
  return 0;
}

void srv_pg_close(struct srv_pg *pg) {
  if (!pg) return;
  for (int i = 0; i < pg->n; i++) PQfinish(pg->c[i].pq);
  PQfinish(pg->listener);
  PQfinish(pg->admit);
  free(pg->c);
  free(pg->url);
  free(pg->shown);
  pthread_mutex_destroy(&pg->mu);
  pthread_cond_destroy(&pg->cv);
  pthread_mutex_destroy(&pg->lmu);
  pthread_mutex_destroy(&pg->amu);
  free(pg);
}

void srv_pg_refuse(struct srv_pg *pg, const char *msg) {
  pthread_mutex_lock(&pg->mu);
  snprintf(pg->refuse, sizeof pg->refuse, "%s", msg ? msg : "");
  pthread_mutex_unlock(&pg->mu);
}

const char *srv_pg_path(const struct srv_pg *pg) { return pg->shown; }

int srv_pg_results_shared(const struct srv_pg *pg) {
  (void)pg;
  return 1;
}
