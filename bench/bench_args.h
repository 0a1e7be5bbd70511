/* Command-line and statistics helpers shared by the benchmark programs in bench/. */
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

/* Parses a comma-separated list of integers in [lo, hi] into out[0..max); returns how many, or
 * -1 when one is not such an integer. */
static inline int parse_list(const char *s, int *out, int max, int lo, int hi) {
  int n = 0;
  for (const char *p = s; *p && n < max;) {
    char *end;
    long v = strtol(p, &end, 10);
    if (end == p || (*end && *end != ',') || v < lo || v > hi) return -1;
    out[n++] = (int)v;
    p = *end ? end + 1 : end;
  }
  return n;
}

static inline int bench_cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Median of v[0..n) (n >= 1); sorts v in place. */
static inline double bench_median(double *v, int n) {
  qsort(v, (size_t)n, sizeof *v, bench_cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

#endif
