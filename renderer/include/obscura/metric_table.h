/* The metric table: every figure a comparison reports, declared once (name, label, unit, direction,
 * range, what it needs, definition), and the one function that computes all of them for a pair of
 * images. The server's comparisons, `obscura diff`, `obscura metrics`, docs/metrics.md, the
 * OpenAPI schema and the dashboard's columns are generated from or iterate this table. */
#ifndef OBSCURA_METRIC_TABLE_H
#define OBSCURA_METRIC_TABLE_H

#include <stdint.h>
#include "obscura/image.h"
#include "obscura/metrics.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Which way is better. */
typedef enum obs_metric_direction {
  OBS_METRIC_LOWER,  /* lower is better (errors) */
  OBS_METRIC_HIGHER, /* higher is better (similarities, PSNR) */
  OBS_METRIC_ZERO,   /* closer to zero is better (signed errors: bias) */
  OBS_METRIC_NONE    /* informative, not a quality (the reference's own noise) */
} obs_metric_direction;

/* What a metric needs from the pair (one of them per metric). */
typedef enum obs_metric_needs {
  OBS_METRIC_NEEDS_SCALAR,  /* a scalar channel; AO-like display values in [0, 1] */
  OBS_METRIC_NEEDS_DISPLAY, /* a scalar channel in [0, 1] shown as grey, or HDR RGB (FLIP) */
  OBS_METRIC_NEEDS_RGB,     /* an RGB output "<name>.R/G/B" (linear, HDR allowed) */
  OBS_METRIC_NEEDS_VECTOR,  /* unit vectors "<name>.X/Y/Z" (bent normals) */
  OBS_METRIC_NEEDS_STDERR,  /* the reference's standard error "<name>_stderr" */
  OBS_METRIC_NEEDS_PATCHES  /* per-patch outputs (computed on the patches, not by compare_all) */
} obs_metric_needs;

/* The metrics, in table order (also the order of columns and JSON keys). */
typedef enum obs_metric_id {
  OBS_METRIC_RMSE,
  OBS_METRIC_BIAS,
  OBS_METRIC_MAX_ABS,
  OBS_METRIC_PSNR,
  OBS_METRIC_SSIM,
  OBS_METRIC_FLIP,
  OBS_METRIC_ANGLE_DEG,
  OBS_METRIC_REF_NOISE,
  OBS_METRIC_PATCH_RMSE,
  OBS_METRIC_RMSE_R,
  OBS_METRIC_RMSE_G,
  OBS_METRIC_RMSE_B,
  OBS_METRIC_RMSE_LUMINANCE,
  OBS_METRIC_SSIM_LUMINANCE,
  OBS_METRIC_REL_MSE,
  OBS_METRIC_COUNT
} obs_metric_id;

typedef struct obs_metric {
  const char *name;       /* CSV column and `obscura diff --json` key: "rmse", "rmse_r" */
  const char *json_group; /* NULL: a key of the comparison's `metrics` object; "rgb": of its
                             `metrics.rgb` object */
  const char *json_key;   /* the key inside that object ("rmse" for rmse_r in "rgb") */
  int json_index;         /* -1: a number; 0..2: element of an array under json_key */
  const char *label;      /* short human label: "RMSE", "PSNR" */
  const char *unit;       /* "" when unitless: "dB", "deg" */
  obs_metric_direction direction;
  double min, max;        /* the range of values (+-INFINITY when open) */
  obs_metric_needs needs;
  int digits;             /* significant digits a table shows */
  const char *definition; /* one line, as docs/metrics.md states it */
  const char *same_as;    /* NULL, or the metric whose value this one always equals where both
                             apply (rmse_luminance is an RGB output's rmse): tables show one */
} obs_metric;

/* The table: obs_metric_table()[id] for id in [0, OBS_METRIC_COUNT). */
const obs_metric *obs_metric_table(void);
/* The metric called `name`, or NULL. */
const obs_metric *obs_metric_find(const char *name);
const char *obs_metric_direction_name(obs_metric_direction d); /* "lower", "higher", "zero", "none" */
const char *obs_metric_needs_name(obs_metric_needs n); /* "scalar", "display", "rgb", ... */

/* Every metric of the table that applies to one pair. */
typedef struct obs_metric_values {
  double v[OBS_METRIC_COUNT];          /* NaN where not finite-computable (JSON null) */
  unsigned char has[OBS_METRIC_COUNT]; /* 1 where the metric applies to this pair */
  int64_t pixels;                      /* selected pixels */
  int at_reference_accuracy;           /* as obs_compare's */
} obs_metric_values;

/* How compare_all reads the pair. */
typedef struct obs_metric_opts {
  const char *channel; /* a scalar channel, an RGB output prefix ("radiance" for radiance.R/G/B)
                          or a vector output prefix ("bent_normal" for .X/.Y/.Z); which one is
                          found from the channels the reference has */
  const char *mask;    /* channel of the reference whose value > 0 selects pixels; NULL: all */
  const char *stderr_channel; /* the reference's standard error of `channel` (scalar, or RGB
                                 prefix); NULL: "<channel>_stderr" where present */
  double ppd;          /* FLIP's pixels per degree; 0: OBS_FLIP_DEFAULT_PPD */
  obs_image *flip_map; /* may be NULL; where flip applies (has[OBS_METRIC_FLIP]), receives its
                          per-pixel map (channel "flip"; the caller frees it), else is zeroed */
} obs_metric_opts;

/* Computes every applicable metric of the table for `candidate` against `reference` (same size),
 * the kind of `channel` found from the reference's channels:
 *   scalar channel: rmse, bias, max_abs, psnr, ssim, ref_noise (obs_metrics_compare), and flip
 *     (LDR-FLIP, the value as grey) when every finite selected reference value lies in [0, 1]
 *     (a display value such as AO; depth has no FLIP);
 *   RGB output: rmse_r/g/b, rmse_luminance, ssim_luminance, rel_mse (obs_metrics_compare_rgb),
 *     rmse, bias, max_abs, psnr, ssim and ref_noise on the luminance Y (the reference's noise from
 *     the luminance of its standard error), and flip = HDR-FLIP of the RGB;
 *   vector output: angle_deg (pixels where either vector has length 0 are left out).
 * patch_rmse is never filled here (the server computes it on the patches). Unfilled entries have
 * has[id] = 0 and v[id] = NaN. */
int obs_metrics_compare_all(const obs_image *candidate, const obs_image *reference,
                            const obs_metric_opts *opts, obs_metric_values *out, obs_err *err);

/* The table as JSON (new reference): an array of objects {name, json_group, json_key, json_index,
 * label, unit, direction, min, max (null when open), needs, digits, definition}. */
struct json_t;
struct json_t *obs_metric_table_json(void);
/* The table as docs/metrics.md shows it (a Markdown table) and as schema/openapi.yaml's Metrics
 * schema (YAML at its indentation); new strings the caller frees, NULL when out of memory. */
char *obs_metric_table_markdown(void);
char *obs_metric_table_openapi(void);
/* Sets, in `metrics` (a JSON object), every metric `vals` has at its json_group/json_key place
 * (null for NaN), plus "pixels", "at_reference_accuracy". */
int obs_metric_values_json(const obs_metric_values *vals, struct json_t *metrics);
/* Metric m's value in a `metrics` object as obs_metric_values_json writes it (borrowed; NULL when
 * absent). */
struct json_t *obs_metric_json_get(const struct json_t *metrics, const obs_metric *m);

#ifdef __cplusplus
}
#endif
#endif
