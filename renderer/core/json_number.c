/* Range of JSON number tokens: which ones jansson cannot store, found on the raw text so the
 * pre-scan can name them by pointer before the parser refuses them by line and column. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "json_util.h"

int obs_json_number_out_of_range(const char *t, size_t n) {
  size_t i = 0;
  int neg = t[0] == '-';
  i += neg;
  if (i >= n || !isdigit((unsigned char)t[i])) return 0;
  int real = 0;
  for (size_t k = i; k < n; k++) real |= t[k] == '.' || t[k] == 'e' || t[k] == 'E';
  if (!real) {
    static const char lim[] = "9223372036854775807"; /* 2^63 - 1; -2^63 is one more */
    while (i + 1 < n && t[i] == '0') i++;
    size_t nd = n - i, ld = sizeof lim - 1;
    for (size_t k = i; k < n; k++)
      if (!isdigit((unsigned char)t[k])) return 0;
    if (nd != ld) return nd > ld;
    int cmp = memcmp(t + i, lim, ld);
    return cmp > 0 && !(neg && !memcmp(t + i, "9223372036854775808", ld));
  }
  /* Reals: the decimal exponent of the first significant digit decides, strtod only near the
   * boundary, on a copy of at most SIG_MAX significant digits. The halfway point between DBL_MAX
   * and the next power of two has 768, so a tail beyond SIG_MAX digits can only matter through
   * whether it is zero: a sticky 1 stands in for a nonzero one. */
  long long lead = 0; /* digits before the point, leading zeros dropped */
  long long zeros = 0; /* zeros after the point before the first significant digit */
  int seen = 0, point = 0;
  enum { SIG_MAX = 800 };
  char digits[SIG_MAX + 2];
  size_t nd = 0;
  int sticky = 0;
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
    if (nd < SIG_MAX) digits[nd++] = t[i];
    else sticky |= t[i] != '0';
  }
  if (sticky) digits[nd++] = '1';
  if (!seen) return 0;
  long long ex = 0;
  if (i < n && (t[i] == 'e' || t[i] == 'E')) {
    i++;
    int eneg = i < n && t[i] == '-';
    if (i < n && (t[i] == '-' || t[i] == '+')) i++;
    for (; i < n && isdigit((unsigned char)t[i]); i++)
      if (ex < 100000) ex = ex * 10 + (t[i] - '0');
    if (eneg) ex = -ex;
  }
  /* The value is 0.d1d2... x 10^e10 with e10 = ex + lead (or ex - zeros after the point). */
  long long e10 = ex + (lead ? lead : -zeros);
  if (e10 <= 308) return 0;
  if (e10 > 309) return 2;
  char buf[SIG_MAX + 48];
  snprintf(buf, sizeof buf, "0.%.*se%lld", (int)nd, digits, e10);
  return isinf(strtod(buf, NULL)) ? 2 : 0;
}
