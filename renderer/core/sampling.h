/* Deterministic sample generation: every value depends only on (pixel, sample index, seed), so
 * images are bit-identical whatever the thread count or tile order. */
#ifndef OBS_SAMPLING_H
#define OBS_SAMPLING_H

#include <math.h>
#include <stdint.h>

typedef enum { OBS_SAMPLER_SOBOL, OBS_SAMPLER_HALTON, OBS_SAMPLER_RANDOM } obs_sampler_kind;

/* 32-bit integer hash with good avalanche (Wellons' lowbias32). */
static inline uint32_t obs_hash32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

static inline uint32_t obs_hash_combine(uint32_t a, uint32_t b) {
  return obs_hash32(a ^ (b + 0x9e3779b9U + (a << 6) + (a >> 2)));
}

/* [0,1) from the top 24 bits: exactly representable, never 1. */
static inline float obs_u32_to_unit(uint32_t x) { return (float)(x >> 8) * 0x1p-24f; }

/* Per-pixel-sample stream of 2D points. */
typedef struct obs_sampler2d {
  obs_sampler_kind kind;
  uint32_t scramble0, scramble1; /* per-stream seeds */
} obs_sampler2d;

/* Seeds the stream for pixel (x, y), pixel sample s, stream id `stream` and the user's seed. */
void obs_sampler2d_init(obs_sampler2d *s, obs_sampler_kind kind, uint32_t x, uint32_t y,
                        uint32_t pixel_sample, uint32_t stream, uint32_t seed);
/* The i-th point of the stream in [0,1)^2. */
void obs_sampler2d_get(const obs_sampler2d *s, uint32_t i, float *u, float *v);
/* Where pixel sample `i` of `spp` looks through its pixel, (jx, jy) in [0, 1)^2 from the pixel's
 * corner: one sample looks through the centre; several are stratified over the pixel by `s`. */
static inline void obs_sampler2d_pixel(const obs_sampler2d *s, int spp, uint32_t i, float *jx,
                                       float *jy) {
  *jx = 0.5f, *jy = 0.5f;
  if (spp > 1) obs_sampler2d_get(s, i, jx, jy);
}
/* Points i0 ... i0 + n - 1 of the stream into u[], v[]: obs_sampler2d_get's values, a Sobol
 * stream's computed eight at a time at x86-64-v3 when isa (simd.h's level) has it. */
void obs_sampler2d_get_n(const obs_sampler2d *s, uint32_t i0, uint32_t n, float *u, float *v,
                         int isa);

/* The sample index shuffled by a nested uniform scramble of its bits (Burley 2020, section 4):
 * the first 2^k indices map onto one aligned block of 2^k, so a Sobol stream read at the
 * shuffled index keeps its stratification, while two streams read at one index under different
 * seeds are decorrelated. Techniques that use several streams for one sample (one per path
 * dimension) need this: without it, their points at equal indices are correlated. */
uint32_t obs_sample_shuffle(uint32_t index, uint32_t seed);

/* Directions about +z: cosine-weighted (pdf cos/pi) and uniform (pdf 1/2pi) hemisphere. */
static inline void obs_sample_cosine(float u, float v, float d[3]) {
  float r = sqrtf(u), phi = 6.28318530717958647692f * v;
  d[0] = r * cosf(phi);
  d[1] = r * sinf(phi);
  d[2] = sqrtf(u < 1.0f ? 1.0f - u : 0.0f); /* not fmaxf: a libm call without -ffast-math */
}

static inline void obs_sample_uniform(float u, float v, float d[3]) {
  float z = u, r = sqrtf(z < 1.0f ? 1.0f - z * z : 0.0f), phi = 6.28318530717958647692f * v;
  d[0] = r * cosf(phi);
  d[1] = r * sinf(phi);
  d[2] = z;
}

/* The sampling frame: the one orthonormal basis (t, b) about a unit normal n that every technique
 * and backend builds its hemisphere, disc or march directions on (GLSL twin obs_onb in
 * renderer/vulkan/shaders/include/frame.glsl, the same operations in the same order, so the same
 * bits). Duff et al. 2017: branchless and stable, but it turns half-way round with the sign of
 * n's z, so every direction built on it changes with that sign.
 *
 * The guard: each component of n within OBS_ONB_FLAT (2^-20) of 0 counts as +0 before the basis
 * is built, and only then is the sign taken. Why this guard, relative to what:
 *  - n is unit length, so an absolute bound on its components is a relative one: the same at
 *    every scene scale and translation.
 *  - A component that is 0 in exact arithmetic reaches here as +0, -0 or a few float rounding
 *    errors of 1 (2^-24 each) of either sign: a wall of an axis-aligned room gets its sign of
 *    zero from its triangle's winding; a cross product of edges whose products cancel
 *    (dx dy - dy dx) gives the rounding error of dx dy under a fused multiply-add, with a sign
 *    that changes with the scale and the instruction set; a normal rotated from view space in
 *    float carries a last-bit error. 2^-20 is 16 of those rounding errors, far above them and
 *    far below any tilt that matters: ignoring a component below it tilts the frame by under
 *    2^-20 radians (1e-6), a millionth of the way a direction travels.
 *  - Guarding z alone would remove the flip; guarding all three also makes the frame of a normal
 *    that differs only by such noise the same bits (normals rotated back from view space on
 *    Vulkan against the CPU's exact ones), at no cost.
 * The flip itself remains, at z = -2^-20 instead of 0, where no rounding of a zero lands. The
 * caller's own n stays the frame's third axis: t and b are orthogonal to it within 2^-20. */
#define OBS_ONB_FLAT 0x1p-20f
static inline void obs_onb(const float n[3], float t[3], float b[3]) {
  const float x = fabsf(n[0]) < OBS_ONB_FLAT ? 0.0f : n[0];
  const float y = fabsf(n[1]) < OBS_ONB_FLAT ? 0.0f : n[1];
  const float z = fabsf(n[2]) < OBS_ONB_FLAT ? 0.0f : n[2];
  const float sign = z < 0.0f ? -1.0f : 1.0f;
  const float a = -1.0f / (sign + z);
  const float c = x * y * a;
  t[0] = 1.0f + sign * x * x * a;
  t[1] = sign * c;
  t[2] = -sign * x;
  b[0] = c;
  b[1] = sign + y * y * a;
  b[2] = -y;
}

#endif
