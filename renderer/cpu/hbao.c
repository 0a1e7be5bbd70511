/* hbao on the CPU: the twin of renderer/vulkan/hbao_vk.c and its shaders, operation for operation.
 *
 * Every float expression here is written in the order the GLSL writes it, in float32 (no double in
 * per-pixel math, no FMA contraction in ISO C mode), so that both backends give the same bits on the
 * same G-buffer except where noted (exp in the blur). The definition is in docs/techniques/hbao.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer.h"
#include "hbao.h"
#include "obscura/render.h"
#include "parallel.h"
#include "techniques.h"

/* The texels the AO pass runs on: the full G-buffer or its half-resolution subsample. */
typedef struct hbao_level {
  int w, h, s;         /* size, and full-resolution pixels per texel (1 or 2) */
  const float *depth;  /* w*h */
  const float *normal; /* 3 per texel */
} hbao_level;

typedef struct hbao_job {
  const obs_gbuffer *g; /* full resolution: camera and, for the blur, depth */
  hbao_level lv;
  const obs_hbao_params *p;
  const float *table;
  float cos_b, sin_b;
  float falloff; /* 1 / (2 sigma^2) of the blur's Gaussian */
  const float *in;
  float *out;
  int axis;      /* blur: 0 = horizontal, 1 = vertical */
} hbao_job;

/* Elevation (sin, cos) over the view plane z = const of the tangent plane (normal n) along the image
 * direction D = (dx, dy) (view-space, y up) seen from the pixel whose ray is r (r.z = 1; nr = n.r).
 * The tangent line is the tangent plane cut by the plane through the eye that contains the pixel's
 * ray and D: L = (n.D) r - (n.r) D, oriented to move along +D in the image. A planar surface's
 * samples therefore lie exactly on L whatever the perspective. */
OBS_HOT_INLINE void tangent(const float n[3], const float r[3], float nr, float dx, float dy, float *sin_t,
                    float *cos_t) {
  float nd = n[0] * dx + n[1] * dy;
  float lx = nd * r[0] - nr * dx;
  float ly = nd * r[1] - nr * dy;
  float lz = nd;
  if (!(nr < 0.0f)) { /* back-facing by rounding: keep the orientation along +D */
    lx = -lx;
    ly = -ly;
    lz = -lz;
  }
  float h2 = lx * lx + ly * ly;
  float l = sqrtf(h2 + lz * lz);
  if (!(l > 0.0f)) {
    *sin_t = 0.0f;
    *cos_t = 1.0f;
    return;
  }
  *sin_t = -lz / l;
  *cos_t = sqrtf(h2) / l;
}

OBS_HOT_INLINE float ao_texel(const hbao_job *jb, int ax, int ay) {
  const hbao_level *lv = &jb->lv;
  const obs_hbao_params *p = jb->p;
  const obs_gbuffer *g = jb->g;
  size_t ci = (size_t)ay * (size_t)lv->w + (size_t)ax;
  float z = lv->depth[ci];
  if (!(z > 0.0f)) return 1.0f;
  float R = p->radius;
  if (!(R > 0.0f)) return 1.0f;
  float fx = (float)(lv->s * ax) + 0.5f, fy = (float)(lv->s * ay) + 0.5f;
  float P[3];
  obs_gbuffer_position(g, fx, fy, z, P);
  float r[3] = {0.0f, 0.0f, 1.0f};
  if (!g->ortho) {
    r[0] = (2.0f * fx / (float)g->width - 1.0f) * g->half_w;
    r[1] = (1.0f - 2.0f * fy / (float)g->height) * g->half_h;
  }
  /* Projected radius in texels; under one texel nothing can be sampled (early exit). */
  float num = R * (0.5f * (float)g->width);
  float rpx = g->ortho ? num / g->half_w : num / (g->half_w * z);
  float rl = rpx / (float)lv->s;
  if (!(rl >= 1.0f)) return 1.0f;
  /* Beyond the screen samples would only repeat edge texels: march at most across it. */
  float cap = (float)(lv->w > lv->h ? lv->w : lv->h);
  if (rl > cap) rl = cap;
  float st = rl / (float)(p->steps + 1);
  const float *n = lv->normal + 3 * ci;
  float nr = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
  const float *row = jb->table + (size_t)((ay & 3) * 4 + (ax & 3)) * (size_t)p->directions * 4;
  float cx = (float)ax + 0.5f, cy = (float)ay + 0.5f;
  float sum = 0.0f;
  for (int i = 0; i < p->directions; i++) {
    float dx = row[4 * i], dy = row[4 * i + 1], jit = row[4 * i + 2];
    float sin_t, cos_t;
    tangent(n, r, nr, dx, -dy, &sin_t, &cos_t);
    /* Horizon starts at t + bias; past the zenith nothing can rise above it. */
    if (!(cos_t * jb->cos_b - sin_t * jb->sin_b > 0.0f)) continue;
    float sin_h = sin_t * jb->cos_b + cos_t * jb->sin_b;
    for (int k = 1; k <= p->steps; k++) {
      float o = ((float)k + jit) * st;
      float sx = cx + o * dx, sy = cy + o * dy;
      int ix = (int)floorf(sx), iy = (int)floorf(sy);
      ix = ix < 0 ? 0 : ix > lv->w - 1 ? lv->w - 1 : ix;
      iy = iy < 0 ? 0 : iy > lv->h - 1 ? lv->h - 1 : iy;
      if (ix == ax && iy == ay) continue;
      float zs = lv->depth[(size_t)iy * (size_t)lv->w + (size_t)ix];
      if (!(zs > 0.0f)) continue; /* background */
      float S[3];
      obs_gbuffer_position(g, (float)(lv->s * ix) + 0.5f, (float)(lv->s * iy) + 0.5f, zs, S);
      /* In units of R, so huge and tiny scenes neither overflow nor underflow the square. */
      float ux = (S[0] - P[0]) / R, uy = (S[1] - P[1]) / R, uz = (S[2] - P[2]) / R;
      float d2 = ux * ux + uy * uy + uz * uz;
      if (!(d2 < 1.0f) || !(d2 > 0.0f)) continue;
      float len = sqrtf(d2);
      float sin_s = -uz / len;
      /* Texel snapping moves the sample off the direction's slice; measure its elevation against
       * the tangent in its own slice and re-base it on this direction's tangent, so points of the
       * tangent plane never count as horizon (the article hides this with the bias alone). */
      float sin_ts, cos_ts;
      tangent(n, r, nr, (float)(ix - ax), -(float)(iy - ay), &sin_ts, &cos_ts);
      float e = sin_s - sin_ts + sin_t;
      if (e > 1.0f) e = 1.0f;
      if (e > sin_h) {
        sum += (1.0f - d2) * (e - sin_h);
        sin_h = e;
      }
    }
  }
  float ao = 1.0f - p->scale * sum / (float)p->directions;
  return ao > 1.0f ? 1.0f : ao > 0.0f ? ao : 0.0f;
}

OBS_HOT_KERNEL static int ao_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) jb->out[(size_t)y * (size_t)jb->lv.w + (size_t)x] = ao_texel(jb, x, y);
  return 0;
}

/* Relative depth difference, clamped so that its square times any allowed sharpness is finite. */
OBS_HOT_INLINE float rel_dz(float z, float zc) {
  float q = fabsf(z - zc) / zc;
  return q < OBS_HBAO_MAX_REL_DZ ? q : OBS_HBAO_MAX_REL_DZ;
}

/* Depth-aware bilinear upsampling of the half-resolution AO (jb->in) to full resolution. */
static int up_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  const obs_gbuffer *g = jb->g;
  const hbao_level *lv = &jb->lv;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      float zc = g->depth[i];
      if (!(zc > 0.0f)) {
        jb->out[i] = 1.0f;
        continue;
      }
      int hx[2] = {x >> 1, (x >> 1) + (x & 1)}, hy[2] = {y >> 1, (y >> 1) + (y & 1)};
      if (hx[1] > lv->w - 1) hx[1] = lv->w - 1;
      if (hy[1] > lv->h - 1) hy[1] = lv->h - 1;
      float bx[2] = {(x & 1) ? 0.5f : 1.0f, (x & 1) ? 0.5f : 0.0f};
      float by[2] = {(y & 1) ? 0.5f : 1.0f, (y & 1) ? 0.5f : 0.0f};
      float sw = 0.0f, sa = 0.0f;
      for (int c = 0; c < 4; c++) {
        int a = c & 1, b = c >> 1;
        float wb = bx[a] * by[b];
        if (!(wb > 0.0f)) continue;
        size_t j = (size_t)hy[b] * (size_t)lv->w + (size_t)hx[a];
        float z = lv->depth[j];
        if (!(z > 0.0f)) continue;
        float q = rel_dz(z, zc);
        float w = wb / (1.0f + OBS_HBAO_UPSAMPLE_K * (q * q));
        sw += w;
        sa += w * jb->in[j];
      }
      /* All four neighbours uncovered (a sliver thinner than two pixels): no information. */
      float v = sw > 0.0f ? sa / sw : 1.0f;
      jb->out[i] = v > 1.0f ? 1.0f : v > 0.0f ? v : 0.0f;
    }
  return 0;
}

/* One direction of the separable cross-bilateral blur. */
OBS_HOT_KERNEL static int blur_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  const obs_gbuffer *g = jb->g;
  int rad = jb->p->blur_radius, W = g->width, H = g->height;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)W + (size_t)x;
      float zc = g->depth[i];
      if (!(zc > 0.0f)) {
        jb->out[i] = jb->in[i];
        continue;
      }
      float sw = 0.0f, sa = 0.0f;
      for (int k = -rad; k <= rad; k++) {
        int qx = jb->axis ? x : x + k, qy = jb->axis ? y + k : y;
        if (qx < 0 || qx >= W || qy < 0 || qy >= H) continue;
        size_t j = (size_t)qy * (size_t)W + (size_t)qx;
        float z = g->depth[j];
        if (!(z > 0.0f)) continue;
        float q = rel_dz(z, zc);
        /* The one transcendental that both backends evaluate themselves: GLSL's exp may differ
         * from libm's in the last bits, which changes the blurred AO by ~1e-7. */
        float w = expf(-((float)(k * k) * jb->falloff + jb->p->blur_sharpness * (q * q)));
        sw += w;
        sa += w * jb->in[j];
      }
      float v = sa / sw; /* the centre tap has weight exp(0) = 1 */
      jb->out[i] = v > 1.0f ? 1.0f : v > 0.0f ? v : 0.0f;
    }
  return 0;
}

int obs_hbao_cpu_apply(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                       double *stage_ms, obs_err *err) {
  return obs_hbao_cpu_apply_ex(g, p, threads, ao, NULL, stage_ms, err);
}

int obs_hbao_cpu_apply_ex(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                          float *ao_raw, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int i = 0; i < OBS_HBAO_PASS_COUNT; i++) stage_ms[i] = 0.0;
  if (g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "hbao: G-buffer %dx%d is empty", g->width, g->height);
  if (p->directions < 1 || p->directions > OBS_HBAO_MAX_DIRECTIONS || p->steps < 1 ||
      p->steps > OBS_HBAO_MAX_STEPS || p->blur_radius < 0 ||
      p->blur_radius > OBS_HBAO_MAX_BLUR_RADIUS)
    return obs_err_set(err, OBS_EINVAL,
                       "hbao: params directions=%d steps=%d blur_radius=%d out of range",
                       p->directions, p->steps, p->blur_radius);
  size_t n = (size_t)g->width * (size_t)g->height;
  int lw, lh;
  obs_hbao_level_size(p, g->width, g->height, &lw, &lh);
  size_t ln = (size_t)lw * (size_t)lh;
  /* One allocation: table, half-resolution depth+normal+AO (if any), raw AO, blur temporary. */
  size_t ntab = (size_t)OBS_HBAO_NOISE_CELLS * (size_t)p->directions * 4;
  size_t nhalf = p->half_res ? 5 * ln : 0;
  float *mem = malloc((ntab + nhalf + 2 * n) * sizeof(float));
  if (!mem) return obs_err_set(err, OBS_ENOMEM, "hbao: %dx%d: out of memory", g->width, g->height);
  float *table = mem, *half = mem + ntab, *raw = half + nhalf, *tmp = raw + n;
  obs_hbao_directions(p, table);

  hbao_job jb;
  memset(&jb, 0, sizeof jb);
  jb.g = g;
  jb.p = p;
  jb.table = table;
  jb.cos_b = (float)cos((double)p->angle_bias);
  jb.sin_b = (float)sin((double)p->angle_bias);
  float sigma = ((float)p->blur_radius + 1.0f) * 0.5f;
  jb.falloff = 1.0f / (2.0f * sigma * sigma);
  jb.lv = (hbao_level){g->width, g->height, 1, g->depth, g->normal};

  double t = obs_now_ms();
  if (p->half_res) {
    /* The top-left texel of each 2x2 (not the minimum depth): its depth and normal stay those of
     * one real surface point, at a known pixel centre. */
    float *hd = half, *hn = half + ln;
    for (int y = 0; y < lh; y++)
      for (int x = 0; x < lw; x++) {
        size_t j = (size_t)y * (size_t)lw + (size_t)x;
        size_t i = (size_t)(2 * y) * (size_t)g->width + (size_t)(2 * x);
        hd[j] = g->depth[i];
        for (int k = 0; k < 3; k++) hn[3 * j + k] = g->normal[3 * i + k];
      }
    jb.lv = (hbao_level){lw, lh, 2, hd, hn};
    if (stage_ms) stage_ms[OBS_HBAO_PASS_DOWNSAMPLE] = obs_now_ms() - t;
    t = obs_now_ms();
  }
  float *level_ao = p->half_res ? half + 4 * ln : raw;
  jb.out = level_ao;
  int rc = obs_parallel_tiles(lw, lh, threads, ao_tile, &jb, NULL, NULL, NULL);
  if (stage_ms) stage_ms[OBS_HBAO_PASS_AO] = obs_now_ms() - t;
  if (!rc && p->half_res) {
    t = obs_now_ms();
    jb.in = level_ao;
    jb.out = raw;
    rc = obs_parallel_tiles(g->width, g->height, threads, up_tile, &jb, NULL, NULL, NULL);
    if (stage_ms) stage_ms[OBS_HBAO_PASS_UPSAMPLE] = obs_now_ms() - t;
  }
  if (!rc && ao_raw) memcpy(ao_raw, raw, n * sizeof(float));
  if (!rc && p->blur_radius > 0) {
    t = obs_now_ms();
    jb.in = raw;
    jb.out = tmp;
    jb.axis = 0;
    rc = obs_parallel_tiles(g->width, g->height, threads, blur_tile, &jb, NULL, NULL, NULL);
    if (!rc) {
      jb.in = tmp;
      jb.out = ao;
      jb.axis = 1;
      rc = obs_parallel_tiles(g->width, g->height, threads, blur_tile, &jb, NULL, NULL, NULL);
    }
    if (stage_ms) stage_ms[OBS_HBAO_PASS_BLUR] = obs_now_ms() - t;
  } else if (!rc) {
    memcpy(ao, raw, n * sizeof(float));
  }
  free(mem);
  if (rc) return obs_err_set(err, rc, "hbao: %dx%d: CPU passes failed", g->width, g->height);
  return 0;
}


int obs_hbao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  obs_hbao_params p;
  if (obs_hbao_params_read(ctx->params, &p))
    return obs_err_set(err, OBS_EINVAL, "%s: /technique/params: invalid hbao parameters", sc->name);
  int rc = obs_image_init(out, sc->width, sc->height, OBS_SCREEN_CHANNELS, obs_screen_channel_names, err);
  if (rc) return rc;
  obs_gbuffer g;
  double build_ms = 0, gb_ms = 0, st[OBS_HBAO_PASS_COUNT];
  if ((rc = obs_gbuffer_raycast(sc, &g, ctx->threads, &build_ms, &gb_ms, err))) {
    obs_image_free(out);
    return rc;
  }
  ctx->build_ms = build_ms;
  double t0 = obs_now_ms();
  size_t plane = (size_t)sc->width * (size_t)sc->height;
  rc = obs_hbao_cpu_apply_ex(&g, &p, ctx->threads, out->data + OBS_SCREEN_AO * plane,
                             out->data + OBS_SCREEN_AO_RAW * plane, st, err);
  ctx->render_ms = gb_ms + (obs_now_ms() - t0);
  if (rc) {
    obs_gbuffer_free(&g);
    obs_image_free(out);
    return rc;
  }
  ctx->rays = plane; /* the G-buffer's primary rays */
  obs_render_ctx_stage(ctx, "gbuffer", gb_ms);
  for (int i = 0; i < OBS_HBAO_PASS_COUNT; i++)
    if (i == OBS_HBAO_PASS_AO || (i == OBS_HBAO_PASS_BLUR && p.blur_radius > 0) ||
        ((i == OBS_HBAO_PASS_DOWNSAMPLE || i == OBS_HBAO_PASS_UPSAMPLE) && p.half_res))
      obs_render_ctx_stage(ctx, obs_hbao_pass_names[i], st[i]);
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  obs_gbuffer_export(&g, &rig, out);
  obs_gbuffer_free(&g);
  return 0;
}
