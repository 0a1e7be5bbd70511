/* The connection guard of obscurad's HTTP layer: it tracks which connections are still sending
 * their request headers and since when, and closes them when they take too long in all (not per
 * byte), when one client address holds too many of them, or when the pool nears its limit, so a
 * client that sends a complete request promptly always gets in. It also bounds the request-body
 * bytes held in memory across all connections, and the time an upload may take to send them. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <time.h>

#include "obscurad.h"

/* A connection younger than this is never closed for its address's quota: a burst of fast,
 * legitimate connections from one address (a test harness, a page loading) must not evict
 * itself. Slow clients are older than that by the time they matter. */
#define GRACE_MS 1000.0
#define BUCKETS 1024
#define REAP_PERIOD_MS 100
/* At most one summary line of closed connections per this period: an attack must not flood the
 * log. */
#define LOG_PERIOD_MS 10000.0

typedef struct peer peer;

typedef struct gconn {
  struct gconn *prev, *next;   /* every tracked connection, oldest first */
  struct gconn *pprev, *pnext; /* those of the same address, oldest first */
  peer *peer;
  int fd;
  int waiting;   /* its request headers are not complete */
  int uploading; /* its headers are, its body is still arriving */
  int closing;   /* shut down here; libmicrohttpd closes it and then reports it closed */
  double since;  /* when it began waiting (accept, or the end of its previous request) or
                    uploading */
  int64_t received; /* body bytes of the request being uploaded */
} gconn;

struct peer {
  peer *next; /* hash chain */
  unsigned char key[16];
  int keylen;
  int waiting; /* its connections that are waiting and not closing */
  gconn *head, *tail;
};

struct srv_guard {
  pthread_mutex_t mu;
  pthread_cond_t cv;
  pthread_t reaper;
  int reaper_started, stop;
  gconn *head, *tail;
  peer *buckets[BUCKETS];
  int live; /* tracked connections not closing */
  double header_timeout_ms;
  int soft_limit, per_address;
  int64_t max_inflight;
  _Atomic int64_t inflight;
  double body_timeout_ms, min_body_rate; /* an upload's time: timeout + received / rate */
  /* Closed connections by reason, and what the last log line reported. */
  unsigned long long timed_out, over_quota, for_room, too_slow, logged;
  double last_log;
};

/* The quota key of an address: IPv4 as is (IPv4-mapped IPv6 included), IPv6 by its /64, which
 * is what one host or subscriber normally holds. */
static int address_key(const struct sockaddr *sa, unsigned char key[16]) {
  if (sa && sa->sa_family == AF_INET) {
    memcpy(key, &((const struct sockaddr_in *)sa)->sin_addr, 4);
    return 4;
  }
  if (sa && sa->sa_family == AF_INET6) {
    const unsigned char *a = ((const struct sockaddr_in6 *)sa)->sin6_addr.s6_addr;
    static const unsigned char mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
    if (!memcmp(a, mapped, 12)) {
      memcpy(key, a + 12, 4);
      return 4;
    }
    memcpy(key, a, 8);
    return 8;
  }
  return 0;
}

void srv_guard_client_name(const struct sockaddr *sa, char *buf, size_t n) {
  unsigned char key[16] = {0};
  int len = address_key(sa, key);
  char addr[INET6_ADDRSTRLEN] = "unknown";
  if (len == 4) {
    inet_ntop(AF_INET, key, addr, sizeof addr);
    snprintf(buf, n, "%s", addr);
  } else if (len == 8) {
    inet_ntop(AF_INET6, key, addr, sizeof addr); /* the rest of key is zero: prefix::/64 */
    snprintf(buf, n, "%s/64", addr);
  } else {
    snprintf(buf, n, "unknown");
  }
}

static unsigned hash_key(const unsigned char *k, int n) {
  unsigned h = 2166136261u;
  for (int i = 0; i < n; i++) h = (h ^ k[i]) * 16777619u;
  return h % BUCKETS;
}

static peer *peer_get(srv_guard *g, const unsigned char *key, int n) {
  unsigned b = hash_key(key, n);
  for (peer *p = g->buckets[b]; p; p = p->next)
    if (p->keylen == n && !memcmp(p->key, key, (size_t)n)) return p;
  peer *p = calloc(1, sizeof *p);
  if (!p) return NULL;
  memcpy(p->key, key, (size_t)n);
  p->keylen = n;
  p->next = g->buckets[b];
  g->buckets[b] = p;
  return p;
}

static void peer_drop(srv_guard *g, peer *p) {
  peer **pp = &g->buckets[hash_key(p->key, p->keylen)];
  while (*pp && *pp != p) pp = &(*pp)->next;
  if (*pp) *pp = p->next;
  free(p);
}

/* Shuts the socket down; libmicrohttpd sees the end of the stream on its own thread and closes
 * the connection as usual. Safe against a reused descriptor: libmicrohttpd reports a connection
 * closed (srv_guard_closed, which takes the mutex held here) before it closes the descriptor. */
static void evict(srv_guard *g, gconn *c, unsigned long long *reason) {
  shutdown(c->fd, SHUT_RDWR);
  c->closing = 1;
  g->live--;
  if (c->waiting) c->peer->waiting--;
  (*reason)++;
}

/* Oldest first: the waiting connection of `p` (any address when NULL) that has waited at least
 * `min_age` ms, other than `self`; with `uploading`, the oldest one receiving a body instead. */
static gconn *oldest_waiting(srv_guard *g, peer *p, const gconn *self, double now, double min_age,
                             int uploading) {
  for (gconn *c = p ? p->head : g->head; c; c = p ? c->pnext : c->next)
    if (c != self && !c->closing && (uploading ? c->uploading : c->waiting) &&
        now - c->since >= min_age)
      return c;
  return NULL;
}

/* Keeps the address of `c` within its quota and the pool under its soft limit, closing the
 * oldest connections still sending headers, and then the oldest still sending a body (an upload
 * trickled byte by byte would hold its slot as long as it likes). Returns 1 when the pool stays
 * over the soft limit (every other connection is busy with a request). */
static int make_room(srv_guard *g, gconn *self, peer *p, double now) {
  while (p && p->waiting > g->per_address) {
    gconn *v = oldest_waiting(g, p, self, now, GRACE_MS, 0);
    if (!v) break;
    evict(g, v, &g->over_quota);
  }
  while (g->live > g->soft_limit) {
    gconn *v = oldest_waiting(g, NULL, self, now, 0, 0);
    if (!v) v = oldest_waiting(g, NULL, self, now, 0, 1);
    if (!v) return 1;
    evict(g, v, &g->for_room);
  }
  return 0;
}

void *srv_guard_started(srv_guard *g, int fd, const struct sockaddr *addr) {
  if (!g) return NULL;
  gconn *c = calloc(1, sizeof *c);
  if (!c) return NULL;
  unsigned char key[16];
  int n = address_key(addr, key);
  pthread_mutex_lock(&g->mu);
  c->peer = peer_get(g, key, n);
  if (!c->peer) {
    pthread_mutex_unlock(&g->mu);
    free(c);
    return NULL;
  }
  c->fd = fd;
  c->waiting = 1;
  c->since = obs_now_ms();
  c->prev = g->tail;
  if (g->tail) g->tail->next = c;
  else g->head = c;
  g->tail = c;
  peer *p = c->peer;
  c->pprev = p->tail;
  if (p->tail) p->tail->pnext = c;
  else p->head = c;
  p->tail = c;
  p->waiting++;
  g->live++;
  make_room(g, c, p, c->since);
  pthread_mutex_unlock(&g->mu);
  return c;
}

int srv_guard_headers_done(srv_guard *g, void *ctx, int has_body) {
  gconn *c = ctx;
  if (!g || !c) return 0;
  pthread_mutex_lock(&g->mu);
  if (c->waiting && !c->closing) c->peer->waiting--;
  c->waiting = 0;
  c->uploading = has_body;
  c->received = 0;
  c->since = obs_now_ms();
  int busy = !c->closing && make_room(g, c, NULL, obs_now_ms());
  pthread_mutex_unlock(&g->mu);
  return busy;
}

void srv_guard_body_progress(srv_guard *g, void *ctx, size_t n) {
  gconn *c = ctx;
  if (!g || !c) return;
  pthread_mutex_lock(&g->mu);
  c->received += (int64_t)n;
  pthread_mutex_unlock(&g->mu);
}

void srv_guard_body_done(srv_guard *g, void *ctx) {
  gconn *c = ctx;
  if (!g || !c) return;
  pthread_mutex_lock(&g->mu);
  c->uploading = 0;
  pthread_mutex_unlock(&g->mu);
}

void srv_guard_request_done(srv_guard *g, void *ctx) {
  gconn *c = ctx;
  if (!g || !c) return;
  pthread_mutex_lock(&g->mu);
  c->uploading = 0;
  if (!c->waiting && !c->closing) {
    c->waiting = 1;
    c->since = obs_now_ms();
    c->peer->waiting++;
  }
  pthread_mutex_unlock(&g->mu);
}

void srv_guard_closed(srv_guard *g, void *ctx) {
  gconn *c = ctx;
  if (!g || !c) return;
  pthread_mutex_lock(&g->mu);
  if (!c->closing) {
    g->live--;
    if (c->waiting) c->peer->waiting--;
  }
  if (c->prev) c->prev->next = c->next;
  else g->head = c->next;
  if (c->next) c->next->prev = c->prev;
  else g->tail = c->prev;
  peer *p = c->peer;
  if (c->pprev) c->pprev->pnext = c->pnext;
  else p->head = c->pnext;
  if (c->pnext) c->pnext->pprev = c->pprev;
  else p->tail = c->pprev;
  if (!p->head) peer_drop(g, p);
  pthread_mutex_unlock(&g->mu);
  free(c);
}

int srv_guard_reserve(srv_guard *g, int64_t bytes) {
  if (!g) return 0;
  int64_t cur = atomic_load(&g->inflight);
  do {
    if (cur + bytes > g->max_inflight) return -1;
  } while (!atomic_compare_exchange_weak(&g->inflight, &cur, cur + bytes));
  return 0;
}

void srv_guard_release(srv_guard *g, int64_t bytes) {
  if (g && bytes) atomic_fetch_sub(&g->inflight, bytes);
}

int64_t srv_guard_inflight(srv_guard *g) { return g ? atomic_load(&g->inflight) : 0; }

/* One pass of the reaper: the header time as a whole, the pace of uploads, then quotas that grew
 * while connections were young. Returns what to log (a line, or ""). An upload has
 * --body-timeout plus one second per --min-body-rate bytes received, from the end of its headers:
 * a client trickling a byte now and then would otherwise hold its share of the in-flight budget
 * (the whole announced length) for as long as it likes, and four such held all of it. */
static void reap(srv_guard *g, char *line, size_t n) {
  double now = obs_now_ms();
  line[0] = '\0';
  for (gconn *c = g->head; c; c = c->next) {
    if (c->closing) continue;
    if (c->waiting && now - c->since > g->header_timeout_ms) {
      evict(g, c, &g->timed_out);
    } else if (c->uploading && now - c->since > g->body_timeout_ms +
                                                    1e3 * (double)c->received / g->min_body_rate) {
      evict(g, c, &g->too_slow);
      srv_refused("min-body-rate");
    }
  }
  for (int b = 0; b < BUCKETS; b++)
    for (peer *p = g->buckets[b]; p; p = p->next)
      if (p->waiting > g->per_address) make_room(g, NULL, p, now);
  make_room(g, NULL, NULL, now);
  unsigned long long total = g->timed_out + g->over_quota + g->for_room + g->too_slow;
  if (total != g->logged && now - g->last_log >= LOG_PERIOD_MS) {
    snprintf(line, n,
             "http: %llu connection(s) closed so far before completing their request: %llu "
             "after header-timeout, %llu over max-pending-per-address, %llu to keep room in "
             "max-connections, %llu uploading slower than body-timeout and min-body-rate allow",
             total, g->timed_out, g->over_quota, g->for_room, g->too_slow);
    g->logged = total;
    g->last_log = now;
  }
}

static void *reaper_main(void *arg) {
  srv_guard *g = arg;
  pthread_mutex_lock(&g->mu);
  while (!g->stop) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    ts.tv_nsec += REAP_PERIOD_MS * 1000000L;
    if (ts.tv_nsec >= 1000000000L) ts.tv_sec++, ts.tv_nsec -= 1000000000L;
    pthread_cond_timedwait(&g->cv, &g->mu, &ts);
    if (g->stop) break;
    char line[400];
    reap(g, line, sizeof line);
    if (line[0]) {
      pthread_mutex_unlock(&g->mu);
      srv_log("%s", line);
      pthread_mutex_lock(&g->mu);
    }
  }
  pthread_mutex_unlock(&g->mu);
  return NULL;
}

/* Every connection holds a descriptor: a soft limit below the connection limit would make
 * accept fail before the guard can make room. */
static void raise_fd_limit(int need) {
  struct rlimit rl;
  if (getrlimit(RLIMIT_NOFILE, &rl) || rl.rlim_cur == RLIM_INFINITY) return;
  if (rl.rlim_cur < rl.rlim_max) {
    rl.rlim_cur = rl.rlim_max;
    if (setrlimit(RLIMIT_NOFILE, &rl))
      srv_log("cannot raise the open-file limit to %llu: %s", (unsigned long long)rl.rlim_max,
              strerror(errno));
  }
  /* Said whether or not there was room to raise it. */
  if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY &&
      rl.rlim_cur < (rlim_t)need)
    srv_log("open-file limit %llu is below max-connections plus the daemon's own files (%d): "
            "raise it (ulimit -n) or lower --max-connections",
            (unsigned long long)rl.rlim_cur, need);
}

int srv_guard_reserve_slots(int max_connections) {
  int r = max_connections / 16;
  return r < 4 ? 4 : r > 64 ? 64 : r;
}

int srv_guard_create(const srv_config *cfg, srv_guard **out, obs_err *err) {
  *out = NULL;
  srv_guard *g = calloc(1, sizeof *g);
  if (!g) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  g->header_timeout_ms = cfg->header_timeout * 1e3;
  g->soft_limit = cfg->max_connections - srv_guard_reserve_slots(cfg->max_connections);
  g->per_address = cfg->max_pending_per_address;
  g->max_inflight = cfg->max_inflight;
  g->body_timeout_ms = cfg->body_timeout * 1e3;
  g->min_body_rate = (double)cfg->min_body_rate;
  g->last_log = -LOG_PERIOD_MS;
  atomic_init(&g->inflight, 0);
  pthread_condattr_t ca;
  pthread_condattr_init(&ca);
  pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
  pthread_mutex_init(&g->mu, NULL);
  pthread_cond_init(&g->cv, &ca);
  pthread_condattr_destroy(&ca);
  raise_fd_limit(cfg->max_connections + 64);
  if (pthread_create(&g->reaper, NULL, reaper_main, g)) {
    srv_guard_free(g);
    return obs_err_set(err, OBS_EIO, "cannot start the connection reaper thread");
  }
  g->reaper_started = 1;
  *out = g;
  return 0;
}

void srv_guard_free(srv_guard *g) {
  if (!g) return;
  if (g->reaper_started) {
    pthread_mutex_lock(&g->mu);
    g->stop = 1;
    pthread_cond_signal(&g->cv);
    pthread_mutex_unlock(&g->mu);
    pthread_join(g->reaper, NULL);
  }
  /* libmicrohttpd has stopped and reported every connection closed: nothing is left to free
   * but peers of connections it never reported (none in practice). */
  while (g->head) {
    gconn *c = g->head;
    g->head = c->next;
    free(c);
  }
  for (int b = 0; b < BUCKETS; b++)
    while (g->buckets[b]) {
      peer *p = g->buckets[b];
      g->buckets[b] = p->next;
      free(p);
    }
  pthread_cond_destroy(&g->cv);
  pthread_mutex_destroy(&g->mu);
  free(g);
}
