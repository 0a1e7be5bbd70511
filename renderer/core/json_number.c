/* What JSON number tokens become once parsed, decided on the raw text: which ones jansson cannot
 * store (so the pre-scan can name them by pointer before the parser refuses them by line and
 * column), and which ones it stores as another value (a nonzero literal read as 0, an integer a
 * double cannot hold, a fraction read as a whole number), which the exact pre-scan refuses. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "json_util.h"

/* A number token split into its significant digits and decimal exponent: the value is
 * 0.d1d2...dn x 10^e10, or zero when n is 0. Beyond SIG_MAX digits only whether the tail is zero
 * can matter to rounding (the halfway point between DBL_MAX and the next power of two has 768
 * significant digits): a sticky 1 stands in for a nonzero tail. */
enum { SIG_MAX = 800 };
typedef struct num_text {
  int neg, real;       /* real: the token has '.', 'e' or 'E' */
  char digits[SIG_MAX + 2];
  size_t nd;           /* significant digits kept (sticky included) */
  size_t sig;          /* of those, up to the last nonzero one */
  long long e10;
  int whole;           /* the written value is a whole number */
} num_text;

/* 0 when t[0..n) is not a number token (the parser refuses those). */
static int split(const char *t, size_t n, num_text *x) {
  memset(x, 0, sizeof *x);
  size_t i = 0;
  x->neg = t[0] == '-';
  i += (size_t)x->neg;
  if (i >= n || !isdigit((unsigned char)t[i])) return 0;
  for (size_t k = i; k < n; k++) x->real |= t[k] == '.' || t[k] == 'e' || t[k] == 'E';
  long long lead = 0;  /* digits before the point, leading zeros dropped */
  long long zeros = 0; /* zeros after the point before the first significant digit */
  int seen = 0, point = 0, sticky = 0;
  for (; i < n && (isdigit((unsigned char)t[i]) || t[i] == '.'); i++) {
    if (t[i] == '.') {
      point = 1;
      continue;
    }
    if (!seen && t[i] == '0') {
      if (point) zeros++;
      continue;
    }
    seen = 1;
    if (!point) lead++;
    if (x->nd < SIG_MAX) x->digits[x->nd++] = t[i];
    else sticky |= t[i] != '0';
  }
  long long ex = 0;
  if (i < n && (t[i] == 'e' || t[i] == 'E')) {
    i++;
    int eneg = i < n && t[i] == '-';
    if (i < n && (t[i] == '-' || t[i] == '+')) i++;
    for (; i < n && isdigit((unsigned char)t[i]); i++)
      if (ex < 100000) ex = ex * 10 + (t[i] - '0');
    if (eneg) ex = -ex;
  }
  if (!seen) {
    x->whole = 1;
    return 1;
  }
  x->e10 = ex + (lead ? lead : -zeros);
  /* Whole when no significant digit (trailing zeros aside) falls after the point. */
  size_t last = x->nd;
  while (last && x->digits[last - 1] == '0') last--;
  x->whole = !sticky && (long long)last <= x->e10;
  if (sticky) x->digits[x->nd++] = '1';
  x->sig = sticky ? x->nd : last;
  return 1;
}

/* The double the token is read as (strtod is correctly rounded, and the shortened copy rounds the
 * same way thanks to the sticky digit). */
static double value_of(const num_text *x) {
  if (!x->nd) return x->neg ? -0.0 : 0.0;
  if (x->e10 > 400) return x->neg ? -INFINITY : INFINITY;
  if (x->e10 < -400) return x->neg ? -0.0 : 0.0;
  char buf[SIG_MAX + 48];
  snprintf(buf, sizeof buf, "%s0.%.*se%lld", x->neg ? "-" : "", (int)x->nd, x->digits, x->e10);
  return strtod(buf, NULL);
}

/* An integer token beyond json_int_t (64-bit: [-2^63, 2^63 - 1]). */
static int int_out_of_range(const num_text *x) {
  static const char lim[] = "9223372036854775807"; /* 2^63 - 1; -2^63 is one more */
  size_t ld = sizeof lim - 1;
  if (!x->nd) return 0;
  if (x->e10 != (long long)ld) return x->e10 > (long long)ld;
  char d[sizeof lim];
  memset(d, '0', ld);
  memcpy(d, x->digits, x->nd < ld ? x->nd : ld);
  int cmp = memcmp(d, lim, ld);
  return cmp > 0 && !(x->neg && !memcmp(d, "9223372036854775808", ld));
}

/* Whether the whole number written as x is exactly the (finite, whole) double d. */
static int whole_equals(const num_text *x, double d) {
  char exact[420];
  snprintf(exact, sizeof exact, "%.0f", fabs(d)); /* glibc prints a double's exact value */
  size_t len = strlen(exact);
  if (!x->nd) return d == 0;
  if ((long long)len != x->e10) return 0;
  for (size_t k = 0; k < len; k++)
    if (exact[k] != (k < x->nd ? x->digits[k] : '0')) return 0;
  return 1;
}

int obs_json_number_fault(const char *t, size_t n, int exact, double *read_as) {
  num_text x;
  if (read_as) *read_as = 0;
  if (!split(t, n, &x)) return OBS_JSON_NUMBER_OK;
  if (!x.real && int_out_of_range(&x)) return OBS_JSON_NUMBER_INT_RANGE;
  /* Reals: the decimal exponent of the first significant digit decides, strtod only near the
   * boundary. */
  if (x.real && x.nd && x.e10 > 309) return OBS_JSON_NUMBER_REAL_RANGE;
  if (x.real && x.nd && x.e10 >= 308 && isinf(value_of(&x))) return OBS_JSON_NUMBER_REAL_RANGE;
  if (!exact || !x.nd) return OBS_JSON_NUMBER_OK;
  /* Up to 15 significant digits at a moderate exponent, every number is itself: a double holds
   * 15 digits, so neither a whole number nor a fraction's distance to the next whole number (at
   * least one unit of its last digit) is lost. */
  if (x.sig <= 15 && x.e10 > -300 && x.e10 < 300) return OBS_JSON_NUMBER_OK;
  double d = value_of(&x);
  if (read_as) *read_as = d;
  /* Subnormals keep their sign and order (a camera's tiny up vector is still one); zero does
   * not. */
  if (d == 0) return OBS_JSON_NUMBER_UNDERFLOW;
  if (x.whole && !x.real && !whole_equals(&x, d)) return OBS_JSON_NUMBER_INEXACT;
  if (!x.whole && d == floor(d)) return OBS_JSON_NUMBER_ROUNDS_WHOLE;
  return OBS_JSON_NUMBER_OK;
}

const char *obs_json_number_fault_text(int fault) {
  switch (fault) {
    case OBS_JSON_NUMBER_INT_RANGE:
      return "integer outside the 64-bit range [-2^63, 2^63 - 1]";
    case OBS_JSON_NUMBER_REAL_RANGE:
      return "number too large for a double (beyond +-1.8e308)";
    case OBS_JSON_NUMBER_UNDERFLOW:
      return "nonzero number too small for a double (below 4.9e-324 in magnitude it becomes 0)";
    case OBS_JSON_NUMBER_INEXACT:
      return "integer a double cannot hold exactly (beyond 2^53 = 9007199254740992 only some "
             "are)";
    case OBS_JSON_NUMBER_ROUNDS_WHOLE:
      return "fraction that a double rounds to a whole number";
    default:
      return "number";
  }
}
