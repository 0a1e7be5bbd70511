/* Scrambled Sobol, rotated Halton and counter-based random 2D point streams. */
#include "sampling.h"

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
