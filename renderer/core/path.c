/* The containment check and mkdir -p of obscura/path.h. */
#include "obscura/path.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int obs_path_is_inside(const char *dir, const char *path) {
  if (!dir || !path || !*dir || !*path) return 0;
  size_t n = strlen(dir);
  while (n > 1 && dir[n - 1] == '/') n--;
  if (n == 1 && dir[0] == '/') return path[0] == '/';
  if (strncmp(dir, path, n)) return 0;
  /* Past the prefix: the end, or a separator (trailing slashes included) starting the child. */
  return path[n] == '\0' || path[n] == '/';
}

/* Sets err from the failing call's errno and leaves errno as it was. */
static int fail(obs_err *err, int code, const char *fmt, const char *path) {
  int e = errno;
  obs_err_set(err, code, fmt, path, strerror(e));
  errno = e;
  return code;
}

int obs_path_make_dirs(const char *dir, obs_err *err) {
  char buf[PATH_MAX];
  if (!dir || !*dir) {
    errno = EINVAL;
    return obs_err_set(err, OBS_EINVAL, "directory path must not be empty");
  }
  size_t len = strlen(dir);
  if (len >= sizeof buf) {
    errno = ENAMETOOLONG;
    return obs_err_set(err, OBS_EINVAL, "%s: path too long", dir);
  }
  memcpy(buf, dir, len + 1);
  for (char *p = buf + 1;; p++) {
    if (*p == '/' || *p == '\0') {
      char c = *p;
      *p = '\0';
      if (mkdir(buf, 0755) && errno != EEXIST)
        return fail(err, OBS_EIO, "%s: cannot create directory: %s", buf);
      *p = c;
      if (!c) break;
    }
  }
  struct stat st;
  if (stat(buf, &st)) return fail(err, OBS_EIO, "%s: cannot create directory: %s", buf);
  if (!S_ISDIR(st.st_mode)) {
    errno = ENOTDIR;
    return obs_err_set(err, OBS_EIO, "%s: exists and is not a directory", buf);
  }
  return OBS_OK;
}

void obs_path_err_relative(obs_err *err, const char *dir) {
  if (!err || !err->count || !dir || !*dir) return;
  char real[PATH_MAX], with_slash[PATH_MAX + 2];
  const char *forms[2] = {realpath(dir, real) ? real : NULL, dir};
  for (int i = 0; i < 2; i++) {
    if (!forms[i] || !strcmp(forms[i], "/") || (i == 1 && forms[0] && !strcmp(forms[0], dir)))
      continue;
    size_t n = strlen(forms[i]);
    while (n > 1 && forms[i][n - 1] == '/') n--;
    if ((size_t)snprintf(with_slash, sizeof with_slash, "%.*s/", (int)n, forms[i]) >=
        sizeof with_slash)
      continue;
    obs_err_replace(err, with_slash, "");
  }
}
