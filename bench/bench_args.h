/* Command-line helpers shared by the benchmark programs in bench/. */
#ifndef OBS_BENCH_ARGS_H
#define OBS_BENCH_ARGS_H

#include <stdlib.h>

/* Parses a whole decimal integer in [lo, hi] into *out; -1 (and *out untouched) otherwise. */
static inline int parse_int(const char *s, int lo, int hi, int *out) {
  char *end;
  long v = strtol(s, &end, 10);
  if (end == s || *end || v < lo || v > hi) return -1;
  *out = (int)v;
  return 0;
}

#endif
