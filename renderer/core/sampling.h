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

/* Randomised QMC with independent replicates, for honest standard errors (docs/accuracy.md,
 * "Standard errors"). The n samples of one estimate form R replicates of consecutive samples
 * (sizes n / R or one more), each an independently scrambled stream read from its first point
 * (Sobol: its own Owen scramble; Halton: its own Cranley-Patterson rotation), so the replicates'
 * means are independent unbiased estimates and their spread measures the estimate's error, QMC's
 * stratification included. R = min(n, OBS_RQMC_REPLICATES). Replicates cost accuracy: R sets of
 * n / R points converge at the scrambled sequence's rate but with a larger constant than one set
 * of n (measured on the Cornell box at 16-256 samples: RMSE x1.4 with 4 replicates, x1.75 with 8
 * for binary AO; x2 and x3 for the smooth exp falloff). 4 replicates leave 3 degrees of freedom,
 * too few alone (a Student t with 3 puts 5.8 % outside 3 standard errors): every user pools them
 * with a prior worth 8 more (driver.h's obs_pixel_prior, patch_mesh.h's obs_patch_mesh_errors),
 * which brings that to 1.2 %. A random stream is i.i.d. already: every sample is its own replicate
 * (R = n) and reads the stream at its index. */
#define OBS_RQMC_REPLICATES 4
#define OBS_RQMC_MAX 8 /* the most replicates a caller may ask for (obs_rqmc_init_max) */
typedef struct obs_rqmc {
  obs_sampler2d s[OBS_RQMC_MAX]; /* replicate r's stream; random: s[0] only */
  uint32_t n, reps;              /* samples, replicates */
} obs_rqmc;

/* The seed of replica r >= 1 of a render seeded `seed`: an independent set of every sample (the
 * pilot renders of the driver's pooled prior, driver.h). */
static inline uint32_t obs_sampler_replica_seed(uint32_t seed, uint32_t replica) {
  return obs_hash_combine(seed, 0x7e11ca5U + replica);
}

/* How many replicates n samples of `kind` form, R. */
static inline uint32_t obs_rqmc_replicates(obs_sampler_kind kind, uint32_t n) {
  if (!n) return 1;
  return kind == OBS_SAMPLER_RANDOM || n < OBS_RQMC_REPLICATES ? n : OBS_RQMC_REPLICATES;
}
/* The replicates of n samples (n >= 1) for pixel (x, y), pixel sample, stream and seed (as
 * obs_sampler2d_init). */
void obs_rqmc_init(obs_rqmc *q, obs_sampler_kind kind, uint32_t x, uint32_t y,
                   uint32_t pixel_sample, uint32_t stream, uint32_t seed, uint32_t n);
/* The same with up to `max` (<= OBS_RQMC_MAX) replicates for QMC streams, for estimates pooled
 * more coarsely than per pixel, which must carry more of their error themselves. */
void obs_rqmc_init_max(obs_rqmc *q, obs_sampler_kind kind, uint32_t x, uint32_t y,
                       uint32_t pixel_sample, uint32_t stream, uint32_t seed, uint32_t n,
                       uint32_t max);
/* Replicate r's samples: [obs_rqmc_first(r), obs_rqmc_first(r + 1)). */
static inline uint32_t obs_rqmc_first(const obs_rqmc *q, uint32_t r) {
  uint32_t base = q->n / q->reps, extra = q->n % q->reps;
  return r * base + (r < extra ? r : extra);
}
/* Where sample i (i < n) comes from: point *j of stream q->s[r], r returned (random: r = 0 and
 * j = i). */
uint32_t obs_rqmc_locate(const obs_rqmc *q, uint32_t i, uint32_t *j);
/* Sample i's point, and whether it is the last sample of its replicate. */
int obs_rqmc_get(const obs_rqmc *q, uint32_t i, float *u, float *v);
/* Points i0 ... i0 + m - 1 into u[], v[]: obs_rqmc_get's values, through obs_sampler2d_get_n
 * (eight at a time at x86-64-v3) over each replicate's part. */
void obs_rqmc_get_n(const obs_rqmc *q, uint32_t i0, uint32_t m, float *u, float *v, int isa);

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
