/* Scrambled Sobol, rotated Halton and counter-based random 2D point streams. */
#include "sampling.h"

#include "simd.h"

/* Nested uniform (Owen) scrambling by hashing, Burley 2020 "Practical Hash-based Owen
 * Scrambling": keeps Sobol's stratification while decorrelating pixels. */
static uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
  x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
  x = ((x >> 4) & 0x0F0F0F0FU) | ((x & 0x0F0F0F0FU) << 4);
  x = ((x >> 8) & 0x00FF00FFU) | ((x & 0x00FF00FFU) << 8);
  return (x >> 16) | (x << 16);
}

static uint32_t laine_karras(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cU;
  x ^= x * 0xb82f1e52U;
  x ^= x * 0xc7afe638U;
  x ^= x * 0x8d22f6e6U;
  return x;
}

/* First two Sobol dimensions, generated directly in bit-reversed order so Owen scrambling costs
 * one reversal per dimension: dimension 0 reversed is the index itself; dimension 1 (primitive
 * polynomial x+1, direction numbers v_k = v_{k-1} ^ (v_{k-1} >> 1)) reversed has direction
 * numbers w_k = w_{k-1} ^ (w_{k-1} << 1). */
static uint32_t sobol1_reversed(uint32_t i) {
  uint32_t r = 0, w = 1;
  for (; i; i >>= 1, w ^= w << 1)
    r ^= w & (0u - (i & 1u)); /* branchless: the bits of a shuffled index are random */
  return r;
}

static float radical_inverse3(uint32_t i) {
  double inv = 1.0 / 3.0, f = inv, r = 0.0;
  while (i) {
    r += (double)(i % 3) * f;
    i /= 3;
    f *= inv;
  }
  return (float)r;
}

uint32_t obs_sample_shuffle(uint32_t index, uint32_t seed) {
  return reverse_bits(laine_karras(reverse_bits(index), seed));
}

void obs_sampler2d_init(obs_sampler2d *s, obs_sampler_kind kind, uint32_t x, uint32_t y,
                        uint32_t pixel_sample, uint32_t stream, uint32_t seed) {
  uint32_t h = obs_hash_combine(obs_hash_combine(obs_hash32(x), y), pixel_sample);
  h = obs_hash_combine(obs_hash_combine(h, stream), seed);
  s->kind = kind;
  s->scramble0 = h;
  s->scramble1 = obs_hash32(h ^ 0xa511e9b3U);
}

void obs_rqmc_init(obs_rqmc *q, obs_sampler_kind kind, uint32_t x, uint32_t y,
                   uint32_t pixel_sample, uint32_t stream, uint32_t seed, uint32_t n) {
  obs_rqmc_init_max(q, kind, x, y, pixel_sample, stream, seed, n, OBS_RQMC_REPLICATES);
}

void obs_rqmc_init_max(obs_rqmc *q, obs_sampler_kind kind, uint32_t x, uint32_t y,
                       uint32_t pixel_sample, uint32_t stream, uint32_t seed, uint32_t n,
                       uint32_t max) {
  obs_sampler2d_init(&q->s[0], kind, x, y, pixel_sample, stream, seed);
  q->n = n;
  if (max > OBS_RQMC_MAX) max = OBS_RQMC_MAX;
  q->reps = kind == OBS_SAMPLER_RANDOM ? (n ? n : 1) : n < max ? (n ? n : 1) : max;
  if (kind == OBS_SAMPLER_RANDOM) return;
  /* Replicate r > 0: the stream's seeds hashed with r, an independent scramble. */
  for (uint32_t r = 1; r < q->reps; r++) {
    q->s[r].kind = kind;
    q->s[r].scramble0 = obs_hash_combine(q->s[0].scramble0, 0x51ed270bU + r);
    q->s[r].scramble1 = obs_hash32(q->s[r].scramble0 ^ 0xa511e9b3U);
  }
}

uint32_t obs_rqmc_locate(const obs_rqmc *q, uint32_t i, uint32_t *j) {
  if (q->s[0].kind == OBS_SAMPLER_RANDOM) {
    *j = i;
    return 0;
  }
  uint32_t base = q->n / q->reps, extra = q->n % q->reps, big = extra * (base + 1);
  if (i < big) {
    *j = i % (base + 1);
    return i / (base + 1);
  }
  *j = (i - big) % base;
  return extra + (i - big) / base;
}

int obs_rqmc_get(const obs_rqmc *q, uint32_t i, float *u, float *v) {
  uint32_t j, r = obs_rqmc_locate(q, i, &j);
  obs_sampler2d_get(&q->s[r], j, u, v);
  return q->s[0].kind == OBS_SAMPLER_RANDOM || i + 1 == obs_rqmc_first(q, r + 1);
}

void obs_rqmc_get_n(const obs_rqmc *q, uint32_t i0, uint32_t m, float *u, float *v, int isa) {
  if (q->s[0].kind == OBS_SAMPLER_RANDOM) {
    obs_sampler2d_get_n(&q->s[0], i0, m, u, v, isa);
    return;
  }
  for (uint32_t k = 0; k < m;) {
    uint32_t j, r = obs_rqmc_locate(q, i0 + k, &j), end = obs_rqmc_first(q, r + 1) - i0;
    uint32_t len = (end < m ? end : m) - k;
    obs_sampler2d_get_n(&q->s[r], j, len, u + k, v + k, isa);
    k += len;
  }
}

#if OBS_SIMD_AVX2
OBS_AVX2_INLINE __m256i reverse_bits8(__m256i x) {
  static const uint32_t m[4] = {0x55555555U, 0x33333333U, 0x0F0F0F0FU, 0x00FF00FFU};
  for (int k = 0; k < 4; k++) {
    __m256i mk = _mm256_set1_epi32((int)m[k]);
    int sh = 1 << k;
    x = _mm256_or_si256(_mm256_and_si256(_mm256_srli_epi32(x, sh), mk),
                        _mm256_slli_epi32(_mm256_and_si256(x, mk), sh));
  }
  return _mm256_or_si256(_mm256_srli_epi32(x, 16), _mm256_slli_epi32(x, 16));
}

OBS_AVX2_INLINE __m256i laine_karras8(__m256i x, uint32_t seed) {
  static const uint32_t c[4] = {0x6c50b47cU, 0xb82f1e52U, 0xc7afe638U, 0x8d22f6e6U};
  x = _mm256_add_epi32(x, _mm256_set1_epi32((int)seed));
  for (int k = 0; k < 4; k++)
    x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, _mm256_set1_epi32((int)c[k])));
  return x;
}

OBS_AVX2_INLINE __m256 unit8(__m256i x) {
  return _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(x, 8)), _mm256_set1_ps(0x1p-24f));
}

/* obs_sampler2d_get's Sobol points eight lanes at a time, with its integer operations: the
 * reversed second dimension takes as many rounds as the largest index has bits (a lane's missing
 * bits add nothing). Returns how many points it wrote (whole groups of eight). */
OBS_V3_FN static uint32_t sobol8_v3(const obs_sampler2d *s, uint32_t i0, uint32_t n, float *u,
                                    float *v) {
  uint32_t k = 0;
  for (; k + 8 <= n; k += 8) {
    uint32_t top = i0 + k + 7 < i0 + k ? UINT32_MAX : i0 + k + 7, rounds = 0;
    while (rounds < 32 && top >> rounds) rounds++;
    __m256i i = _mm256_add_epi32(_mm256_set1_epi32((int)(i0 + k)),
                                 _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    __m256i r = _mm256_setzero_si256(), one = _mm256_set1_epi32(1);
    uint32_t w = 1;
    for (uint32_t b = 0; b < rounds; b++, w ^= w << 1) {
      __m256i bit = _mm256_and_si256(_mm256_srli_epi32(i, (int)b), one);
      __m256i mask = _mm256_sub_epi32(_mm256_setzero_si256(), bit);
      r = _mm256_xor_si256(r, _mm256_and_si256(_mm256_set1_epi32((int)w), mask));
    }
    _mm256_storeu_ps(u + k, unit8(reverse_bits8(laine_karras8(i, s->scramble0))));
    _mm256_storeu_ps(v + k, unit8(reverse_bits8(laine_karras8(r, s->scramble1))));
  }
  return k;
}
#endif

void obs_sampler2d_get_n(const obs_sampler2d *s, uint32_t i0, uint32_t n, float *u, float *v,
                         int isa) {
  uint32_t k = 0;
#if OBS_SIMD_AVX2
  if (s->kind == OBS_SAMPLER_SOBOL && isa >= OBS_ISA_AVX2) k = sobol8_v3(s, i0, n, u, v);
#endif
  (void)isa;
  for (; k < n; k++) obs_sampler2d_get(s, i0 + k, &u[k], &v[k]);
}

void obs_sampler2d_get(const obs_sampler2d *s, uint32_t i, float *u, float *v) {
  switch (s->kind) {
    case OBS_SAMPLER_SOBOL:
      /* owen(x) = reverse(laine_karras(reverse(x))), and reverse(sobol_d(i)) is generated
       * directly. */
      *u = obs_u32_to_unit(reverse_bits(laine_karras(i, s->scramble0)));
      *v = obs_u32_to_unit(reverse_bits(laine_karras(sobol1_reversed(i), s->scramble1)));
      return;
    case OBS_SAMPLER_HALTON: {
      /* Cranley-Patterson rotation per stream. */
      float a = (float)((double)reverse_bits(i) * 0x1p-32) + obs_u32_to_unit(s->scramble0);
      float b = radical_inverse3(i) + obs_u32_to_unit(s->scramble1);
      a -= a >= 1.0f ? 1.0f : 0.0f;
      b -= b >= 1.0f ? 1.0f : 0.0f;
      /* Rounding can land exactly on 1 after the wrap; keep [0,1). */
      *u = a < 1.0f ? a : 0x1.fffffep-1f;
      *v = b < 1.0f ? b : 0x1.fffffep-1f;
      return;
    }
    default:
      *u = obs_u32_to_unit(obs_hash_combine(s->scramble0, i));
      *v = obs_u32_to_unit(obs_hash_combine(s->scramble1, i));
      return;
  }
}
