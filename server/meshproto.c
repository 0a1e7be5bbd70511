/* The pipe protocol between obscurad and its mesh-import worker (framing in meshimport.h). The
 * daemon side trusts nothing the worker sends: a worker that assimp has corrupted may write any
 * bytes, so sizes are checked before allocating and every index and coordinate after reading. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "meshimport.h"

static int write_all(int fd, const void *buf, size_t n) {
  const char *p = buf;
  while (n) {
    ssize_t w = write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return -1;
    p += w;
    n -= (size_t)w;
  }
  return 0;
}

/* The worker links this file too and needs nothing else of the renderer's clock. */
static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* Reads exactly n bytes: 0; SRV_MESH_REPLY_EOF; SRV_MESH_REPLY_TIMEOUT (deadline_ms > 0 only). */
static int read_full(int fd, void *buf, size_t n, double deadline_ms) {
  char *p = buf;
  while (n) {
    if (deadline_ms > 0) {
      double left = deadline_ms - now_ms();
      if (left <= 0) return SRV_MESH_REPLY_TIMEOUT;
      struct pollfd pf = {.fd = fd, .events = POLLIN};
      int pr = poll(&pf, 1, left > 1 ? (int)left : 1);
      if (pr < 0 && errno == EINTR) continue;
      if (pr < 0) return SRV_MESH_REPLY_EOF;
      if (pr == 0) continue; /* the loop re-reads the clock */
    }
    ssize_t r = read(fd, p, n);
    if (r < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (r <= 0) return SRV_MESH_REPLY_EOF;
    p += r;
    n -= (size_t)r;
  }
  return 0;
}

int srv_meshproto_write_request(int fd, const char *path, const char *root,
                                uint64_t max_triangles) {
  size_t pl = strlen(path), rl = strlen(root);
  if (pl > SRV_MESH_MAX_PATH || rl > SRV_MESH_MAX_PATH) {
    errno = ENAMETOOLONG;
    return -1;
  }
  /* One write, so a request is never half in the pipe when the worker dies. */
  char buf[20 + 2 * SRV_MESH_MAX_PATH];
  uint32_t h[3] = {SRV_MESH_MAGIC, (uint32_t)pl, (uint32_t)rl};
  memcpy(buf, h, 12);
  memcpy(buf + 12, &max_triangles, 8);
  memcpy(buf + 20, path, pl);
  memcpy(buf + 20 + pl, root, rl);
  return write_all(fd, buf, 20 + pl + rl);
}

int srv_meshproto_read_request(int fd, char *path, char *root, uint64_t *max_triangles) {
  uint32_t h[3];
  char *p = (char *)h;
  size_t got = 0;
  while (got < sizeof h) {
    ssize_t r = read(fd, p + got, sizeof h - got);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return got == 0 ? 1 : -1;
    got += (size_t)r;
  }
  if (h[0] != SRV_MESH_MAGIC || h[1] > SRV_MESH_MAX_PATH || h[2] > SRV_MESH_MAX_PATH) return -1;
  if (read_full(fd, max_triangles, 8, 0) || read_full(fd, path, h[1], 0) ||
      read_full(fd, root, h[2], 0))
    return -1;
  path[h[1]] = '\0';
  root[h[2]] = '\0';
  return 0;
}

int srv_meshproto_write_mesh(int fd, const obs_mesh *m) {
  uint32_t h[2] = {SRV_MESH_MAGIC, 0};
  uint64_t counts[2] = {m->nverts, m->ntris};
  uint32_t normals = m->nrm != NULL;
  if (write_all(fd, h, sizeof h) || write_all(fd, counts, sizeof counts) ||
      write_all(fd, &normals, sizeof normals) ||
      write_all(fd, m->pos, m->nverts * 3 * sizeof(float)) ||
      (m->nrm && write_all(fd, m->nrm, m->nverts * 3 * sizeof(float))) ||
      write_all(fd, m->idx, m->ntris * 3 * sizeof(uint32_t)))
    return -1;
  return 0;
}

int srv_meshproto_write_error(int fd, int code, const char *msg) {
  size_t n = strlen(msg);
  if (n > SRV_MESH_MAX_MSG) n = SRV_MESH_MAX_MSG;
  int32_t c = code < 0 ? code : OBS_EINVAL;
  uint32_t h[3] = {SRV_MESH_MAGIC, 0, (uint32_t)n};
  memcpy(&h[1], &c, sizeof c);
  return write_all(fd, h, sizeof h) || write_all(fd, msg, n) ? -1 : 0;
}

static int bad(char *msg, size_t n, const char *what) {
  snprintf(msg, n, "%s", what);
  return SRV_MESH_REPLY_BAD;
}

/* Floats of a mesh that must all be finite (the worker already maps non-finite ones to 0). */
static int all_finite(const float *v, size_t n) {
  for (size_t i = 0; i < n; i++)
    if (!isfinite(v[i])) return 0;
  return 1;
}

int srv_meshproto_read_reply(int fd, double timeout_ms, const srv_mesh_limits *lim, obs_mesh *m,
                             int *code, char *msg, size_t n) {
  double deadline_ms = now_ms() + (timeout_ms > 0 ? timeout_ms : 1);
  memset(m, 0, sizeof *m);
  msg[0] = '\0';
  uint32_t h[2];
  int rc = read_full(fd, h, sizeof h, deadline_ms);
  if (rc) return rc;
  if (h[0] != SRV_MESH_MAGIC) return bad(msg, n, "wrong magic number");
  int32_t status;
  memcpy(&status, &h[1], sizeof status);
  if (status < 0) {
    uint32_t len;
    if ((rc = read_full(fd, &len, sizeof len, deadline_ms))) return rc;
    if (len > SRV_MESH_MAX_MSG) return bad(msg, n, "error message too long");
    char text[SRV_MESH_MAX_MSG + 1];
    if ((rc = read_full(fd, text, len, deadline_ms))) return rc;
    text[len] = '\0';
    for (char *c = text; *c; c++)
      if ((unsigned char)*c < 0x20) *c = ' ';
    snprintf(msg, n, "%s", text);
    *code = status;
    return SRV_MESH_REPLY_ERROR;
  }
  if (status != 0) return bad(msg, n, "unknown status");
  uint64_t counts[2];
  uint32_t normals;
  if ((rc = read_full(fd, counts, sizeof counts, deadline_ms)) ||
      (rc = read_full(fd, &normals, sizeof normals, deadline_ms)))
    return rc;
  if (normals > 1) return bad(msg, n, "bad normals flag");
  if (counts[0] == 0 || counts[1] == 0) return bad(msg, n, "empty mesh");
  if (counts[1] > lim->max_triangles || counts[0] > lim->max_vertices ||
      counts[0] > UINT32_MAX) {
    snprintf(msg, n, "%llu vertices and %llu triangles, beyond the limit of %llu and %llu",
             (unsigned long long)counts[0], (unsigned long long)counts[1],
             (unsigned long long)lim->max_vertices, (unsigned long long)lim->max_triangles);
    return SRV_MESH_REPLY_BAD;
  }
  size_t nv = (size_t)counts[0], nt = (size_t)counts[1];
  m->pos = malloc(nv * 3 * sizeof(float));
  m->nrm = normals ? malloc(nv * 3 * sizeof(float)) : NULL;
  m->idx = malloc(nt * 3 * sizeof(uint32_t));
  m->nverts = nv;
  m->ntris = nt;
  if (!m->pos || !m->idx || (normals && !m->nrm)) {
    obs_geometry_mesh_free(m);
    return bad(msg, n, "out of memory for the mesh");
  }
  if ((rc = read_full(fd, m->pos, nv * 3 * sizeof(float), deadline_ms)) ||
      (normals && (rc = read_full(fd, m->nrm, nv * 3 * sizeof(float), deadline_ms))) ||
      (rc = read_full(fd, m->idx, nt * 3 * sizeof(uint32_t), deadline_ms))) {
    obs_geometry_mesh_free(m);
    return rc;
  }
  const char *why = NULL;
  if (!all_finite(m->pos, nv * 3) || (m->nrm && !all_finite(m->nrm, nv * 3)))
    why = "non-finite coordinates";
  for (size_t i = 0; !why && i < nt * 3; i++)
    if (m->idx[i] >= nv) why = "a vertex index out of range";
  if (why) {
    obs_geometry_mesh_free(m);
    return bad(msg, n, why);
  }
  return SRV_MESH_REPLY_MESH;
}
