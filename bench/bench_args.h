/* Command-line and statistics helpers shared by the benchmark programs in bench/. */
#ifndef OBS_BENCH_ARGS_H
#define OBS_BENCH_ARGS_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* What a command-line option takes. */
typedef enum bench_kind {
  BENCH_INT,    /* a whole number in [lo, hi] into *(int *)dst */
  BENCH_LIST,   /* 1 to cap comma-separated whole numbers in [lo, hi] into (int *)dst, *count;
                 * with empty_ok, "" is a list of none */
  BENCH_REAL,   /* a number in [lo, hi] into *(double *)dst; `open` makes an end exclusive */
  BENCH_STR,    /* the value itself into *(const char **)dst */
  BENCH_STR0,   /* likewise, but "none" stores NULL */
  BENCH_NAMES,  /* 1 to cap comma-separated names into (const char **)dst, *count (empty_ok as
                 * for BENCH_LIST) */
  BENCH_FLAG,   /* no value: sets *(int *)dst to 1 */
  BENCH_CUSTOM, /* the value handed to parse(v, dst), which returns 0 or -1 */
} bench_kind;

enum { BENCH_OPEN_LO = 1, BENCH_OPEN_HI = 2 };

/* One option of a benchmark: the table of these is the only place its name and bounds live. */
typedef struct bench_opt {
  const char *name; /* "--threads" */
  bench_kind kind;
  double lo, hi;
  void *dst;
  int *count, cap, empty_ok; /* BENCH_LIST, BENCH_NAMES */
  int open;                  /* BENCH_REAL: BENCH_OPEN_LO / BENCH_OPEN_HI */
  int (*parse)(const char *v, void *dst);
  const char *want; /* BENCH_CUSTOM: what the value should look like, for the message */
} bench_opt;

#define BENCH_OPT_INT(n, l, h, d) \
  { .name = (n), .kind = BENCH_INT, .lo = (l), .hi = (h), .dst = (d) }
#define BENCH_OPT_LIST(n, l, h, d, c, cp) \
  { .name = (n), .kind = BENCH_LIST, .lo = (l), .hi = (h), .dst = (d), .count = (c), .cap = (cp) }
#define BENCH_OPT_LIST0(n, l, h, d, c, cp)                                                        \
  {                                                                                               \
    .name = (n), .kind = BENCH_LIST, .lo = (l), .hi = (h), .dst = (d), .count = (c), .cap = (cp), \
    .empty_ok = 1                                                                                 \
  }
#define BENCH_OPT_REAL(n, l, h, op, d) \
  { .name = (n), .kind = BENCH_REAL, .lo = (l), .hi = (h), .open = (op), .dst = (d) }
#define BENCH_OPT_STR(n, d) \
  { .name = (n), .kind = BENCH_STR, .dst = (d) }
#define BENCH_OPT_STR0(n, d) \
  { .name = (n), .kind = BENCH_STR0, .dst = (d) }
#define BENCH_OPT_NAMES(n, d, c, cp, e) \
  { .name = (n), .kind = BENCH_NAMES, .dst = (d), .count = (c), .cap = (cp), .empty_ok = (e) }
#define BENCH_OPT_FLAG(n, d) \
  { .name = (n), .kind = BENCH_FLAG, .dst = (d) }
#define BENCH_OPT_CUSTOM(n, fn, w, d) \
  { .name = (n), .kind = BENCH_CUSTOM, .parse = (fn), .want = (w), .dst = (d) }

/* Reads one value for `o`; prints why it is refused and returns -1 when it is. */
static inline int bench_opt_value(const char *prog, const bench_opt *o, const char *v) {
  /* Only whole-number kinds convert their bounds: a real bound may be out of int's range. */
  int whole = o->kind == BENCH_INT || o->kind == BENCH_LIST;
  int lo = whole ? (int)o->lo : 0, hi = whole ? (int)o->hi : 0;
  switch (o->kind) {
    case BENCH_INT:
      if (!parse_int(v, lo, hi, (int *)o->dst)) return 0;
      fprintf(stderr, "%s: %s %s: want a whole number from %d to %d\n", prog, o->name, v, lo, hi);
      return -1;
    case BENCH_LIST: {
      /* One more slot than the list holds, so that a list too long is refused, not cut. */
      int tmp[256], n = o->cap < 256 ? parse_list(v, tmp, o->cap + 1, lo, hi) : -1;
      if (n >= (o->empty_ok ? 0 : 1) && n <= o->cap) {
        memcpy(o->dst, tmp, (size_t)n * sizeof *tmp);
        *o->count = n;
        return 0;
      }
      fprintf(stderr, "%s: %s %s: want %d to %d comma-separated whole numbers from %d to %d\n",
              prog, o->name, v, o->empty_ok ? 0 : 1, o->cap, lo, hi);
      return -1;
    }
    case BENCH_REAL: {
      char *end;
      double x = strtod(v, &end);
      int ok = end != v && !*end && (o->open & BENCH_OPEN_LO ? x > o->lo : x >= o->lo) &&
               (o->open & BENCH_OPEN_HI ? x < o->hi : x <= o->hi);
      if (ok) {
        *(double *)o->dst = x;
        return 0;
      }
      fprintf(stderr, "%s: %s %s: want a number in %c%g, %g%c\n", prog, o->name, v,
              o->open & BENCH_OPEN_LO ? '(' : '[', o->lo, o->hi,
              o->open & BENCH_OPEN_HI ? ')' : ']');
      return -1;
    }
    case BENCH_STR:
      *(const char **)o->dst = v;
      return 0;
    case BENCH_STR0:
      *(const char **)o->dst = strcmp(v, "none") ? v : NULL;
      return 0;
    case BENCH_NAMES: {
      /* The names point into a copy of the value, which lives as long as the program. */
      static char pool[4096];
      static size_t used;
      size_t len = strlen(v) + 1;
      int n = 0;
      if (len <= sizeof pool - used) {
        char *copy = memcpy(pool + used, v, len), *save = NULL;
        used += len;
        for (char *t = strtok_r(copy, ",", &save); t && n <= o->cap; t = strtok_r(NULL, ",", &save))
          if (n++ < o->cap) ((const char **)o->dst)[n - 1] = t;
        if (n >= (o->empty_ok ? 0 : 1) && n <= o->cap) {
          *o->count = n;
          return 0;
        }
      }
      fprintf(stderr, "%s: %s %s: want %d to %d comma-separated names\n", prog, o->name, v,
              o->empty_ok ? 0 : 1, o->cap);
      return -1;
    }
    case BENCH_CUSTOM:
      if (!o->parse(v, o->dst)) return 0;
      fprintf(stderr, "%s: %s %s: want %s\n", prog, o->name, v, o->want);
      return -1;
    case BENCH_FLAG:
      break;
  }
  return -1;
}

/* Parses argv against opts[0..n): --help / -h prints usage(stdout) and exits 0; an unknown
 * option, a missing value or one out of bounds prints a message naming it and usage(stderr) and
 * returns -1 (the benchmarks then exit 2); 0 when all were read. */
static inline int bench_parse_opts(int argc, char **argv, const bench_opt *opts, int n,
                                   void (*usage)(FILE *)) {
  const char *prog = strrchr(argv[0], '/') ? strrchr(argv[0], '/') + 1 : argv[0];
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage(stdout);
      exit(0);
    }
    const bench_opt *o = NULL;
    for (int k = 0; k < n && !o; k++)
      if (!strcmp(a, opts[k].name)) o = &opts[k];
    if (!o) {
      fprintf(stderr, "%s: unknown option '%s'\n", prog, a);
    } else if (o->kind == BENCH_FLAG) {
      *(int *)o->dst = 1;
      continue;
    } else if (i + 1 >= argc) {
      fprintf(stderr, "%s: %s needs a value\n", prog, a);
    } else if (!bench_opt_value(prog, o, argv[++i])) {
      continue;
    }
    usage(stderr);
    return -1;
  }
  return 0;
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
