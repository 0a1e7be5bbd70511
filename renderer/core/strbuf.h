/* A growing text buffer for the generated documents (the registry's schema, OpenAPI and
 * Markdown copies, the ranges table): printf-style appends that remember a failure instead of
 * reporting each one. */
#ifndef OBS_STRBUF_H
#define OBS_STRBUF_H

#include <stddef.h>

typedef struct obs_strbuf {
  char *s; /* owned; NULL until the first append */
  size_t len, cap;
  int failed; /* an allocation or format failed: later appends do nothing */
} obs_strbuf;

/* Appends printf-style text. */
__attribute__((format(printf, 2, 3))) void obs_strbuf_put(obs_strbuf *b, const char *fmt, ...);
/* The text (the caller frees it), or NULL after a failure or when nothing was appended; the
 * buffer is empty again either way. */
char *obs_strbuf_finish(obs_strbuf *b);

#endif
