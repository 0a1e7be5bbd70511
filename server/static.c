/* Static files of --web-dir (the dashboard): index.html for directories, no listings, and no way
 * out of the directory (no "..", no hidden segments, no symlinks leading outside); plus a fixed
 * allowlist of third-party files under /vendor/ taken from --vendor-dir (npm's node_modules). */
#include <fcntl.h>
#include <limits.h>
#include <microhttpd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

static const struct {
  const char *ext, *type;
} types[] = {
    {".html", "text/html; charset=utf-8"},
    {".js", "text/javascript; charset=utf-8"},
    {".mjs", "text/javascript; charset=utf-8"},
    {".css", "text/css; charset=utf-8"},
    {".json", "application/json"},
    {".svg", "image/svg+xml"},
    {".png", "image/png"},
    {".jpg", "image/jpeg"},
    {".jpeg", "image/jpeg"},
    {".gif", "image/gif"},
    {".webp", "image/webp"},
    {".ico", "image/x-icon"},
    {".txt", "text/plain; charset=utf-8"},
    {".map", "application/json"},
    {".wasm", "application/wasm"},
    {".woff2", "font/woff2"},
    {".yaml", "text/plain; charset=utf-8"},
};

static const char *content_type(const char *path) {
  const char *dot = strrchr(path, '.');
  const char *slash = strrchr(path, '/');
  if (!dot || (slash && dot < slash)) return "application/octet-stream";
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
    if (!strcasecmp(dot, types[i].ext)) return types[i].type;
  return "application/octet-stream";
}

/* Every segment must be a plain name: not empty-dot, not "..", not hidden, no backslash. */
static int path_ok(const char *p) {
  if (p[0] != '/' || strlen(p) > 1024 || strchr(p, '\\')) return 0;
  for (const char *s = p + 1; *s;) {
    const char *e = strchr(s, '/');
    size_t n = e ? (size_t)(e - s) : strlen(s);
    if (n > 0 && s[0] == '.') return 0;
    s += n;
    if (*s == '/') s++;
  }
  return 1;
}

static int not_found(srv_req *r) {
  return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "not found");
}

/* The only files served from --vendor-dir: URL path -> path inside it. node_modules holds far
 * more than the dashboard needs (and test tooling), so nothing else of it is reachable. */
static const struct {
  const char *url, *file;
} vendor_files[] = {
    {"/vendor/uplot/uPlot.iife.min.js", "uplot/dist/uPlot.iife.min.js"},
    {"/vendor/uplot/uPlot.min.css", "uplot/dist/uPlot.min.css"},
};

/* Serves root/rel when it resolves (symlinks included) to a regular file inside root. */
static int serve_inside(srv_req *r, const char *root, const char *rel) {
  char joined[PATH_MAX + 1100], real[PATH_MAX];
  snprintf(joined, sizeof joined, "%s/%s", root, rel);
  struct stat st;
  if (!root[0] || !realpath(joined, real) || !obs_path_is_inside(root, real) ||
      stat(real, &st) || !S_ISREG(st.st_mode))
    return not_found(r);
  int fd = open(real, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return not_found(r);
  struct MHD_Response *resp = MHD_create_response_from_fd64((uint64_t)st.st_size, fd);
  if (!resp) {
    close(fd);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "cannot serve the file");
  }
  MHD_add_response_header(resp, "Content-Type", content_type(real));
  /* The dashboard changes with the daemon; revalidating keeps a stale app.js from lingering. */
  MHD_add_response_header(resp, "Cache-Control", "no-cache");
  return srv_respond(r, MHD_HTTP_OK, resp);
}

int srv_static_serve(srv_req *r) {
  if (strcmp(r->method, "GET") && strcmp(r->method, "HEAD"))
    return srv_respond_method(r, "GET, HEAD");
  srv_app *app = r->app;
  /* /vendor/ belongs to the allowlist alone, whatever --web-dir holds. */
  if (!strncmp(r->path, "/vendor/", 8)) {
    for (size_t i = 0; i < sizeof vendor_files / sizeof vendor_files[0]; i++)
      if (!strcmp(r->path, vendor_files[i].url))
        return serve_inside(r, app->vendor_real, vendor_files[i].file);
    return not_found(r);
  }
  if (!path_ok(r->path)) return not_found(r);
  char rel[1100];
  size_t n = strlen(r->path);
  snprintf(rel, sizeof rel, "%s%s", r->path + 1, r->path[n - 1] == '/' ? "index.html" : "");
  return serve_inside(r, app->web_real, rel);
}
