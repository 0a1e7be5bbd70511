/* Image statistics and error metrics between two images' channels. */
#ifndef OBSCURA_METRICS_H
#define OBSCURA_METRICS_H

#include <stdint.h>
#include "obscura/image.h"
#include "obscura/patches.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct obs_stats {
  double mean, min, max; /* over finite values only; 0 when there are none */
  int64_t count;         /* finite values counted */
  int64_t nan_count;     /* NaN values */
  int64_t inf_count;     /* +-Inf values */
} obs_stats;

/* Statistics of one channel. `mask` (may be NULL) names a channel whose value > 0 selects the
 * pixels counted (e.g. "alpha" for covered pixels). */
int obs_metrics_stats(const obs_image *img, const char *channel, const char *mask, obs_stats *out,
                      obs_err *err);

/* Root-mean-square error of channel `channel` between a and b (same size), over pixels where `mask`
 * (channel of b, may be NULL) is > 0. */
int obs_metrics_rmse(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *rmse, obs_err *err);

/* Mean structural similarity of channel `channel` between a and b (same size), as Wang et al.
 * (2004) and scikit-image's structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
 * use_sample_covariance=False, data_range=L) define it: local means, variances and covariance under
 * an 11x11 Gaussian window (sigma 1.5, truncated at 3.5 sigma, normalised), the image mirrored at
 * its borders (scipy's "reflect"), C1 = (0.01 L)^2, C2 = (0.03 L)^2, L = OBS_SSIM_DATA_RANGE (1:
 * AO and luminance both; docs/metrics.md), and the mean of the SSIM map over the pixels at least 5
 * from every border (skimage's crop). With `mask` (channel of b, may be NULL) only the selected
 * pixels of that cropped area count (the windows still read their unselected neighbours: a mask
 * chooses which local similarities are averaged, it does not change them). Computed in double.
 * 1 means identical; NaN (undefined) for images with fewer than 11 pixels in a dimension (skimage
 * refuses them) and when a counted pixel's window holds a non-finite value; 1 when no pixel
 * counts. */
#define OBS_SSIM_WINDOW 11
#define OBS_SSIM_SIGMA 1.5
#define OBS_SSIM_DATA_RANGE 1.0
int obs_metrics_ssim(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *ssim, obs_err *err);

/* FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020): the
 * per-pixel perceived difference in [0, 1] of `test` against `reference` (same size) for a viewer
 * at OBS_FLIP_DEFAULT_PPD pixels per degree, and its mean. `channel` names
 *   - a scalar channel: a display value in [0, 1] (AO), entering LDR-FLIP as the grey sRGB
 *     colour (v, v, v), since that is what obscura's PNGs show for it (values are clamped to
 *     [0, 1], as a display does); `hdr` must be 0;
 *   - an RGB output prefix ("radiance" for radiance.R/G/B): with hdr = 0 the values are taken as
 *     linear in [0, 1] (clamped) and sRGB-encoded for LDR-FLIP; with hdr = 1 HDR-FLIP: the maximum
 *     over LDR-FLIP of ACES-tone-mapped exposures between the start and stop exposures the
 *     reference's luminance median and maximum give (docs/metrics.md).
 * The filters read every pixel (the picture as shown); `mask` (channel of the reference, > 0
 * selects, may be NULL) chooses the pixels the mean averages (none selected: mean 0). `map`
 * (may be NULL; initialised by the call, owned by the caller) receives the per-pixel error in
 * channel "flip" for every pixel. A non-finite input value makes its pixel's error NaN. */
/* FLIP's default observer: a 0.7 m wide 4K display seen from 0.7 m, 3840 pi / 180 = 67.02
 * pixels per degree. */
#define OBS_FLIP_DEFAULT_PPD (3840.0 * 3.14159265358979323846 / 180.0)
int obs_metrics_flip(const obs_image *test, const obs_image *reference, const char *channel,
                     const char *mask, int hdr, obs_image *map /* may be NULL; channel "flip" */,
                     double *mean, obs_err *err);
/* obs_metrics_flip at `ppd` pixels per degree (> 0). */
int obs_metrics_flip_ppd(const obs_image *test, const obs_image *reference, const char *channel,
                         const char *mask, int hdr, double ppd, obs_image *map, double *mean,
                         obs_err *err);
/* Writes `dir`/flip.exr (channel "flip", float) and `dir`/flip.png (the error through the magma
 * colour ramp, FLIP's own display: black 0 to light yellow 1) from a map made by obs_metrics_flip,
 * creating `dir` when missing; staged and renamed like obs_metrics_write_error_files. */
int obs_metrics_write_flip_files(const obs_image *map, const char *dir, obs_err *err);

/* PSNR reported for identical images (and the ceiling for all): 10 log10(1/MSE) is +Inf at MSE 0,
 * which JSON cannot carry and a ranking cannot use. 100 dB is RMSE 1e-5, far below any AO noise. */
#define OBS_METRICS_PSNR_MAX 100.0
/* Error magnitude mapped to the full colour of the error image's ramp (larger errors clamp). Fixed
 * rather than per-image so heatmaps of different candidates can be compared by eye. */
#define OBS_METRICS_ERROR_SCALE 0.25

/* A candidate render compared with a reference on one channel over the reference's covered pixels.
 * Definitions (d = candidate - reference per selected pixel, N = pixels; docs/metrics.md):
 *   rmse = sqrt(sum d^2 / N), exactly obs_metrics_rmse;  bias = sum d / N;  max_abs = max |d|;
 *   psnr = min(10 log10(1 / rmse^2), OBS_METRICS_PSNR_MAX) (peak 1, so identical -> 100 dB);
 *   ssim = obs_metrics_ssim(candidate, reference, channel, mask).
 * Non-finite values are never hidden: a NaN difference in a selected pixel makes rmse, bias,
 * max_abs and psnr NaN; otherwise an infinite difference makes rmse and max_abs +Inf, psnr -Inf
 * and bias +-Inf (NaN when both signs occur). Equal infinities are no error. SSIM is NaN when a
 * counted window holds a non-finite value. With no pixel selected every error is 0, psnr is the
 * cap and ssim 1 (check `pixels`). */
typedef struct obs_compare {
  double rmse;
  double bias; /* mean(candidate - reference): > 0 means the candidate is too bright */
  double max_abs;
  double psnr; /* dB, peak 1, capped at OBS_METRICS_PSNR_MAX */
  double ssim;
  int64_t pixels;   /* selected pixels (all when mask is NULL) */
  double ref_noise; /* mean of the reference's "<channel>_stderr" (e.g. ao_stderr) over the selected
                       pixels, finite values only; 0 when the reference has no such channel */
  int at_reference_accuracy; /* rmse < 2 * ref_noise: the difference is within the reference's own
                                noise, so ranking it against others would rank noise. Never set
                                when ref_noise is 0 or rmse is NaN. */
} obs_compare;

/* Compares channel `channel` of `candidate` with `reference` (same size) over the pixels where the
 * reference's `mask` channel is > 0 (NaN deselects; NULL mask: every pixel), filling `out`. Values
 * are expected in [0,1] (AO); nothing is clamped. */
int obs_metrics_compare(const obs_image *candidate, const obs_image *reference, const char *channel,
                        const char *mask, obs_compare *out, obs_err *err);

/* Fills `out` (initialised by the call, owned by the caller; obs_image_free) with the same size as
 * the inputs and channels:
 *   "error"     candidate - reference where the reference's `mask` > 0 (NULL: everywhere), 0
 *               elsewhere; equal infinities give 0, other non-finite differences are kept;
 *   "R","G","B" a diverging blue-white-red ramp for a PNG (display values, no gamma encoding):
 *               0 is white (1,1,1), -OBS_METRICS_ERROR_SCALE and below is blue #2166AC, +scale and
 *               above is red #B2182B, linear in between; unselected pixels are mid grey (0.5) and
 *               NaN errors green (0,1,0), both off the ramp so neither reads as an error size. */
int obs_metrics_error_image(const obs_image *candidate, const obs_image *reference,
                            const char *channel, const char *mask, obs_image *out, obs_err *err);

/* Writes `dir`/error.exr (channel "error" only, float) and `dir`/error.png (8-bit RGB from "R","G",
 * "B") from an image made by obs_metrics_error_image, creating `dir` when missing. Both are written
 * under staging names and renamed into place only when both succeeded. */
int obs_metrics_write_error_files(const obs_image *err_img, const char *dir, obs_err *err);

/* Luminance of linear RGB (Rec. 709 / sRGB primaries): 0.2126 R + 0.7152 G + 0.0722 B. */
#define OBS_LUMINANCE(r, g, b) (0.2126 * (double)(r) + 0.7152 * (double)(g) + 0.0722 * (double)(b))
/* Floor of the denominator of the relative MSE, so black reference pixels do not dominate. */
#define OBS_METRICS_RELMSE_EPS 1e-2

/* Mean luminance of RGB output `rgb` (channels "<rgb>.R/G/B") over the pixels `mask` selects. */
int obs_metrics_luminance_mean(const obs_image *img, const char *rgb, const char *mask,
                               double *mean, obs_err *err);

/* A new image (owned by the caller) holding the luminance of RGB output `rgb` of `img` in
 * channel "<rgb>", the luminance of `stderr_rgb`'s channels (when non-NULL and present) in
 * "<rgb>_stderr" (a bound of the luminance's standard error: the channels' errors taken as fully
 * correlated), and "alpha" copied when present: the scalar image the scalar comparison
 * (obs_metrics_compare, error images) runs on for an RGB output. */
int obs_metrics_luminance_image(const obs_image *img, const char *rgb, const char *stderr_rgb,
                                obs_image *out, obs_err *err);

/* RGB output `rgb` of a candidate against a reference over the reference's `mask` pixels.
 * With c, r the candidate's and reference's values, N the selected pixels (docs/metrics.md):
 *   rmse[k] = sqrt(sum (c_k - r_k)^2 / N) for k = R, G, B (exactly obs_metrics_rmse per channel);
 *   rmse_luminance = the same on the luminance Y = OBS_LUMINANCE;
 *   ssim_luminance = obs_metrics_ssim on Y (its constants assume values near [0, 1]);
 *   rel_mse = sum over pixels and the three channels of (c_k - r_k)^2 / (r_k^2 + eps)
 *             divided by 3N, eps = OBS_METRICS_RELMSE_EPS.
 * A NaN in a selected pixel makes every figure NaN except SSIM (NaN for windows holding it). */
typedef struct obs_compare_rgb {
  double rmse[3];
  double rmse_luminance;
  double ssim_luminance;
  double rel_mse;
  int64_t pixels;
} obs_compare_rgb;

int obs_metrics_compare_rgb(const obs_image *candidate, const obs_image *reference,
                            const char *rgb, const char *mask, obs_compare_rgb *out,
                            obs_err *err);

/* Statistics of every value of `p` (all components, all frames), like obs_metrics_stats. */
void obs_metrics_patch_stats(const obs_patches *p, obs_stats *out);

/* Root-mean-square error over the patches of a candidate against a reference with the same count,
 * components and frames (every frame's patches count), weighted by the patches' areas (the reference's, else the candidate's, else
 * all equal): sqrt(sum_i a_i sum_k (c_ik - r_ik)^2 / (components * sum_i a_i)). Patches of zero
 * area do not count. Non-finite differences as in obs_metrics_rmse. */
int obs_metrics_patch_rmse(const obs_patches *candidate, const obs_patches *reference,
                           double *rmse, obs_err *err);

/* How well a candidate's reported standard errors describe its actual error against a reference
 * of the same quantity made with many more samples (docs/accuracy.md, "Standard errors"). Every
 * selected value counts once (each channel of each pixel, or of each patch); with d = candidate -
 * reference and s the reported standard error:
 *   rms_stderr = sqrt(mean s^2), rmse = sqrt(mean d^2), ratio = rms_stderr / rmse (1 when both
 *   are 0, +Inf when only rmse is);
 *   within3 = share of values with |d| <= 3 s;
 *   zero_with_error = share of values with s = 0 and d != 0.
 * The reference's own noise adds to d: at 64x the samples it widens d by under 1 %. Values whose
 * candidate, reference or standard error is not finite are counted in `nonfinite` and left out. */
typedef struct obs_stderr_calib {
  double rms_stderr, rmse, ratio, within3, zero_with_error;
  int64_t values, nonfinite;
  int64_t unsampled; /* patches: values left out as carrying no estimate (below) */
} obs_stderr_calib;

/* The calibration of output `name` of `candidate` (channel "<name>", or "<name>.R/G/B") with its
 * standard error `stderr_name` ("<stderr_name>" or "<stderr_name>.R/G/B", the same kind) against
 * `reference`'s `name`, over the pixels where the reference's `mask` channel is > 0 (NULL: all). */
int obs_metrics_stderr_calib(const obs_image *candidate, const obs_image *reference,
                             const char *name, const char *stderr_name, const char *mask,
                             obs_stderr_calib *out, obs_err *err);

/* The same over per-patch values of equal count and frames: `se` has one component (the error of
 * every component of `candidate`) or as many as `candidate`; patches of zero area (when the
 * reference's or the candidate's areas are known) are left out, and so are those whose standard
 * error is 1 or more: per-patch values lie in [0, 1], and 1 marks a patch no sample reached
 * (obscurance_map's), whose value is a convention, not an estimate (counted in `unsampled`). */
int obs_metrics_patch_stderr_calib(const obs_patches *candidate, const obs_patches *se,
                                   const obs_patches *reference, obs_stderr_calib *out,
                                   obs_err *err);

/* One candidate of a speed/accuracy comparison for obs_metrics_pareto. */
typedef struct obs_pareto_point {
  double time_ms; /* lower is better (the median of the timed runs) */
  double error;   /* lower is better (RMSE) */
  int at_reference_accuracy; /* error within the reference's noise: see below */
  /* The run-to-run spread of the time: the fastest and slowest timed run. 0 (or a value on the
   * wrong side of time_ms) stands for time_ms itself: no measured spread. */
  double time_min_ms, time_max_ms;
  /* How far two errors may differ and still count as equal: the reference's noise. 0 or NaN:
   * errors compare exactly. */
  double error_tolerance;
} obs_pareto_point;

/* Marks the Pareto-optimal points: optimal[i] = 1 when no other point dominates it. Point j
 * dominates i when j is no slower and no less accurate than i and better in one of the two, where
 * "better" needs a margin: j is faster only when its slowest run beats i's fastest one (their
 * spreads [time_min_ms, time_max_ms] do not overlap), and more accurate only when its error is
 * lower by more than the larger of the two error_tolerance values; "no slower" and "no less
 * accurate" are the negations of "slower" and "less accurate" with those margins. Without spreads
 * and tolerances this is the exact definition: exact ties (same time, same error) are all optimal.
 * Points whose error is within the reference's noise (at_reference_accuracy) count as equally
 * accurate among themselves and more accurate than every other point, so only the fastest of them
 * (beyond the spreads) is optimal. A point with a NaN time or (unless at_reference_accuracy) a NaN
 * error takes no part: it is never optimal and dominates nothing. Returns the number of optimal
 * points, or OBS_EINVAL on NULL arguments with n > 0. */
int obs_metrics_pareto(const obs_pareto_point *points, size_t n, unsigned char *optimal,
                       obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
