/* The compiler keeps the arithmetic the renderer's bit-for-bit promises rest on, under the
 * project's own flags: a float conversion rounds even where the vectorizer packs it with its
 * double source (GCC 12's SLP vectorizer at -O3 dropped it, so release and sanitizer builds gave
 * other bits: CMakeLists.txt turns that pass off), and no multiply-add is fused. */
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct toolchain_hit {
  double t, ng[3];
} toolchain_hit;

/* The shape that was miscompiled: a double rounded to float, the float read back into a double
 * sum and into a product, three components at a time. Opaque to interprocedural optimisation,
 * so the function itself is what runs (a copy specialised to its call's constants kept the
 * rounding). */
#if defined(__GNUC__) && !defined(__clang__)
#define TOOLCHAIN_OPAQUE __attribute__((noipa))
#else
#define TOOLCHAIN_OPAQUE __attribute__((noinline))
#endif
void obs_toolchain_round_and_sum(const toolchain_hit *h, int n, double sum[][3], double *scaled,
                                 double k);
TOOLCHAIN_OPAQUE void obs_toolchain_round_and_sum(const toolchain_hit *h, int n,
                                                           double sum[][3], double *scaled,
                                                           double k) {
  for (int i = 0; i < n; i++) {
    float ng[3];
    for (int c = 0; c < 3; c++) {
      ng[c] = (float)h[i].ng[c];
      sum[i][c] += ng[c];
    }
    for (int c = 0; c < 3; c++) scaled[3 * i + c] = ng[c] * k;
  }
}

static void test_float_rounding_kept(void **state) {
  (void)state;
  uint32_t seed = 12345;
  toolchain_hit h[64];
  for (int i = 0; i < 64; i++)
    for (int c = 0; c < 3; c++) h[i].ng[c] = obs_test_unit(&seed) * 2 - 1 + 1e-9 * (i + c);
  double sum[64][3], scaled[192];
  memset(sum, 0, sizeof sum);
  obs_toolchain_round_and_sum(h, 64, sum, scaled, 1.0);
  for (int i = 0; i < 64; i++)
    for (int c = 0; c < 3; c++) {
      double want = (double)(float)h[i].ng[c];
      assert_true(sum[i][c] == want);
      assert_true(scaled[3 * i + c] == want);
    }
}

/* a * b + c rounded twice: 1 + 2^-30 squared is 1 + 2^-29 + 2^-60, whose last term only a fused
 * multiply-add keeps. */
TOOLCHAIN_OPAQUE static double mul_add(double a, double b, double c) { return a * b + c; }

static void test_no_fused_multiply_add(void **state) {
  (void)state;
  const double a = 1.0 + 0x1p-30;
  assert_true(mul_add(a, a, -(1.0 + 0x1p-29)) == 0.0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_float_rounding_kept),
      cmocka_unit_test(test_no_fused_multiply_add),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
