/* Error codes and the growable error-message buffer every obscura function fills on failure. */
#ifndef OBSCURA_ERROR_H
#define OBSCURA_ERROR_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Every fallible function returns 0 or one of these (negative) codes. */
enum {
  OBS_OK = 0,
  OBS_EINVAL = -1,      /* bad input: document, parameter, argument */
  OBS_ENOMEM = -2,      /* allocation failed */
  OBS_EIO = -3,         /* file could not be read or written */
  OBS_ECANCELED = -4,   /* the caller's cancel flag was raised */
  OBS_EUNSUPPORTED = -5,/* backend or feature not available here */
  OBS_ENOTFOUND = -6,   /* named thing (technique, channel, file) does not exist */
  OBS_EINTERNAL = -7,   /* a library we call failed unexpectedly */
  OBS_ETRANSIENT = -8,  /* the environment failed (disk full, read-only, I/O error, database
                           busy): the same call may succeed once the fault is cleared */
  OBS_ECONFLICT = -9    /* the thing changed hands meanwhile (a job another node now holds):
                           the call was refused and changed nothing */
};

/* Accumulates one or more human-readable problems, one per line. A zeroed struct is a valid empty
 * buffer (OBS_ERR_INIT). The struct owns `text`; release it with obs_err_free. */
typedef struct obs_err {
  char *text;    /* NUL-terminated, lines separated by '\n'; NULL while empty */
  size_t len;
  size_t cap;
  int count;     /* number of problems added */
} obs_err;

#define OBS_ERR_INIT {0, 0, 0, 0}

/* Appends one problem (printf-style). Returns `code` so callers can `return obs_err_set(...)`. */
int obs_err_set(obs_err *err, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* Message text, "" when empty. Borrowed pointer, valid until the next call on `err`. */
const char *obs_err_message(const obs_err *err);
void obs_err_clear(obs_err *err);
/* Rewrites every occurrence of `from` in the messages as `to` (e.g. a scene directory's resolved
 * path as "", so that files are named as the scene names them, not where they lie). */
void obs_err_replace(obs_err *err, const char *from, const char *to);
void obs_err_free(obs_err *err);
/* Short name of a code ("invalid input", ...). Static string. */
const char *obs_strerror(int code);

#ifdef __cplusplus
}
#endif
#endif
