/* proximity_ao on Vulkan: the rasterised G-buffer with object ids (gbuffer_vk.c: the object's
 * index in the albedo target's alpha) in place of the CPU's ray-cast hits, then the walk along
 * each pixel's normal as a compute pass (shaders/proximity_ao.comp.glsl) over every field, the
 * fields packed into one 3D texture read texel by texel. The fields themselves were built by the
 * framework and flooded on this device (obs_prox_flood_vulkan, the CPU's bits). Analytic spheres
 * are drawn tessellated, so their pixels take the ray's hit on the true sphere in the pass, with
 * its normal, as the CPU's ray caster does; the depth and normal outputs are the pass's.
 *
 * Precision: the shader sees no world coordinates. Each field's world-to-grid map is composed on
 * the host in double with the camera frame (the grid coordinates of the camera's origin, and the
 * grid images of its axes and of the world axes times the step length), so a pixel's grid point
 * is its camera-relative depth and image position through one float map, whatever the scene's
 * size and distance from the origin.
 *
 * The push block, the image bindings and the parameter buffer's rows are layout.h's, which the
 * shader includes too.
 *
 * One shading sample per pixel, at its centre (the G-buffer's): image.spp is not used here. Moving
 * scenes (motion) render on the CPU only (the descriptor's motion_backends). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "geometry.h"
#include "layout.h"
#include "obscura/render.h"
#include "plan_vk.h"
#include "session_vk.h"
#include "proximity_ao.h"
#include "shaders.h"
#include "techniques.h"
#include "vk.h"
#include "volume_textures_vk.h"

/* The parameter buffer's header rows (layout.h) as proximity.h's limits size them. */
_Static_assert(OBS_PROX_H_DISC == OBS_PROX_H_FIRST + (OBS_PROX_MAX_STEPS + 4) / 4 &&
                   OBS_PROX_H_COUNT == OBS_PROX_H_DISC + OBS_PROX_DISC_POINTS / 2,
               "layout.h's header rows against the disc table's size");
_Static_assert(sizeof(obs_prox_recon_push) <= OBS_VK_PUSH_MAX,
               "push constants past the device layer's");

/* Loop iterations per invocation and dispatch where the device sets no limit: bounds a dispatch's
 * length on GPUs. */
#define ITERS_UNLIMITED (1 << 20)

typedef struct job {
  const obs_scene *sc;
  const obs_prox_fields *fs;
  const obs_geometry *geo; /* camera-relative (built at the rig's origin) */
  obs_proximity_ao_params p;
  obs_prox_recon recon;
  obs_camera_rig rig;
  obs_region rg;  /* the region rendered */
  obs_image *out; /* the render's image */
} job;

/* What the device holds for one render. */
typedef struct dev {
  obs_vk_gbuffer gb;
  obs_vk_texture *atlas;
  int (*at)[3]; /* each field's corner in the atlas */
  obs_vk_data *params;
} dev;

static void dev_free(obs_vk *vk, dev *d) {
  obs_vk_gbuffer_free(vk, &d->gb);
  obs_vk_texture_free(vk, d->atlas);
  obs_vk_data_free(vk, d->params);
  free(d->at);
  memset(d, 0, sizeof *d);
}

static void put4(float *row, double a, double b, double c, double d) {
  row[0] = (float)a, row[1] = (float)b, row[2] = (float)c, row[3] = (float)d;
}

/* Packs every field into one 3D texture and uploads them (a zero 1x1x1 one when there are none:
 * the pass's descriptor needs a texture). */
static int upload_fields(obs_vk *vk, const obs_prox_fields *fs, dev *d, obs_err *err) {
  size_t n = fs->n;
  int(*dims)[3] = calloc(n ? n : 1, sizeof *dims);
  d->at = calloc(n ? n : 1, sizeof *d->at);
  if (!dims || !d->at) {
    free(dims);
    return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for the proximity fields");
  }
  for (size_t i = 0; i < n; i++) memcpy(dims[i], fs->f[i].dims, sizeof dims[i]);
  int max = obs_vk_texture_max_side(vk, OBS_VK_TEXTURE_3D), total[3] = {1, 1, 1}, rc = 0;
  long bad = obs_vk_atlas_pack((const int(*)[3])dims, n, max, d->at, total);
  if (bad >= 0) {
    const int *b = dims[bad];
    rc = obs_err_set(err, OBS_EUNSUPPORTED,
                     "vulkan: /objects/%zu: its proximity field of %dx%dx%d voxels does not fit, "
                     "with the fields before it, in one 3D texture of sides at most %d on \"%s\"; "
                     "lower /technique/params/volume_res",
                     fs->f[bad].object, b[0], b[1], b[2], max, obs_vk_device_name(vk));
    goto done;
  }
  obs_vk_texture_desc desc = {OBS_VK_TEXTURE_3D, total[0], total[1], total[2], 1, 0};
  if ((rc = obs_vk_texture_create(vk, &desc, &d->atlas, err))) goto done;
  for (size_t i = 0; i < n && !rc; i++)
    rc = obs_vk_texture_upload(vk, d->atlas, d->at[i], dims[i], fs->f[i].value, err);
done:
  free(dims);
  return rc;
}

/* Field i's rows: its frame-0 world-to-grid map composed with the camera frame in double. */
static void put_field(float *r, const job *jb, size_t i, const int at[3]) {
  const obs_prox_field *f = &jb->fs->f[i];
  const obs_camera_rig *rig = &jb->rig;
  double m[3][4], h = obs_proximity_ao_step(&jb->p, jb->fs->rp), o[3], gf[3], gr[3], gu[3];
  obs_prox_world_to_grid(f, &jb->sc->objects[f->object], 0, m);
  for (int k = 0; k < 3; k++) {
    o[k] = m[k][3], gf[k] = 0, gr[k] = 0, gu[k] = 0;
    for (int j = 0; j < 3; j++) {
      o[k] += m[k][j] * rig->origin[j];
      gf[k] += m[k][j] * rig->forward[j];
      gr[k] += m[k][j] * rig->right[j];
      gu[k] += m[k][j] * rig->up[j];
    }
  }
  put4(r + 4 * OBS_PROX_F_ORIGIN, o[0], o[1], o[2], (double)f->object);
  put4(r + 4 * OBS_PROX_F_FWD, gf[0], gf[1], gf[2], at[0]);
  put4(r + 4 * OBS_PROX_F_RIGHT, gr[0], gr[1], gr[2], at[1]);
  put4(r + 4 * OBS_PROX_F_UP, gu[0], gu[1], gu[2], at[2]);
  /* Column j: the grid image of world axis j times the step R / N (the CPU maps n h the same). */
  for (int j = 0; j < 3; j++)
    put4(r + 4 * (OBS_PROX_F_NX + j), m[0][j] * h, m[1][j] * h, m[2][j] * h, f->dims[j]);
}

/* The whole parameter buffer (malloc'd, *rows rows of 4 floats). */
static float *build_params(const job *jb, const dev *d, size_t *rows) {
  size_t objects = OBS_PROX_H_COUNT + jb->fs->n * OBS_PROX_F_COUNT;
  *rows = objects + (jb->sc->nobjects ? jb->sc->nobjects : 1);
  float *b = calloc(*rows * 4, sizeof *b);
  if (!b) return NULL;
  const obs_camera_rig *rig = &jb->rig;
  const obs_prox_recon *rc = &jb->recon;
  put4(b + 4 * OBS_PROX_H_RIGHT, rig->right[0], rig->right[1], rig->right[2], rig->half_w);
  put4(b + 4 * OBS_PROX_H_UP, rig->up[0], rig->up[1], rig->up[2], rig->half_h);
  put4(b + 4 * OBS_PROX_H_FWD, rig->forward[0], rig->forward[1], rig->forward[2], rig->ortho);
  put4(b + 4 * OBS_PROX_H_RECON, rc->stop_value, rc->scale_before, rc->scale_after, 0);
  for (int i = 0; i <= rc->steps; i++) b[4 * OBS_PROX_H_FIRST + i] = (float)rc->first[i];
  memcpy(b + 4 * OBS_PROX_H_DISC, rc->disc, sizeof rc->disc);
  for (size_t i = 0; i < jb->fs->n; i++)
    put_field(b + 4 * (OBS_PROX_H_COUNT + i * OBS_PROX_F_COUNT), jb, i, d->at[i]);
  for (size_t s = 0; s < jb->geo->nspheres; s++) {
    const obs_sphere *sp = &jb->geo->spheres[s];
    double c[3], v[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) c[k] = sp->center[k] + (jb->geo->origin[k] - rig->origin[k]);
    for (int k = 0; k < 3; k++) {
      v[0] += c[k] * rig->right[k];
      v[1] += c[k] * rig->up[k];
      v[2] += c[k] * rig->forward[k];
    }
    put4(b + 4 * (objects + sp->object), v[0], v[1], v[2], sp->radius);
  }
  return b;
}

static void progress(obs_render_ctx *ctx, double fraction) {
  if (ctx->progress) ctx->progress(ctx->progress_user, fraction);
}

/* Fields per dispatch: as many as the device's loop limit allows one invocation to walk, at
 * least one. llvmpipe counts a loop's iterations plus the pass that leaves it, so a field costs
 * its steps, its disc points, a pass out of each step's disc loop and of the step loop, and its
 * turn of the loop over fields. */
static int fields_per_dispatch(obs_vk *vk, const job *jb) {
  uint32_t limit = obs_vk_loop_limit(vk);
  double budget = limit ? (double)limit - 1024 : ITERS_UNLIMITED;
  double per = 2.0 * jb->recon.steps + jb->recon.first[jb->recon.steps] + 2;
  double n = floor(budget / per);
  return n < 1 ? 1 : n > 1e6 ? 1000000 : (int)n;
}

/* The dispatches over the region, a chunk of fields each, then its two images read back into px
 * (per pixel, 4 floats of each): acc (occlusion sum, product of (1 - a), fields, ao) and surf
 * (world normal, view depth). `t` gets the stages "shade" and "readback". */
static int shade(obs_render_ctx *ctx, obs_vk *vk, const job *jb, const obs_region *rg, const dev *d,
                 float *px, obs_vk_plan_times *t, obs_err *err) {
  int per = fields_per_dispatch(vk, jb), nf = (int)jb->fs->n;
  int chunks = nf ? (nf + per - 1) / per : 1;
  obs_prox_recon_push pc = {.region = {rg->x0, rg->y0, rg->x1 - rg->x0, rg->y1 - rg->y0},
                            .size = {jb->sc->width, jb->sc->height},
                            .steps = jb->recon.steps,
                            .mode = jb->recon.mode,
                            .combine = jb->p.combine,
                            .self_occlusion = jb->p.self_occlusion,
                            .objects = (int32_t)(OBS_PROX_H_COUNT + jb->fs->n * OBS_PROX_F_COUNT)};
  enum { ACC = OBS_VK_PLAN_IMAGE0, SURF };
  obs_vk_plan plan = {
      .technique = "proximity_ao",
      .width = pc.region[2],
      .height = pc.region[3],
      .images = {[ACC] = {.channels = 4}, [SURF] = {.channels = 4}},
      .passes = {{.stage = "shade",
                  OBS_VK_SPIRV(proximity_ao_comp),
                  OBS_VK_PUSH(pc),
                  .images = {[OBS_PROX_B_DEPTH] = OBS_VK_PLAN_DEPTH,
                             [OBS_PROX_B_NORMAL] = OBS_VK_PLAN_NORMAL,
                             [OBS_PROX_B_ALBEDO] = OBS_VK_PLAN_ALBEDO,
                             [OBS_PROX_B_ACC] = ACC,
                             [OBS_PROX_B_SURF] = SURF},
                  .textures = {d->atlas},
                  .ntextures = 1,
                  .data = d->params}},
      .downloads = {{ACC, px}, {SURF, px + 4 * (size_t)pc.region[2] * (size_t)pc.region[3]}}};
  obs_vk_plan_state s;
  int rc = obs_vk_plan_open(vk, &d->gb, &plan, &s, err);
  for (int c = 0; c < chunks && !rc; c++) {
    if ((rc = obs_driver_cancelled(ctx, err))) break;
    pc.f0 = c * per;
    pc.f1 = pc.f0 + per < nf ? pc.f0 + per : nf;
    pc.phase = (c == 0 ? OBS_PROX_PHASE_FIRST : 0) | (c + 1 == chunks ? OBS_PROX_PHASE_LAST : 0);
    if (!(rc = obs_vk_plan_dispatch(&s, err))) progress(ctx, 0.3 + 0.6 * (c + 1) / chunks);
  }
  return obs_vk_plan_close(&s, rc, t, err);
}

/* The region's AO, field counts, depths, world normals and coverage (a covered pixel's normal is
 * a unit vector, an uncovered one's 0) from what shade read back. */
static void scatter(const obs_region *rg, const float *px, obs_image *out) {
  int rw = rg->x1 - rg->x0, rh = rg->y1 - rg->y0;
  size_t n = (size_t)rw * (size_t)rh;
  float *ch[OBS_PROX_CHANNELS];
  for (int c = 0; c < OBS_PROX_CHANNELS; c++)
    ch[c] = obs_image_channel(out, obs_proximity_ao_channels[c]);
  for (size_t i = 0; i < n; i++) {
    size_t at = (size_t)(rg->y0 + (int)(i / (size_t)rw)) * (size_t)out->width + (size_t)rg->x0 +
                i % (size_t)rw;
    const float *a = px + 4 * i, *s = px + 4 * (n + i);
    ch[0][at] = a[3];
    ch[1][at] = a[2];
    ch[2][at] = s[3];
    for (int k = 0; k < 3; k++) ch[3 + k][at] = s[k];
    ch[6][at] = s[0] != 0.0f || s[1] != 0.0f || s[2] != 0.0f ? 1.0f : 0.0f;
  }
}

/* The G-buffer, the fields and the parameters on the device; timed as the render's build. */
static int dev_build(obs_render_ctx *ctx, obs_vk *vk, const job *jb, dev *d, obs_err *err) {
  double gb_ms = 0, t0 = obs_now_ms();
  int rc = obs_vk_gbuffer_render(vk, jb->sc, jb->geo, &d->gb, &gb_ms, err);
  if (rc) return rc;
  obs_driver_stage_add(ctx, "gbuffer", gb_ms);
  double t1 = obs_now_ms();
  size_t rows = 0;
  float *b = NULL;
  if (!(rc = upload_fields(vk, jb->fs, d, err)) && !(b = build_params(jb, d, &rows)))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: proximity_ao: out of memory", jb->sc->name);
  if (!rc) rc = obs_vk_data_create(vk, b, rows * 4 * sizeof *b, &d->params, err);
  free(b);
  obs_driver_stage_add(ctx, "upload", obs_now_ms() - t1);
  ctx->build_ms += obs_now_ms() - t0;
  return rc;
}

/* The render on the device (obs_vk_session_fn): geometry, G-buffer, fields and parameters, the
 * shading dispatches and the readback into the region of the image. */
static int render(obs_render_ctx *ctx, obs_vk *vk, void *user, obs_err *err) {
  job *jb = user;
  const obs_region *rg = &jb->rg;
  dev d;
  obs_geometry geo;
  float *px = NULL;
  memset(&d, 0, sizeof d);
  memset(&geo, 0, sizeof geo);
  jb->geo = &geo;
  double t0 = obs_now_ms();
  int rc = obs_geometry_build_at(jb->sc, jb->rig.origin, &geo, err);
  ctx->build_ms += obs_now_ms() - t0;
  if (rc || (rc = dev_build(ctx, vk, jb, &d, err))) goto done;
  progress(ctx, 0.3);
  double t1 = obs_now_ms();
  size_t npx = (size_t)(rg->x1 - rg->x0) * (size_t)(rg->y1 - rg->y0);
  obs_vk_plan_times t;
  if (!(px = malloc(8 * npx * sizeof *px))) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: proximity_ao: out of memory", jb->sc->name);
    goto done;
  }
  if ((rc = shade(ctx, vk, jb, rg, &d, px, &t, err))) goto done;
  double t2 = obs_now_ms();
  scatter(rg, px, jb->out);
  obs_vk_plan_record(ctx, &t);
  obs_driver_stage_add(ctx, "readback", obs_now_ms() - t2);
  ctx->render_ms = obs_now_ms() - t1;
  ctx->rays = 0;
done:
  free(px);
  dev_free(vk, &d);
  obs_geometry_free(&geo);
  jb->geo = NULL;
  return rc;
}

int obs_proximity_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  memset(out, 0, sizeof *out);
  if (!ctx->prepared)
    return obs_err_set(err, OBS_EINTERNAL, "%s: proximity_ao: no fields were built for it",
                       sc->name);
  /* The G-buffer carries object indices + 1 as floats, exact below 2^24. */
  if (sc->nobjects >= (1u << 24) - 1)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "%s: /objects: proximity_ao on Vulkan tells at most %u objects apart "
                       "(got %zu)",
                       sc->name, (1u << 24) - 2, sc->nobjects);
  job jb = {.sc = sc, .fs = &ctx->prepared->fields, .out = out};
  jb.p = *(const obs_proximity_ao_params *)ctx->bound;
  obs_proximity_ao_recon(&jb.p, &jb.recon);
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.rig);
  int rc = obs_driver_image(ctx, OBS_PROX_CHANNELS, obs_proximity_ao_channels, out, &jb.rg, err);
  if (rc) return rc;
  if (sc->spp > 1)
    obs_render_ctx_warn(ctx,
                        "proximity_ao on vulkan shades each pixel at its centre: image.spp "
                        "%d is not used (the cpu backend averages jittered pixel samples)",
                        sc->spp);
  if ((rc = obs_vk_session_run(ctx, "proximity_ao", render, &jb, err))) obs_image_free(out);
  return rc;
}
