/* The instruction-set levels of the CPU code: which one this process runs (the CPU's best, capped
 * by OBSCURA_ISA), the attributes of the AVX2 kernels, and the dispatch of the hot tile kernels.
 *
 * The twins' per-pixel arithmetic is IEEE float32 operation for operation with the shaders, and
 * AVX2's add, mul, div, sqrt, floor and compares are the same correctly rounded operations per
 * lane, so a kernel that keeps the scalar code's order gives the same bits eight pixels at a time
 * (ISO C mode keeps -ffp-contract=off, so no multiply-add is fused behind our back, even in the
 * x86-64-v3 variants that may use FMA instructions). That is the contract of every level: the unit
 * tests run each level the CPU has and compare the bits.
 *
 * OBSCURA_ISA=sse2|avx2|native caps the level for the whole process (obscura's kernels and
 * Embree's, see obs_rt_build), so one machine can stand in for a CPU with less: a developer
 * measuring how an AVX2-only CPU fares runs with OBSCURA_ISA=avx2. OBSCURA_NO_SIMD=1 is the older
 * spelling of OBSCURA_ISA=sse2. Levels are plain `target` attributes picked at run time, not
 * target_clones, so every level also runs under the sanitizers. */
#ifndef OBS_SIMD_H
#define OBS_SIMD_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Ordered: a cap keeps every level at or below it. */
enum {
  OBS_ISA_SSE2 = 0,   /* the x86-64 baseline; scalar spans */
  OBS_ISA_AVX2 = 1,   /* x86-64-v3: AVX2 spans and tile kernels */
  OBS_ISA_AVX512 = 2, /* x86-64-v4: obscura runs its AVX2 code; Embree its AVX-512 kernels */
};

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
#define OBS_SIMD_AVX2 1
#include <immintrin.h>
#define OBS_AVX2_FN __attribute__((target("avx2")))
#define OBS_AVX2_INLINE static inline __attribute__((target("avx2"), always_inline))
/* base[idx[l]] for the 8 lanes l: vgatherdps, or (loads) eight scalar loads from indices taken
 * out 64 bits at a time. AMD's Zen 1 to 3 run vgatherdps as microcode, as do Intel's Skylake to
 * Tiger Lake under the 2023 gather-data-sampling fix, and there the loads win; on an unaffected
 * Intel CPU they cost the hbao AO pass ~1.25x (docs/performance.md). Same bits either way. */
OBS_AVX2_INLINE __m256 obs_avx2_gather(int loads, const float *base, __m256i idx) {
  if (!loads) return _mm256_i32gather_ps(base, idx, 4);
  const __m128i lo = _mm256_castsi256_si128(idx), hi = _mm256_extracti128_si256(idx, 1);
  const unsigned long long a = (unsigned long long)_mm_cvtsi128_si64(lo);
  const unsigned long long b = (unsigned long long)_mm_extract_epi64(lo, 1);
  const unsigned long long c = (unsigned long long)_mm_cvtsi128_si64(hi);
  const unsigned long long d = (unsigned long long)_mm_extract_epi64(hi, 1);
  return _mm256_setr_ps(base[(unsigned)a], base[a >> 32], base[(unsigned)b], base[b >> 32],
                        base[(unsigned)c], base[c >> 32], base[(unsigned)d], base[d >> 32]);
}

/* The x86-64-v3 variant of a tile kernel (OBS_TILE_KERNELS), limited to the features
 * obs_simd_cpu_isa checks (AVX2 and FMA): BMI2, LZCNT or MOVBE instructions in it would fault on a
 * CPU model (a VM's, an emulator's) that offers AVX2 and FMA but masks those. */
#define OBS_V3_FN __attribute__((target("avx2,fma")))

/* The CPU's best level. */
static inline int obs_simd_cpu_isa(void) {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512bw") &&
      __builtin_cpu_supports("avx512vl"))
    return OBS_ISA_AVX512;
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return OBS_ISA_AVX2;
  return OBS_ISA_SSE2;
}
#else
#define OBS_SIMD_AVX2 0
#define OBS_V3_FN
static inline int obs_simd_cpu_isa(void) { return OBS_ISA_SSE2; }
#endif

/* The cap OBSCURA_ISA (or OBSCURA_NO_SIMD) asks for; OBS_ISA_AVX512 when unset, "native" or not
 * understood. The one place these variables are read. */
static inline int obs_simd_isa_cap(void) {
  const char *off = getenv("OBSCURA_NO_SIMD");
  if (off && off[0] && !(off[0] == '0' && !off[1])) return OBS_ISA_SSE2;
  const char *isa = getenv("OBSCURA_ISA");
  if (isa && !strcmp(isa, "sse2")) return OBS_ISA_SSE2;
  if (isa && !strcmp(isa, "avx2")) return OBS_ISA_AVX2;
  return OBS_ISA_AVX512;
}

/* Whether the AVX2 spans take obs_avx2_gather's loads (1) or vgatherdps (0): OBSCURA_GATHER=loads
 * or hw, by default loads on AMD CPUs and where Linux reports the gather-data-sampling mitigation
 * as microcode, whose vgatherdps is slow. */
static inline int obs_simd_gather_loads(void) {
  const char *m = getenv("OBSCURA_GATHER");
  if (m && !strcmp(m, "loads")) return 1;
  if (m && !strcmp(m, "hw")) return 0;
#if OBS_SIMD_AVX2
  __builtin_cpu_init();
  if (__builtin_cpu_is("amd")) return 1;
#endif
  char buf[128] = "";
  FILE *f = fopen("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling", "r");
  if (f) {
    if (!fgets(buf, sizeof buf, f)) buf[0] = 0;
    fclose(f);
  }
  return strstr(buf, "Mitigation: Microcode") != NULL;
}

/* The level this process runs: the CPU's best, capped. Cheap enough to ask once per pass. */
static inline int obs_simd_isa(void) {
  int cpu = obs_simd_cpu_isa(), cap = obs_simd_isa_cap();
  return cpu < cap ? cpu : cap;
}

static inline const char *obs_simd_isa_name(int isa) {
  return isa >= OBS_ISA_AVX512 ? "avx512" : isa == OBS_ISA_AVX2 ? "avx2" : "sse2";
}

/* Whether this process may run the AVX2 spans. */
static inline int obs_simd_avx2(void) { return OBS_SIMD_AVX2 && obs_simd_isa() >= OBS_ISA_AVX2; }

/* Every dispatch path as its (OBSCURA_ISA, OBSCURA_GATHER) settings, the scalar reference first:
 * the unit tests compare them all bit for bit (a level the CPU lacks runs the best it has). */
#define OBS_SIMD_PATHS \
  {{"sse2", "hw"}, {"avx2", "hw"}, {"avx2", "loads"}, {"native", "hw"}, {"native", "loads"}}

/* Defines `static int name(void *user, int thread, int x0, int y0, int x1, int y1)` (an
 * obs_tile_fn) twice around the always-inline body `name##_body` of the same signature: a baseline
 * name##_base and an x86-64-v3 name##_v3, so the body's scalar code also gets roundss for floorf
 * and wider registers where the level allows. obs_simd_tile_pick chooses between them. */
#define OBS_TILE_KERNELS(name)                                                             \
  static int name##_base(void *user, int thread, int x0, int y0, int x1, int y1) {         \
    return name##_body(user, thread, x0, y0, x1, y1);                                      \
  }                                                                                        \
  OBS_V3_FN static int name##_v3(void *user, int thread, int x0, int y0, int x1, int y1) { \
    return name##_body(user, thread, x0, y0, x1, y1);                                      \
  }
#define obs_simd_tile_pick(name, isa) ((isa) >= OBS_ISA_AVX2 ? name##_v3 : name##_base)

#endif
