/* File-system paths: the project's one containment check and one mkdir -p, shared by the
 * renderer (scene files, mesh imports, output directories) and the server (scenes, static files,
 * data directories). */
#ifndef OBSCURA_PATH_H
#define OBSCURA_PATH_H

#include "obscura/error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Whether `path` is `dir` itself or lies below it. Purely lexical: resolve both with realpath()
 * first, so that symlinks and ".." cannot lead out. Trailing slashes on either are ignored, "/"
 * contains every absolute path, and a sibling that merely shares the prefix ("/a/bc" against
 * "/a/b") is outside. An empty or NULL argument contains nothing and is inside nothing. */
int obs_path_is_inside(const char *dir, const char *path);

/* Creates `dir` and any missing parents, like mkdir -p (mode 0755 before the umask). An existing
 * directory is fine; an existing non-directory, at the end or on the way, is an error naming it.
 * Returns 0 or a negative OBS_E* code with the message in err (may be NULL); on failure errno is
 * the failing call's, so callers can explain EACCES or EROFS. */
int obs_path_make_dirs(const char *dir, obs_err *err);

/* Names the files under `dir` in err's messages relative to it, as a scene names them: every
 * "<dir>/" (as given and as resolved) is removed. A render's or a scene's problems then never
 * show where the scene's tree lies on this machine (a server would reveal its directories). */
void obs_path_err_relative(obs_err *err, const char *dir);

#ifdef __cplusplus
}
#endif
#endif
