/* Shared by the PostgreSQL store's tests (test_pg_store.c, test_pg_cluster.c): the server's URL
 * from OBSCURA_TEST_PG_URL (NULL: every case skips), the tests' own connection for what no API
 * call sets up, nodes with known identities, a store emptied before every case, and jobs. */
#ifndef OBS_PG_FIXTURE_H
#define OBS_PG_FIXTURE_H

#include <libpq-fe.h>

#include "obscurad.h"
#include "testutil.h"

extern const char *pg_url;
extern PGconn *pg_admin;

/* SQL on the tests' own connection (failing the case on error); sql_int reads one integer. */
void pg_sql(const char *q);
int64_t pg_sql_int(const char *q);
/* A node with a known boot, so that its worker id is known too. */
srv_node pg_node(const char *name, const char *boot, int lease_seconds);
srv_db *pg_open_node(const char *name, const char *boot, int lease_seconds);
/* cmocka setup/teardown: an emptied store, and node "alpha" (boot "b1") open in *state. */
int pg_setup(void **state);
int pg_teardown(void **state);
/* Connects to the URL, drops the schema and lets two nodes migrate it at once: 0, or 1 after
 * printing why (a URL that does not answer); 0 with pg_url NULL when none is set. */
int pg_fixture_start(void);
void pg_fixture_stop(void);

#define NEED_PG()                                                                                 \
  do {                                                                                            \
    if (!pg_url) skip();                                                                          \
  } while (0)

srv_new_job pg_new_job(int priority, const char *technique);
int64_t pg_insert(srv_db *db, int priority, const char *technique);
/* Claims the next CPU job: its id (attempt in *attempt), or 0 when none is ready. */
int64_t pg_claim(srv_db *db, int *attempt);
srv_state pg_state_of(srv_db *db, int64_t id);

#endif
