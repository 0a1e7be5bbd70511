/* Eight-pixel AVX2 kernels for the CPU twins: the compile-time switch, the function attribute and
 * the run-time check that picks them.
 *
 * The twins' per-pixel arithmetic is IEEE float32 operation for operation with the shaders, and
 * AVX2's add, mul, div, sqrt, floor and compares are the same correctly rounded operations per
 * lane, so a kernel that keeps the scalar code's order gives the same bits eight pixels at a time
 * (ISO C mode keeps -ffp-contract=off, so no multiply-add is fused behind our back). That is the
 * contract of every OBS_AVX2_FN kernel: the unit tests compare both paths bit for bit, and
 * OBSCURA_NO_SIMD=1 in the environment forces the scalar path (for those tests and for bisecting a
 * suspected SIMD fault). Unlike target_clones this is plain code, so it also runs under the
 * sanitizers. */
#ifndef OBS_SIMD_H
#define OBS_SIMD_H

#include <stdlib.h>

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
#define OBS_SIMD_AVX2 1
#include <immintrin.h>
#define OBS_AVX2_FN __attribute__((target("avx2")))
#define OBS_AVX2_INLINE static inline __attribute__((target("avx2"), always_inline))

/* Whether this process may run the AVX2 kernels: the CPU has AVX2 and OBSCURA_NO_SIMD is
 * unset or "0". Cheap enough to ask once per pass. */
static inline int obs_simd_avx2(void) {
  const char *off = getenv("OBSCURA_NO_SIMD");
  if (off && off[0] && !(off[0] == '0' && !off[1])) return 0;
  return __builtin_cpu_supports("avx2");
}
#else
#define OBS_SIMD_AVX2 0
static inline int obs_simd_avx2(void) { return 0; }
#endif

#endif
