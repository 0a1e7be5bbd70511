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
  OBS_NEED_GBUFFER = 1 << 3,   /* rasterised or ray-cast G-buffer */
  /* With OBS_NEED_BVH: the BVH's float frame sits at the geometry, not at the camera, when the
   * camera is far from it (renderer/cpu/raytrace.h, OBS_RT_FRAME_GEOMETRY): for techniques whose
   * camera rays start at the geometry's box rather than at an eye inside the frame. */
  OBS_NEED_BVH_FRAME_GEOMETRY = 1 << 4,
  /* Renders scenes whose objects move (object `motion`): every frame, each output holding all of
   * them (per-patch outputs frame by frame; images show the last frame). Scenes with motion are
   * refused by techniques without it. */
  OBS_NEED_MOTION = 1 << 5,
  /* Renders the scene's volume objects (shape "volume") and only them: the framework reads them
   * (ctx->volumes) and the technique ignores surface objects; techniques without it ignore
   * volumes. Either way the render warns about what it ignored, and a scene with nothing the
   * technique renders is refused. */
  OBS_NEED_VOLUME = 1 << 6,
  /* Shades with the scene's point and directional lights (techniques without it refuse them:
   * they light with quad lights, or with none). */
  OBS_NEED_PUNCTUAL_LIGHTS = 1 << 7,
  /* Lights with an environment map (environment "latlong", "faces" or "sky"), read by the
   * framework (ctx->environment); techniques without it refuse those and take a colour only. */
  OBS_NEED_ENV_MAP = 1 << 8,
  /* Reads per-object proximity fields: declared for the registry and the API; the technique
   * builds them itself through its prepare hook (proximity_ao: renderer/techniques/proximity_ao/
   * proximity.h). */
  OBS_NEED_PROXIMITY = 1 << 9,
  /* Scatters light inside objects filled with a medium (material.medium): a scene where no
   * object has one is refused; techniques without it ignore media. */
  OBS_NEED_MEDIUM = 1 << 10
};

/* What one technique prepares for its own run through its prepare hook: a type each technique
 * that has the hook defines in its folder (struct obs_prepared { ... }), opaque to the framework,
 * which only hands it from prepare to the run (ctx->prepared) and to release. */
typedef struct obs_prepared obs_prepared;
struct obs_rt;
struct obs_scene_volumes;
struct obs_env;

typedef void (*obs_progress_fn)(void *user, double fraction);

#define OBS_MAX_STAGES 16
/* Warnings a render may attach to its result: the scene lies outside the range over which the
 * technique's output is guaranteed (docs/accuracy.md), or a parameter is suspicious. */
#define OBS_MAX_WARNINGS 8
#define OBS_WARNING_LEN 320
/* Per-patch outputs one render may carry. */
#define OBS_MAX_PATCH_OUTPUTS 4

/* Per-stage timings in milliseconds. */
/* A rectangle of pixels [x0, x1) x [y0, y1) of the image. All zero: the whole image. */
typedef struct obs_region {
  int x0, y0, x1, y1;
} obs_region;

/* Who watches the per-pixel driver fill its image (obscurad's preview of a running job). `tile`
 * is called from the render thread that shaded a tile, once its pixels in `img` (the driver's
 * full-size image) are final: the watcher may read those pixels from any thread until `end`,
 * which the driver calls once after the last tile, before `img` is returned or freed; `end`
 * returns only when the watcher has stopped reading. Both must be cheap (a lock and an append):
 * `tile` runs inside the timed shading loop. */
typedef struct obs_tile_watch {
  void (*tile)(void *user, const obs_image *img, const obs_region *tile);
  void (*end)(void *user, const obs_image *img);
  void *user;
} obs_tile_watch;

/* Where the per-pixel driver takes its tiles when one render is split across processes (the
 * CLI's MPI ranks: docs/mpi.md): instead of every tile of the region, the tiles `next` hands out,
 * and after each one `done`. Borrowed by the render; `user` is the source's.
 * Thread safety: `next` and `done` are called from any of the render's threads, concurrently; the
 * source serialises itself.
 * - next: the next tile into *tile (non-empty, inside the render's region; any size, any order):
 *   returns 1, or 0 when there are no more, or a negative OBS_E* code, which stops the render
 *   with that code.
 * - done (may be NULL): the tile's pixels are written into `img` (the driver's full-size image,
 *   borrowed for the call: other threads write other tiles of it meanwhile) and it traced `rays`;
 *   returns 0, or a negative OBS_E* code, which stops the render.
 * The driver reports no progress while it takes tiles from a source (it cannot know how many
 * there are): the source sees every tile. Cancellation still stops it between tiles. */
typedef struct obs_tile_source {
  int (*next)(void *user, obs_region *tile);
  int (*done)(void *user, const obs_image *img, const obs_region *tile, uint64_t rays);
  void *user;
} obs_tile_source;

/* Timings mean the same on every technique and backend (docs/architecture.md, "Timings"):
 * build_ms is what the framework builds for the technique's `needs` (geometry, BVH, G-buffer),
 * render_ms the technique's own work on it (its per-pixel loop or passes, with their readback). */
typedef struct obs_timings {
  double load_ms, build_ms, render_ms, write_ms, total_ms;
} obs_timings;

/* Everything a technique implementation receives. Borrowed for the duration of the call. */
typedef struct obs_render_ctx {
  const obs_scene *scene;
  const json_t *params;        /* defaults filled in */
  const void *bound;           /* params bound to the technique's C struct (obs_params_bind) */
  int threads;                 /* >= 1 */
  obs_progress_fn progress;    /* may be NULL; called with fractions in [0,1], from any thread */
  void *progress_user;
  const atomic_int *cancel;    /* may be NULL; nonzero asks the technique to stop between tiles */
  /* The pixels to render; all zero: the whole image. The image is always full size: pixels
   * outside the region are 0 in every channel (the seam for renders split across processes). */
  obs_region region;
  /* NULL, or where the per-pixel driver takes its tiles (obs_render_opts.tiles); the driver sets
   * `tiled` when it did. Runs that do not go through the per-pixel driver ignore both: a caller
   * learns from `tiled` (obs_result.tiled) whether the technique rendered per pixel. */
  const obs_tile_source *tiles;
  int tiled;
  /* NULL, or who watches the per-pixel driver's tiles (obs_render_opts.watch). */
  const obs_tile_watch *watch;
  /* Built by the framework before the run for the technique's `needs`, owned by it: on the CPU
   * backend, for OBS_NEED_BVH, the BVH (renderer/cpu/raytrace.h); else NULL. */
  const struct obs_rt *rt;
  /* For OBS_NEED_VOLUME, on every backend: the scene's volumes (renderer/core/volume_scene.h),
   * read by the framework and owned by it; else NULL. */
  const struct obs_scene_volumes *volumes;
  /* For OBS_NEED_ENV_MAP: the scene's environment as a cube map (renderer/core/environment.h),
   * read by the framework and owned by it; NULL when the scene has none. */
  const struct obs_env *environment;
  /* What the technique's own prepare hook built for this run (its own type), owned by the
   * framework until its release hook; NULL without the hook. */
  const obs_prepared *prepared;
  /* Filled by the framework and the drivers (see obs_timings): */
  double build_ms;             /* what the framework builds for `needs` */
  double render_ms;            /* the technique's pixels or passes */
  uint64_t rays;               /* rays traced (primary + secondary) */
  /* Finer stages (e.g. "gbuffer", "ao", "blur", "readback"), added with obs_render_ctx_stage. */
  int nstages;
  const char *stage_names[OBS_MAX_STAGES]; /* static strings */
  double stage_ms[OBS_MAX_STAGES];
  /* Per-patch outputs (OBS_OUTPUT_PATCH): the technique initialises patches[0..npatches) with
   * obs_patches_init (name = the output's) and renders them into its image's "<name>" channel
   * with obs_patch_show (renderer/cpu/patch_ids.h); the result takes them over. Points into the
   * result; never NULL. */
  obs_patches *patches;
  int npatches;
  /* A scene with moving objects: what each frame took, one JSON object per frame (the technique
   * says which figures), for summary.json's "frames"; NULL otherwise. The result takes it over. */
  json_t *frames;
  /* What was built for this render (its needs, and a run's own copies), one object per
   * structure: its "name", "bytes" and the figures that size it, for summary.json's "built".
   * The framework creates the array and adds what it builds; a run may append. The result takes
   * it over. */
  json_t *built;
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

/* How a reference image's primary output is put through a candidate technique's response curve
 * before the two are compared: screen-space techniques estimate a function of the obscurance W,
 * not W. Curves apply to scalar primary outputs; other kinds take IDENTITY. */
typedef enum {
  OBS_RESPONSE_IDENTITY = 0,  /* compare with the reference's output itself */
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

/* What a candidate is judged against: a registered technique (rt_ao for the AO techniques,
 * path_trace for RGB ones, later a volume reference), its parameters and the response mapping.
 * The reference technique's `reference_quality` parameter and "seed" are left to the caller (a
 * comparison's reference.samples and reference.seed). */
typedef struct obs_reference_def {
  const struct obs_technique *technique;
  json_t *params;        /* owned */
  obs_response response;
  /* The candidate's output compared with the reference's primary one: NULL for the candidate's
   * primary output, else an obs_reference_alt's. */
  const char *output;
} obs_reference_def;

/* Another reference a candidate may be compared with, on request (a comparison candidate's
 * "against"): one of the candidate's outputs against another technique's primary output, e.g.
 * obscurance's W without colour bleeding against rt_ao with the same falloff. */
typedef struct obs_reference_alt {
  const struct obs_technique *technique; /* the reference technique; NULL ends a list */
  const char *output;          /* the candidate's output compared (its per-pixel channel) */
  /* Pairs (candidate parameter, reference parameter), NULL-terminated: the values copied. */
  const char *const *keys;
  /* A boolean parameter of the candidate that must be false for the outputs to be the same
   * quantity (obscurance's color_bleeding: W is RGB with it); NULL: none. */
  const char *needs_false;
} obs_reference_alt;

/* Another output of a candidate compared with an output of the candidate's own reference job,
 * beside the primary one (a comparison measures it as a row of its own; the metric follows from
 * the output's kind: the mean angle between directions for vector outputs). */
typedef struct obs_output_pair {
  const char *output;           /* the candidate's output; NULL ends a list */
  const char *reference_output; /* the reference technique's output it is compared with */
} obs_output_pair;

/* A technique's reference hook: sets def->technique and def->response and fills def->params (an
 * empty object) with the reference technique's parameters that define the same quantity as the
 * technique with `params` (defaults filled) on `scene`. */
typedef int (*obs_technique_reference_fn)(const obs_scene *scene, const json_t *params,
                                          obs_reference_facts *facts, obs_reference_def *def,
                                          obs_err *err);

/* A parameter whose guaranteed range is narrower than its schema's. The bound applies to
 * value / size^size_power, size being the scene size of obs_range: 1 for lengths (a radius in
 * scene units is stated in scene sizes), -1 for rates per scene unit, 0 for pure numbers. */
typedef struct obs_param_range {
  const char *name; /* key in the technique's params; NULL ends the list */
  double min, max;
  int size_power;
} obs_param_range;

#define OBS_MAX_PARAM_RANGES 4
/* A length parameter (size_power 1) below OBS_LENGTH_TINY or above OBS_LENGTH_HUGE scene sizes
 * renders, but hardly ever as meant (every pixel open, or every pixel occluded): the render says
 * so in a warning (obs_range_check). */
#define OBS_LENGTH_TINY 1e-3
#define OBS_LENGTH_HUGE 10.0
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

/* How far a screen-space technique's samples reach around a covered pixel at linear view depth
 * z: `pixels`, how far across the screen its farthest sample reaches, in the pixels (texels of
 * the level it samples) it reads; `depth`, that sample's reach along the view axis over the
 * smallest depth difference its depth test resolves. Under 1 either way its samples cannot see
 * the geometry: the answer no longer depends on it. */
typedef struct obs_screen_reach {
  double pixels, depth;
} obs_screen_reach;

/* The screen-space rule of a length parameter (docs/accuracy.md, "Screen-space radius"): `reach`
 * gives obs_screen_reach for the bound params, the G-buffer's camera and a depth z (> 0); neither
 * figure may grow with z. Where a covered pixel's reach is under one pixel or one depth step the
 * render warns (obs_screen_rule_check): the share of the covered pixels, what the image reads
 * there (`below_pixel`, `below_depth`) and the smallest value of `param` that reaches one of each
 * at every covered pixel. With `pixel_decides` a pixel under one pixel reads below_pixel whatever
 * its depth reach (hbao's early exit), so only the others are held to the depth step. */
struct obs_gbuffer;
typedef struct obs_screen_rule {
  const char *param;
  void (*reach)(const void *bound, const struct obs_gbuffer *g, double z, obs_screen_reach *out);
  const char *below_pixel, *below_depth;
  int pixel_decides;
} obs_screen_rule;

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
  /* Screen-space techniques: the rule their radius is held to on the G-buffer; NULL: none. */
  const obs_screen_rule *screen;
  obs_tolerance tol;
} obs_range;

/* ---- parameters ------------------------------------------------------------------------------
 * A technique declares its parameters once, as a table of obs_param. From it come the validation
 * of scene documents (messages with JSON pointers), the binding of a validated params object into
 * the technique's C struct (obs_params_bind, before `run`), the registry's "params_schema", the
 * technique part of schema/scene.schema.json, the tables of docs/techniques/ and the OpenAPI
 * block of schema/openapi.yaml. */
typedef enum obs_param_type {
  OBS_PARAM_BOOL,   /* JSON boolean; stored as int (0 or 1) */
  OBS_PARAM_INT,    /* JSON integer (an integral real such as 8.0 counts); stored as int32_t */
  OBS_PARAM_UINT,   /* JSON integer; stored as uint32_t */
  OBS_PARAM_FLOAT,  /* JSON number; stored as float, rounded once */
  OBS_PARAM_DOUBLE, /* JSON number; stored as double */
  OBS_PARAM_ENUM,   /* JSON string, one of `choices`; stored as int, the index of the choice */
  OBS_PARAM_RGB,    /* JSON array of 3 numbers (R, G, B), each in the range; stored as double[3] */
  /* JSON array of distinct names of the scene's objects (each must name one), or null (the
   * default: every object); stored as obs_param_names. Its range is the scene's: the
   * conformance suite renders it null and as the empty list. */
  OBS_PARAM_NAMES
} obs_param_type;

/* A bound OBS_PARAM_NAMES: `count` names (-1: null, every object), each NUL-terminated, one after
 * another in `text`. The bound struct owns them (no pointer into the document). */
#define OBS_PARAM_NAMES_BYTES 1024
typedef struct obs_param_names {
  int count;
  char text[OBS_PARAM_NAMES_BYTES];
} obs_param_names;

/* Whether `name` is selected by `n`: always when n is null (count -1). */
int obs_param_names_has(const obs_param_names *n, const char *name);

enum {
  OBS_PARAM_MIN_EXCLUSIVE = 1 << 0, /* value > min rather than >= min */
  OBS_PARAM_MAX_EXCLUSIVE = 1 << 1, /* value < max rather than <= max */
  OBS_PARAM_NULLABLE = 1 << 2,      /* numbers, RGB: null is a value, bound as null_value */
  OBS_PARAM_DEFAULT_NULL = 1 << 3   /* with NULLABLE: the default is null, not `def` */
};

typedef struct obs_param {
  const char *name;
  obs_param_type type;
  unsigned flags;              /* OBS_PARAM_* */
  double min, max;             /* numbers: the accepted range (ignored when `values` is set) */
  double def;                  /* default: the number (each component of an RGB); 0/1 for a
                                  boolean; the choice's index */
  double null_value;           /* NULLABLE: what null is bound as (e.g. INFINITY = unbounded) */
  const char *const *choices;  /* ENUM: the names, NULL-terminated */
  const int *values;           /* INT: the only values accepted (a JSON Schema enum), or NULL */
  int nvalues;
  const char *description;
  size_t offset;               /* offsetof the member in the technique's params struct */
  /* A length (its obs_param_range has size_power 1): when the technique is chosen for a scene
   * that declared another, its default is this many scene sizes (obs_technique_defaults_for);
   * 0 = `def` (or null) at every scale. */
  double size_default;
} obs_param;

/* A cross-field rule between parameters: when `param` (an enum) is the choice `value`, `needs`
 * (a nullable number) must not be null. The scene loader's check and the allOf of the technique's
 * params schema both come from it. */
typedef struct obs_param_rule {
  const char *param, *value, *needs; /* param NULL ends a list */
} obs_param_rule;

/* The work of one pixel sample of a technique with bound params, in units the server's limits
 * count (docs/server.md, "Mesh import and work limits"): e.g. rays or depth-buffer taps. */
typedef double (*obs_technique_cost_fn)(const void *bound);

/* What one output holds; its EXR channels follow from the name and the kind. */
typedef enum {
  OBS_OUTPUT_SCALAR = 0, /* one value per pixel: channel "<name>" */
  OBS_OUTPUT_VECTOR,     /* a direction per pixel: channels "<name>.X", ".Y", ".Z" */
  OBS_OUTPUT_RGB,        /* linear radiance per pixel: channels "<name>.R", ".G", ".B" */
  OBS_OUTPUT_DEPTH,      /* linear view depth per pixel: channel "<name>.Z" */
  /* One value per patch of the scene (a triangle, numbered in the order geometry.c emits them,
   * or a sub-triangle of one: renderer/techniques/obscurance_map/patch_mesh.h),
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
  OBS_OUTPUT_PRIMARY = 1 << 0, /* the output metrics and comparisons use; one per technique */
  OBS_OUTPUT_UNIT = 1 << 1      /* every value lies in [0, 1] (AO, coverage); RGB is >= 0 */
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
  float background;        /* scalar and RGB outputs of techniques with an `alpha` output: the
                              value of a pixel nothing covers (an AO of 1, an open sky), which a
                              pixel partly covered mixes in by (1 - alpha); 0 by default. What
                              compositing the bricks of a data-parallel render fills in */
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
  const obs_param *params;      /* the parameter table, in the order documents list them */
  size_t params_size;           /* entries of `params` */
  size_t bound_size;            /* sizeof the C struct `params` lands in (ctx->bound) */
  /* Cross-field rules of the parameters, ended by an entry with a NULL param; NULL: none. */
  const obs_param_rule *rules;
  obs_technique_cost_fn cost;   /* NULL: 1 per pixel sample */
  /* With OBS_NEED_VOLUME: how far from a surface point the run reads the volume, in data-space
   * units of the volume hit (a brick's ghost zone, obs_render_opts.brick); NULL: 0. */
  double (*volume_reach)(const void *bound);
  /* With OBS_NEED_MOTION: the work of a scene of `frames` frames in units of one frame's, an
   * upper bound (NULL: frames). */
  double (*frames_cost)(const void *bound, int frames);
  /* With OBS_NEED_MOTION: the backends (bit 1 << obs_backend) whose runs render moving scenes;
   * a moving scene on another is refused, and backend auto picks among these. */
  unsigned motion_backends;
  /* Data only this technique needs (proximity_ao: its proximity fields), built before the run
   * for `backend` into *out with ctx->bound, ctx->scene and ctx->threads, timed in build (it may
   * add stages and entries of ctx->built), and handed to the run as ctx->prepared; release
   * frees it after the run whatever the run returned. What several techniques share (the BVH,
   * volumes, environment maps, the G-buffer) the framework builds for `needs` instead. NULL:
   * nothing to prepare. */
  int (*prepare)(obs_render_ctx *ctx, obs_backend backend, obs_prepared **out, obs_err *err);
  void (*release)(obs_prepared *prepared);
  const char *cost_rule;        /* the cost hook in words ("samples"), for the API and docs */
  /* Milliseconds per unit of work (width x height x spp x cost) on the reference machine of
   * docs/server.md, rounded up: the server's render-time estimate before it has stored runs of
   * the technique. 0: unknown (the server assumes the slowest technique's rate). */
  double ms_per_work;
  unsigned needs;               /* OBS_NEED_* */
  /* The backends (bit 1 << obs_backend) whose runs trace with Embree's kernels on their own,
   * beyond the BVH that OBS_NEED_BVH builds (instant_radiosity's virtual lights): their last bits
   * may move with the instruction-set level and CPU vendor, as those of OBS_NEED_BVH do. */
  unsigned embree_backends;
  const obs_output *outputs;    /* ended by an entry with a NULL name; exactly one primary */
  obs_technique_check_fn check; /* may be NULL */
  obs_technique_reference_fn reference; /* may be NULL: see reference_same */
  /* Without a `reference` hook: the candidate is judged against this technique given the values
   * of the NULL-terminated `reference_keys` the candidate has (obs_reference_def_same, identity
   * response). Both NULL: the technique cannot be compared. */
  const struct obs_technique *reference_same;
  const char *const *reference_keys;
  /* The other references a comparison may ask for (obs_reference_alt), ended by a NULL technique;
   * NULL: none. */
  const obs_reference_alt *reference_alts;
  /* Other outputs compared with the own reference's (obs_output_pair), ended by a NULL output;
   * NULL: none. */
  const obs_output_pair *compared_outputs;
  /* As a reference: the integer parameter a comparison's reference.samples sets (its converged
   * quality, e.g. "samples"); NULL: the technique cannot serve as a reference. */
  const char *reference_quality;
  obs_technique_run_fn run[OBS_BACKEND_COUNT]; /* indexed by obs_backend; NULL = not available */
  obs_range range[OBS_BACKEND_COUNT]; /* guaranteed range of each backend that has a run */
} obs_technique;

/* The technique's primary output (never NULL for a registered technique). */
const obs_output *obs_technique_primary(const obs_technique *t);
/* The output named `name`, or NULL. */
const obs_output *obs_technique_output(const obs_technique *t, const char *name);
/* The name of t's output that is the standard error of its output `of` (its last such), or NULL. */
const char *obs_technique_stderr_name(const obs_technique *t, const char *of);
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
/* Whether `t` runs on `backend` in this build and on this machine (obs_backend_runs). */
int obs_technique_has_backend(const obs_technique *t, obs_backend backend);
/* Resolves AUTO to a concrete backend. Returns OBS_EUNSUPPORTED if none is available. */
int obs_technique_pick_backend(const obs_technique *t, obs_backend requested, obs_backend *out,
                               obs_err *err);
/* The reference definition of `t` with `params` on `scene` (see obs_technique_reference_fn):
 * def->params is a new object owned by the caller (obs_reference_def_free). `facts` may be NULL
 * (nothing is cached). OBS_EUNSUPPORTED when the technique has no reference hook, or names a
 * reference technique that has no reference_quality. */
int obs_technique_reference(const obs_technique *t, const obs_scene *scene, const json_t *params,
                            obs_reference_facts *facts, obs_reference_def *def, obs_err *err);
/* The same against `against` (a technique name; NULL: the technique's own reference, as above):
 * one of t's reference_alts. OBS_EINVAL naming what t can be compared against when it is none of
 * them, or naming the parameter when the alternative's needs_false parameter is true. */
int obs_technique_reference_against(const obs_technique *t, const obs_scene *scene,
                                    const json_t *params, const char *against,
                                    obs_reference_facts *facts, obs_reference_def *def,
                                    obs_err *err);
/* The output of a candidate of `t` compared with a reference by `ref`: an alternative's output
 * when `ref` is one of t's reference_alts, else t's primary output. */
const obs_output *obs_technique_compared_output(const obs_technique *t, const obs_technique *ref);
void obs_reference_def_free(obs_reference_def *def);
/* For reference hooks whose reference is the candidate's own technique with more samples: copies
 * the NULL-terminated `keys` that `params` has into def->params and sets the reference technique
 * and the identity response. */
void obs_reference_def_same(obs_reference_def *def, const struct obs_technique *t,
                            const json_t *params, const char *const *keys);
/* "identity", "ssao_sphere", "ssao_hemi" (stored by the server), and back (-1 when unknown). */
const char *obs_response_name(obs_response r);
int obs_response_parse(const char *name, obs_response *out);
/* The response curve f(W). */
float obs_response_map(obs_response r, float w);
/* Maps channel "ao" of `img` in place through f, and scales "ao_stderr" (when present) by
 * |f'(W)| so the reference's noise is stated in the mapped units (first-order propagation).
 * IDENTITY leaves any image as it is. */
int obs_response_apply(obs_response r, obs_image *img, obs_err *err);

/* Validates `params` (an object with defaults filled, or raw: absent members take their
 * defaults; NULL = {}) against t's table and fills `dst`, t->bound_size bytes: every member from
 * the table, nothing else (padding is zeroed). OBS_EINVAL with "<name> params: /<key>: <rule>
 * (got <value>)" problems when a value is unknown, of the wrong type or out of range. */
int obs_params_bind(const obs_technique *t, const json_t *params, void *dst, obs_err *err);
/* The same into a new block of t->bound_size bytes (free() it); *out is NULL on failure. */
int obs_params_bind_new(const obs_technique *t, const json_t *params, void **out, obs_err *err);
/* t's parameters as the JSON Schema of a params object (new reference): the registry's
 * "params_schema". */
json_t *obs_technique_params_schema(const obs_technique *t);
/* The work per pixel sample of t with `params` (see obs_technique_cost_fn); 1 when t has no cost
 * hook, and when `params` do not bind (the loader reports those). */
double obs_technique_cost(const obs_technique *t, const json_t *params);
/* The work of rendering `sc` with its technique: width x height x spp x obs_technique_cost x
 * the frames' cost (frames_cost: a scene with moving objects renders every frame). */
double obs_scene_work(const obs_scene *sc);
/* `be` (picked for t), or, for a scene with moving objects that `be` does not render frames of,
 * the first backend of t's motion_backends that runs here (`be` again when there is none). */
obs_backend obs_technique_motion_backend(const obs_technique *t, const obs_scene *sc,
                                         obs_backend be);
/* Checks t's parameter table against itself: names unique and non-empty, enums with choices,
 * offsets inside bound_size and aligned, and every default accepted by its own range. Adds one
 * problem per fault and returns OBS_EINVAL, or 0. */
int obs_technique_params_check(const obs_technique *t, obs_err *err);

/* The params `t` starts from on the loaded `scene`, with `given` (an object, may be NULL) set over
 * them: the scene's own params when `t` is the scene's technique; otherwise t's defaults, each
 * length parameter with a size_default (size_power 1 in t's ranges) set to that many sizes of the
 * scene, so a radius or a distance fits the scene's scale. Each derived value not in `given` adds
 * a note saying so to `notes` (a JSON array of strings; may be NULL). Returns a new object, or
 * NULL after filling err. */
json_t *obs_technique_defaults_for(const obs_technique *t, const obs_scene *scene,
                                   const json_t *given, json_t *notes, obs_err *err);
/* The exponent of the scene size in the unit of t's parameter `name` (obs_param_range
 * size_power, from the first backend that declares the parameter), or 0 when none does. */
int obs_technique_param_size_power(const obs_technique *t, const char *name);

/* Texts generated from the registry, each a new string (free() it), NULL when out of memory; the
 * repository keeps copies that tests compare (scripts/gen-registry.sh writes them):
 *  - the technique members of $defs in schema/scene.schema.json;
 *  - the parameter table of docs/techniques/<name>.md (NULL for an unknown name);
 *  - the registry block of components/schemas in schema/openapi.yaml. */
char *obs_registry_scene_schema(void);
char *obs_registry_params_markdown(const char *technique);
char *obs_registry_openapi(void);

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
