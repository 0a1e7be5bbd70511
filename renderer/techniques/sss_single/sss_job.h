/* What sss_single's CPU files share: the job (the scene's media and punctual lights in the ray
 * tracer's frame) and the two estimators of a pixel sample (cpu_maps.c: the light-view maps of
 * the article; cpu_trace.c: the ray-traced reference). */
#ifndef OBS_SSS_CPU_H
#define OBS_SSS_CPU_H

#include <stdatomic.h>
#include <stdint.h>

#include "raytrace.h"
#include "sss_single.h"

/* One punctual light and, for shadow_maps, its light-view maps. Positions are in the ray
 * tracer's frame (world minus rt->geo.origin). */
typedef struct sss_light {
  int point;          /* 1: point light at `pos`; 0: directional along `dir` */
  int index;          /* in the scene's `lights` */
  double pos[3];
  double dir[3];      /* directional: the way its light travels (unit) */
  double power[3];    /* point: intensity; directional: irradiance facing it */
  /* The map's projection: orthographic (directional) over [-half, half]^2 about `centre`, or
   * perspective (point) from `pos` along `fwd` with tan(half field of view) = `half`. */
  double centre[3], fwd[3], right[3], up[3], half, back;
  int size;
  float *pos_map;     /* 3 per texel: the first surface seen from the light */
  float *nrm_map;     /* 3 per texel: its outward unit normal */
  float *irr_map;     /* 3 per texel: transmitted irradiance E_t (Eq. 6.5.4), 0 off media */
  int32_t *id_map;    /* the surface's object, -1 where the light sees nothing */
} sss_light;

/* One medium object's coefficients per scene unit, with sigma_t's smallest channel, the rate the
 * path lengths are drawn with. */
typedef struct sss_medium {
  double sigma_s[3], sigma_t[3], sigma_min, g, eta;
} sss_medium;

typedef struct sss_job {
  const obs_rt *rt;
  obs_sss_single_params p;
  int spp;
  sss_light *lights;
  int nlights;
  sss_medium *media; /* per scene object */
  size_t nobjects;
  int32_t *has_medium;
  /* trace: the entry-point searches made, those stopped unconverged after OBS_SSS_ENTRY_STEPS
   * (their best iterate used) and those that found no refracted path (obs_sss_entry_solve);
   * NULL: not counted. Sums, so the same for any thread order. */
  atomic_ullong *entry_count;
} sss_job;

/* The scene's media per scene unit and its punctual lights in the ray tracer's frame (`jb->rt`
 * and `jb->p` set by the caller); quad lights are ignored with a warning. 0 or OBS_E*. */
int obs_sss_job_setup(obs_render_ctx *ctx, sss_job *jb, obs_err *err);
void obs_sss_job_free(sss_job *jb);

/* The camera ray of pixel sample s of pixel (x, y): the pixel's centre for one sample, else a
 * stratified grid jittered by the seed (the same on both backends and at every scale). */
struct obs_camera_rig;
void obs_sss_sample_ray(const struct obs_camera_rig *cam, uint32_t seed, int spp, int x, int y,
                        int s, double org[3], double dir[3]);

/* The radiance of one pixel sample seen at `hit` (object `obj`) along unit `dir`, by the light-
 * view maps (M or, refined, 2M deterministic path samples per light). Returns the lookups made. */
uint64_t obs_sss_maps_shade(const sss_job *jb, const obs_hit *hit, size_t obj, const double dir[3],
                            uint32_t px, uint32_t py, uint32_t s, double out[3], int *refined);
/* Each light's map projection over the medium objects' bounding sphere (centre, half, back, the
 * basis); refuses a point light inside that sphere. 0 or OBS_E*. */
int obs_sss_maps_setup(sss_job *jb, obs_err *err);
/* The projections and the light-view maps of every light, cast with Embree (obs_parallel_tiles
 * over the texels); 0 or OBS_E*. */
int obs_sss_maps_build(sss_job *jb, int threads, obs_err *err);
/* The radiance of one pixel sample by ray tracing: `samples` path lengths, each connected to every
 * light through the refracted entry point. Fills the sample mean and the sum of squares of the
 * path values per channel; returns the rays traced. */
uint64_t obs_sss_trace_shade(const sss_job *jb, const obs_hit *hit, size_t obj,
                             const double dir[3], uint32_t px, uint32_t py, uint32_t s,
                             double sum[3], double sum2[3]);

/* The point x_i where the light that reaches frame point xs inside object obj entered it: the
 * refracted light path, solved on the surface to convergence (see cpu_trace.c). */
typedef struct sss_entry {
  obs_hit h;      /* the entry point on obj; h.t is the in-medium light path s_i' */
  double wi[3];   /* the light's direction refracted at h (unit, into the medium) */
  double w[3];    /* the light's direction arriving at h (unit) */
  double dist;    /* a point light's distance from h; INFINITY for a directional light */
  double resid;   /* Snell's residual at h: |wi + u| for the unit direction u from xs to h */
  int steps;      /* iterations after the straight line toward the light (fixed-point or Newton) */
  int converged;  /* the position moved less than the tolerance at the last step */
  int stalled;    /* no step shrinks the residual, which stays above 0: no such path exists */
} sss_entry;
/* The default bound on the search's steps. */
#define OBS_SSS_ENTRY_STEPS 16
/* Solves for the entry point with at most max_steps iterations (1: at most the one-step estimate,
 * the refracted direction at the face the straight line to the light crosses). Returns 1 with *e
 * filled (unconverged: the iterate with the smallest residual; stalled: no refracted path reaches
 * xs), 0 when no light path enters obj toward xs (the line to the light leaves through another
 * object or a face turned away). Counts rays. */
int obs_sss_entry_solve(const sss_job *jb, const sss_light *l, size_t obj, const float xs[3],
                        int max_steps, sss_entry *e, uint64_t *rays);

/* A uniform number in [0, 1) from a 64-bit key (splitmix64): images depend only on the key. */
static inline double obs_sss_rand(uint64_t key) {
  uint64_t z = key + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static inline uint64_t obs_sss_key(uint32_t seed, uint32_t x, uint32_t y, uint32_t s, uint32_t i) {
  uint64_t k = seed;
  k = k * 0x100000001B3ull ^ x;
  k = k * 0x100000001B3ull ^ y;
  k = k * 0x100000001B3ull ^ s;
  k = k * 0x100000001B3ull ^ i;
  return k;
}

/* The jitter of map lookup k (0: x, 1: y of path sample k / 2) of light l for pixel sample s of
 * pixel (x, y): a number in [0, 1) with 24 bits, exact in float, so both backends jitter alike
 * (sss_single.comp.glsl has the same hash). */
static inline uint32_t obs_sss_pcg(uint32_t v) {
  uint32_t state = v * 747796405u + 2891336453u;
  uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}
static inline float obs_sss_jitter_u(uint32_t seed, uint32_t x, uint32_t y, uint32_t s,
                                     uint32_t l, uint32_t k) {
  uint32_t h = obs_sss_pcg(seed ^ obs_sss_pcg(x));
  h = obs_sss_pcg(h ^ y);
  h = obs_sss_pcg(h ^ (s * 64u + l));
  h = obs_sss_pcg(h ^ k);
  return (float)(h >> 8) * (1.0f / 16777216.0f);
}

static inline double obs_sss_dot(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline double obs_sss_lum(const double c[3]) {
  return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

#endif
