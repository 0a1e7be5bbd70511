/* The technique registry: one table describing every technique and the backends that run it. */
#ifndef OBSCURA_TECHNIQUE_H
#define OBSCURA_TECHNIQUE_H

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include "obscura/error.h"
#include "obscura/image.h"
#include "obscura/patches.h"
#include "obscura/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a technique needs built from the scene; the renderer builds nothing else. */
enum {
  OBS_NEED_BVH = 1 << 0,       /* ray-tracing acceleration structure (Embree) */
  OBS_NEED_MATERIALS = 1 << 1, /* every object must carry a material */
  OBS_NEED_LIGHTS = 1 << 2,    /* the scene must have at least one light */
  OBS_NEED_GBUFFER = 1 << 3    /* rasterised or ray-cast G-buffer */
};

typedef void (*obs_progress_fn)(void *user, double fraction);

#define OBS_MAX_STAGES 8
/* Warnings a render may attach to its result: the scene lies outside the range over which the
 * technique's output is guaranteed (docs/accuracy.md), or a parameter is suspicious. */
#define OBS_MAX_WARNINGS 8
#define OBS_WARNING_LEN 320
/* Per-patch outputs one render may carry. */
#define OBS_MAX_PATCH_OUTPUTS 4

/* Per-stage timings in milliseconds. */
typedef struct obs_timings {
  double load_ms, build_ms, render_ms, write_ms, total_ms;
} obs_timings;

/* Everything a technique implementation receives. Borrowed for the duration of the call. */
typedef struct obs_render_ctx {
  const obs_scene *scene;
  const json_t *params;        /* defaults filled in */
  int threads;                 /* >= 1 */
  obs_progress_fn progress;    /* may be NULL; called with fractions in [0,1], from any thread */
  void *progress_user;
  const atomic_int *cancel;    /* may be NULL; nonzero asks the technique to stop between tiles */
  /* Filled by the technique: */
  double build_ms;             /* acceleration structures, tessellation */
  double render_ms;
  uint64_t rays;               /* rays traced (primary + secondary) */
  /* Finer stages (e.g. "gbuffer", "ao", "blur", "readback"), added with obs_render_ctx_stage. */
  int nstages;
  const char *stage_names[OBS_MAX_STAGES]; /* static strings */
  double stage_ms[OBS_MAX_STAGES];
  /* Per-patch outputs (OBS_OUTPUT_PATCH): the technique initialises patches[0..npatches) with
   * obs_patches_init (name = the output's) and renders them into its image's "<name>" channel
   * with obs_patches_render; the result takes them over. Points into the result; never NULL. */
  obs_patches *patches;
  int npatches;
  /* Added with obs_render_ctx_warn, from the thread that called the run function only. */
  int nwarnings;
  char warnings[OBS_MAX_WARNINGS][OBS_WARNING_LEN];
} obs_render_ctx;

/* Records one named stage's time (ignored past OBS_MAX_STAGES). */
void obs_render_ctx_stage(obs_render_ctx *ctx, const char *name, double ms);
/* Adds one warning (printf-style; truncated to OBS_WARNING_LEN; the same text twice is kept once;
 * ignored past OBS_MAX_WARNINGS). Not thread-safe: call it outside the tile loop. */
void obs_render_ctx_warn(obs_render_ctx *ctx, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Runs one technique on one backend and fills `out` (initialised by the callee). */
typedef int (*obs_technique_run_fn)(obs_render_ctx *ctx, obs_image *out, obs_err *err);
/* Cross-field parameter checks beyond the params schema; adds "<pointer>: <rule>" problems. */
typedef void (*obs_technique_check_fn)(const obs_scene *scene, const json_t *params,
                                       const char *docname, obs_err *err);

/* How a reference rt_ao image is put through a candidate technique's response curve before the
 * two are compared: screen-space techniques estimate a function of the obscurance W, not W. */
typedef enum {
  OBS_RESPONSE_IDENTITY = 0,  /* compare with W itself */
  OBS_RESPONSE_SSAO_SPHERE,   /* ssao, whole sphere: W^2/4 + W/2 */
  OBS_RESPONSE_SSAO_HEMI,     /* ssao, normal_oriented: min(1, W^2 + W) */
  OBS_RESPONSE_COUNT
} obs_response;

/* Scene facts the reference hooks may need, computed at most once per scene and shared across
 * calls (so a sweep of many candidates traces the scene once). Zero it before the first call. */
typedef struct obs_reference_facts {
  int have_z_median;
  double z_median; /* median linear view depth of the covered pixels (coarse primary-ray pass) */
} obs_reference_facts;

/* A technique's reference hook: fills `rt_ao_params` (an empty object) with the rt_ao parameters
 * that define the same AO as the technique with `params` (defaults filled) on `scene`: weighting,
 * falloff, max_distance and tau only (the caller adds samples and seed), and sets `*response`. */
typedef int (*obs_technique_reference_fn)(const obs_scene *scene, const json_t *params,
                                          obs_reference_facts *facts, json_t *rt_ao_params,
                                          obs_response *response, obs_err *err);

/* A parameter whose guaranteed range is narrower than its schema's. The bound applies to
 * value / size^size_power, size being the scene size of obs_range: 1 for lengths (a radius in
 * scene units is stated in scene sizes), -1 for rates per scene unit, 0 for pure numbers. */
typedef struct obs_param_range {
  const char *name; /* key in the technique's params; NULL ends the list */
  double min, max;
  int size_power;
} obs_param_range;

#define OBS_MAX_PARAM_RANGES 4
/* The unit a parameter's bounds are stated in: "scene sizes", "per scene size" or "". */
const char *obs_param_range_unit(const obs_param_range *p);

/* How far a render inside the range may differ from the same view rendered at scale 1 at the
 * origin (the scene and every length parameter scaled, everything translated): over the covered
 * pixels, mean |d ao| <= ao_mean, and all but `share` of them have |d ao| <= ao_pixel, every
 * normal component within `normal` and linear depth (divided by the scale) within depth_rel of
 * the scale-1 depth, relative. Coverage (alpha) is equal. */
typedef struct obs_tolerance {
  double ao_mean, ao_pixel, share, normal, depth_rel;
} obs_tolerance;

/* The range over which one backend of a technique guarantees its output: finite, in range, and
 * equal to the scale-1 result within `tol` (docs/accuracy.md, "Guaranteed ranges").
 *  - size: the diagonal of the axis-aligned bounding box of the transformed geometry, in scene
 *    units. Float arithmetic fails at absolute magnitudes (squared lengths over- or underflow),
 *    so the guarantee is stated on the size itself.
 *  - translation: max(|camera position|, |bounds centre|) / size, the distance from the world
 *    origin in scene sizes. What a far-off scene loses is the relative precision of its
 *    coordinates (an absolute error |p| eps spread over a scene of that size), so the ratio,
 *    not the distance, is what bounds the error.
 *  - fov_min, fov_max: the perspective camera's fov_y in degrees; `orthographic` is 1 when
 *    orthographic cameras are held to the same guarantee.
 * A zero size_max marks a backend without a declared range. */
typedef struct obs_range {
  double size_min, size_max;
  double translation_max;
  double fov_min, fov_max;
  int orthographic;
  obs_param_range params[OBS_MAX_PARAM_RANGES + 1];
  obs_tolerance tol;
} obs_range;

/* What one output holds; its EXR channels follow from the name and the kind. */
typedef enum {
  OBS_OUTPUT_SCALAR = 0, /* one value per pixel: channel "<name>" */
  OBS_OUTPUT_VECTOR,     /* a direction per pixel: channels "<name>.X", ".Y", ".Z" */
  OBS_OUTPUT_RGB,        /* linear radiance per pixel: channels "<name>.R", ".G", ".B" */
  OBS_OUTPUT_DEPTH,      /* linear view depth per pixel: channel "<name>.Z" */
  /* One value per patch of the scene (a triangle, numbered in the order geometry.c emits them),
   * stored in "<name>.patches" (obscura/patches.h) and rendered per pixel into channel "<name>"
   * by casting a primary ray per pixel. */
  OBS_OUTPUT_PATCH,
  /* A voxel grid: reserved so the registry, the API and the docs can name it; the writer has no
   * file for it yet and refuses a technique that declares one. */
  OBS_OUTPUT_VOXEL,
  OBS_OUTPUT_KIND_COUNT
} obs_output_kind;

/* How an output is shown in its PNG (background pixels, alpha <= 0 when the image has an alpha
 * channel, are black except for GREY, which writes the channel as it is). */
typedef enum {
  OBS_SHOW_NONE = 0,  /* no PNG */
  OBS_SHOW_GREY,      /* the value clamped to [0, 1], linear */
  OBS_SHOW_FALSE,     /* false colour: the covered pixels' [min, max] over a blue-to-yellow ramp */
  OBS_SHOW_NORMAL,    /* RGB = n * 0.5 + 0.5 */
  OBS_SHOW_DEPTH,     /* nearest covered pixel white, farthest 0.1 grey, linear between */
  OBS_SHOW_TONEMAP,   /* value * 2^exposure, clamped, sRGB transfer curve */
  OBS_SHOW_COUNT
} obs_output_show;

enum {
  OBS_OUTPUT_PRIMARY = 1 << 0 /* the output metrics and comparisons use; one per technique */
};

/* Longest output name: "<name>.patches" and "<name>_stderr.X" stay within the 32 bytes the
 * server's output records and the EXR channel names hold. */
#define OBS_OUTPUT_NAME_MAX 20

/* One declared output. The writer, the EXR layers, the PNGs, summary.json's statistics, the
 * server's file allow-list, the API enums and the dashboard captions all follow from the table. */
typedef struct obs_output {
  const char *name;        /* NULL ends a technique's table; at most OBS_OUTPUT_NAME_MAX chars */
  obs_output_kind kind;
  obs_output_show show;
  const char *png;         /* PNG file name ("ao.png"), or NULL for none */
  const char *description; /* the dashboard's caption */
  unsigned flags;          /* OBS_OUTPUT_* */
  const char *stderr_of;   /* names the output this one is the per-pixel standard error of */
  const char *exposure;    /* OBS_SHOW_TONEMAP: the parameter holding the exposure in EV (a number
                              in the technique's params); NULL or absent = 0 EV */
} obs_output;

#define OBS_OUTPUT_MAX_CHANNELS 3
/* The EXR channel names of `o` (at most OBS_OUTPUT_MAX_CHANNELS, written into `names`, each up to
 * OBS_CHANNEL_NAME_MAX bytes); returns their count, 0 for a voxel output (no channels). */
int obs_output_channels(const obs_output *o, char names[][OBS_CHANNEL_NAME_MAX]);
/* "scalar", "vector", "rgb", "depth", "patch", "voxel"; and the show names "none", "grey",
 * "false_colour", "normal", "depth", "tonemap". */
const char *obs_output_kind_name(obs_output_kind k);
const char *obs_output_show_name(obs_output_show s);

typedef struct obs_technique {
  const char *name;
  const char *description;
  const char *params_schema;    /* JSON Schema (object with properties, types, ranges, defaults) */
  unsigned needs;               /* OBS_NEED_* */
  const obs_output *outputs;    /* ended by an entry with a NULL name; exactly one primary */
  obs_technique_check_fn check; /* may be NULL */
  obs_technique_reference_fn reference; /* may be NULL: the technique cannot be compared */
  obs_technique_run_fn run[OBS_BACKEND_COUNT]; /* indexed by obs_backend; NULL = not available */
  obs_range range[OBS_BACKEND_COUNT]; /* guaranteed range of each backend that has a run */
} obs_technique;

/* The technique's primary output (never NULL for a registered technique). */
const obs_output *obs_technique_primary(const obs_technique *t);
/* The output named `name`, or NULL. */
const obs_output *obs_technique_output(const obs_technique *t, const char *name);
/* The EXR file of `t`'s results: "<primary>.exr" into buf. */
void obs_technique_exr_name(const obs_technique *t, char *buf, size_t n);
/* The per-patch file of `o`: "<name>.patches" into buf. */
void obs_output_patch_file(const obs_output *o, char *buf, size_t n);

#define OBS_OUTPUT_FILE_MAX 64
/* The files a result of `t` holds, in the order the writer lists them: "<primary>.exr", each PNG,
 * each per-patch file, "summary.json". Returns the count (at most `max` are filled). */
size_t obs_technique_files(const obs_technique *t, char names[][OBS_OUTPUT_FILE_MAX], size_t max);
/* The union of obs_technique_files over every registered technique, first occurrence first:
 * the names a server may record and serve for a job. */
size_t obs_output_file_names(char names[][OBS_OUTPUT_FILE_MAX], size_t max);
/* Content type of an output file by its extension (.exr, .png, .json, .patches), or NULL. */
const char *obs_output_content_type(const char *file);

size_t obs_technique_count(void);
const obs_technique *obs_technique_at(size_t i);
const obs_technique *obs_technique_find(const char *name);
/* Whether `t` runs on `backend` in this build and on this machine. */
int obs_technique_has_backend(const obs_technique *t, obs_backend backend);
/* Resolves AUTO to a concrete backend. Returns OBS_EUNSUPPORTED if none is available. */
int obs_technique_pick_backend(const obs_technique *t, obs_backend requested, obs_backend *out,
                               obs_err *err);
const char *obs_backend_name(obs_backend b);
/* The reference definition of `t` with `params` on `scene` (see obs_technique_reference_fn):
 * *rt_ao_params is a new object owned by the caller. `facts` may be NULL (nothing is cached).
 * OBS_EUNSUPPORTED when the technique has no reference hook. */
int obs_technique_reference(const obs_technique *t, const obs_scene *scene, const json_t *params,
                            obs_reference_facts *facts, json_t **rt_ao_params,
                            obs_response *response, obs_err *err);
/* "identity", "ssao_sphere", "ssao_hemi" (stored by the server), and back (-1 when unknown). */
const char *obs_response_name(obs_response r);
int obs_response_parse(const char *name, obs_response *out);
/* The response curve f(W). */
float obs_response_map(obs_response r, float w);
/* Maps channel "ao" of `img` in place through f, and scales "ao_stderr" (when present) by
 * |f'(W)| so the reference's noise is stated in the mapped units (first-order propagation). */
int obs_response_apply(obs_response r, obs_image *img, obs_err *err);

/* The registry as a JSON array (new reference, caller owns); each entry's "ranges" holds the
 * guaranteed range of each backend (obs_range). */
json_t *obs_technique_registry_json(void);
/* The guaranteed ranges of every technique and backend as a Markdown table (docs/accuracy.md
 * holds a copy that a test compares); new string, free() it. */
char *obs_technique_ranges_markdown(void);

#ifdef __cplusplus
}
#endif
#endif
