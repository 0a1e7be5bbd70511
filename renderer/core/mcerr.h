/* The standard error of a Monte-Carlo estimate from its independent replicates (sampling.h,
 * obs_rqmc), and what it reports when every replicate agreed: the rule every technique's stderr
 * output follows (docs/accuracy.md, "Standard errors"). */
#ifndef OBS_MCERR_H
#define OBS_MCERR_H

#include <math.h>
#include <stdint.h>

/* Welford's running mean and sum of squared deviations of the replicates' means. */
typedef struct obs_mcerr {
  double mean, m2;
  uint32_t reps;
} obs_mcerr;

static inline void obs_mcerr_add(obs_mcerr *e, double replicate_mean) {
  e->reps++;
  double d = replicate_mean - e->mean;
  e->mean += d / e->reps;
  e->m2 += d * (replicate_mean - e->mean);
}

/* The unbiased estimate of the variance of the mean of the replicates' means: their sample
 * variance over R (0 for fewer than two). Unbiased also when the replicates' sizes differ by one
 * and so do their variances. */
static inline double obs_mcerr_var(const obs_mcerr *e) {
  return e->reps > 1 ? fmax(0.0, e->m2) / ((double)e->reps * (e->reps - 1)) : 0.0;
}

/* When every replicate agreed (all n samples alike, e.g. every AO ray escaped), the spread is 0
 * although an event of probability p ~ 1/n may have been missed by all of them: the truth can
 * differ by p times the event's effect. The reported error is then OBS_MCERR_FLOOR / (n + 2) times
 * `span`, the largest effect one unseen event can have (1 for AO in [0, 1]; 0 where the estimate
 * is deterministic), capped at span / 2 (the largest standard deviation of a value within a span):
 * an estimate missing an event of probability p is outside 3 such errors only if
 * p > 4.5 / (n + 2), which n samples all miss with probability below exp(-4.5 n / (n + 2)) (1.8 %
 * at 16 samples, 1.2 % at 256). */
#define OBS_MCERR_FLOOR 1.5

static inline double obs_mcerr_floor(uint32_t n, double span) {
  double f = OBS_MCERR_FLOOR / ((double)n + 2.0);
  return (f < 0.5 ? f : 0.5) * span;
}

/* Whether the replicates all agreed (or there was one): their spread says nothing. */
static inline int obs_mcerr_agreed(const obs_mcerr *e) { return !(e->m2 > 0 && e->reps > 1); }

/* The standard error of the estimate of n samples with these replicates: the replicates' spread,
 * or, when they all agreed, the floor for `span`. `pooled` (a technique whose driver pools errors
 * with a prior, driver.h): the floor is given negated (the sign bit set even for a floor of 0),
 * the mark of agreeing samples. */
static inline double obs_mcerr_stderr(const obs_mcerr *e, uint32_t n, double span, int pooled) {
  if (!obs_mcerr_agreed(e)) return sqrt(obs_mcerr_var(e));
  return pooled ? -obs_mcerr_floor(n, span) : obs_mcerr_floor(n, span);
}

/* A ratio mean S / N over independent groups of samples, each group r adding its sum s_r of
 * values and its count n_r (a patch's samples: their number varies from group to group), and
 * its variance by the groups' spread (the "ultimate cluster" estimator of survey sampling):
 *   var = R / (R - 1) sum_r (s_r - (S / N) n_r)^2 / N^2.
 * With one sample per group it is the sample variance of the values over N. */
typedef struct obs_mcerr_ratio {
  double s, n, s2, sn, n2;
  double lo, hi;          /* the non-empty groups' smallest and largest means */
  uint32_t groups, filled; /* groups, and those with samples (zeroed: none yet) */
} obs_mcerr_ratio;

static inline void obs_mcerr_ratio_add(obs_mcerr_ratio *e, double s, double n) {
  e->s += s, e->n += n, e->s2 += s * s, e->sn += s * n, e->n2 += n * n;
  if (n > 0) {
    double y = s / n;
    e->lo = e->filled ? fmin(e->lo, y) : y;
    e->hi = e->filled ? fmax(e->hi, y) : y;
    e->filled++;
  }
  e->groups++;
}

/* 0 when the groups all agree (exactly: the sums' rounding would leave a speck). */
static inline double obs_mcerr_ratio_var(const obs_mcerr_ratio *e) {
  if (e->groups < 2 || !(e->n > 0) || !(e->hi > e->lo)) return 0.0;
  double y = e->s / e->n, ss = e->s2 - 2 * y * e->sn + y * y * e->n2;
  double R = e->groups;
  return fmax(0.0, ss) * R / (R - 1) / (e->n * e->n);
}

/* A pixel's standard error over its independent pixel samples, whose variances add: the root of
 * their sum of squares over spp, negated (the sign bit set) when some sample's was (agreed) and
 * none had a spread; +0 when every sample was exact. */
typedef struct obs_mcerr_pixel {
  double var;
  int agreed, spread;
} obs_mcerr_pixel;

static inline void obs_mcerr_pixel_add(obs_mcerr_pixel *p, double se) {
  p->var += se * se;
  p->agreed += signbit(se) != 0;
  p->spread += se > 0;
}

static inline double obs_mcerr_pixel_stderr(const obs_mcerr_pixel *p, int spp) {
  double se = sqrt(p->var) / (spp > 0 ? spp : 1);
  return p->agreed && !p->spread ? -se : se;
}

#endif
