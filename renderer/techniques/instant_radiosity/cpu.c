/* instant_radiosity on the CPU: the interleaved gather of the VPLs and the geometry-aware 4x4
 * filter, the twins of instant_radiosity*.comp.glsl operation for operation (float32, the shader's
 * order, nothing contracted: the build has -ffp-contract=off and the shaders mark the same
 * expressions `precise`) with approximate visibility's march over the depth pyramid and the
 * distance cube, exact visibility by shadow rays (CPU only), and the run on the CPU screen-space
 * driver. The model is docs/techniques/instant_radiosity.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "instant_radiosity.h"
#include "obscura/render.h"
#include "raytrace.h"
#include "screen.h"
#include "techniques.h"

typedef struct irad_job {
  const obs_gbuffer *g;
  const obs_irad_light *l;
  obs_irad_gather_push gp;
  obs_irad_filter_push fp;
  int exact;
  float eye[3], axes[3][3]; /* the camera in the ray tracer's frame (exact visibility) */
  const float *raw;         /* filter input */
  float *out;
} irad_job;

/* Whether the segment from the receiver at view-space (px, py, pz), view normal n, to VPL k is
 * free: a shadow ray from just off the receiver stopping just short of the VPL. */
static int visible(const irad_job *j, float px, float py, float pz, const float *n, int k) {
  const float *a = j->axes[0], *b = j->axes[1], *c = j->axes[2], *v = j->l->vpls.world + 3 * k;
  const float eps = 1e-4f * sqrtf(px * px + py * py + pz * pz);
  float o[3], d[3];
  for (int i = 0; i < 3; i++) {
    float nw = n[0] * a[i] + n[1] * b[i] + n[2] * c[i];
    o[i] = j->eye[i] + px * a[i] + py * b[i] + pz * c[i] + eps * nw;
    d[i] = v[i] - o[i];
  }
  float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(len > 0.0f)) return 1;
  for (int i = 0; i < 3; i++) d[i] /= len;
  obs_rt_ctx ctx;
  obs_rt_ctx_init(&ctx, j->l->rt, NULL);
  return !obs_rt_occluded(j->l->rt, &ctx, o, d, len * (1.0f - 1e-3f));
}

/* 0 below e0, 1 above e1, the smooth Hermite step between (HLSL's smoothstep, spelt out so that
 * both twins compute it alike). */
static float smooth01(float e0, float e1, float x) {
  float t = (x - e0) / (e1 - e0);
  t = t < 0.0f ? 0.0f : t > 1.0f ? 1.0f : t;
  return t * t * (3.0f - 2.0f * t);
}

/* The pixel coordinates of view-space point (x, y, z). */
static void project(const obs_irad_gather_push *pc, float x, float y, float z, float *qx,
                    float *qy) {
  const float fw = (float)pc->width, fh = (float)pc->height;
  if (pc->flags & OBS_IRAD_ORTHO) {
    *qx = (x / pc->half_w + 1.0f) * 0.5f * fw;
    *qy = (1.0f - y / pc->half_h) * 0.5f * fh;
  } else {
    *qx = (x / (z * pc->half_w) + 1.0f) * 0.5f * fw;
    *qy = (1.0f - y / (z * pc->half_h)) * 0.5f * fh;
  }
}

/* How much a sample dz behind an occluding surface at depth (or distance) z is occluded. */
static float occlusion(const obs_irad_gather_push *pc, float z, float dz) {
  float in = smooth01(pc->bias * z, 2.0f * pc->bias * z, dz);
  float out = smooth01(pc->thickness * z, 2.0f * pc->thickness * z, dz);
  return in * (1.0f - out);
}

/* The distance cube's value in the direction of view-space v from its centre. */
static float cube_at(const irad_job *j, float vx, float vy, float vz) {
  const float ax = fabsf(vx), ay = fabsf(vy), az = fabsf(vz);
  int f;
  float a, b;
  if (ax >= ay && ax >= az) {
    f = vx < 0.0f ? 1 : 0, a = vy / ax, b = vz / ax;
  } else if (ay >= az) {
    f = vy < 0.0f ? 3 : 2, a = vx / ay, b = vz / ay;
  } else {
    f = vz < 0.0f ? 5 : 4, a = vx / az, b = vy / az;
  }
  const float R = (float)OBS_IRAD_CUBE;
  float fi = floorf((a + 1.0f) * 0.5f * R), fj = floorf((b + 1.0f) * 0.5f * R);
  fi = fi >= 0.0f ? (fi > R - 1.0f ? R - 1.0f : fi) : 0.0f;
  fj = fj >= 0.0f ? (fj > R - 1.0f ? R - 1.0f : fj) : 0.0f;
  return j->l->cube[(size_t)fj * 6 * OBS_IRAD_CUBE + (size_t)f * OBS_IRAD_CUBE + (size_t)fi];
}

/* The article's approximate visibility of the VPL at view-space r from receiver P: a march over
 * the depth min-pyramid along the segment's on-screen part (samples 2^(i+1) pixels from P on
 * coarser levels as they go, stopping 2 pixels short of the VPL), then OBS_IRAD_CUBE_SAMPLES
 * looks into the distance cube along its part outside the view; each sample's soft comparison
 * multiplies the visibility. */
static float approx_vis(const irad_job *j, float px, float py, float pz, const float *r) {
  const obs_irad_gather_push *pc = &j->gp;
  const int ortho = (pc->flags & OBS_IRAD_ORTHO) != 0;
  /* The segment clipped to the part in front of the camera (perspective: z >= pz / 64). */
  const float zn = ortho ? 0.0f : pz * 0.015625f;
  const float tc = r[2] < zn ? (pz - zn) / (pz - r[2]) : 1.0f;
  const float ex = px + tc * (r[0] - px), ey = py + tc * (r[1] - py), ez = pz + tc * (r[2] - pz);
  float ax, ay, bx, by;
  project(pc, px, py, pz, &ax, &ay);
  project(pc, ex, ey, ez, &bx, &by);
  const float dx = bx - ax, dy = by - ay, len = sqrtf(dx * dx + dy * dy);
  const float fw = (float)pc->width, fh = (float)pc->height;
  float ue = 1.0f; /* where the screen segment leaves the image */
  if (dx > 0.0f) ue = fminf(ue, (fw - ax) / dx);
  if (dx < 0.0f) ue = fminf(ue, -ax / dx);
  if (dy > 0.0f) ue = fminf(ue, (fh - ay) / dy);
  if (dy < 0.0f) ue = fminf(ue, -ay / dy);
  float vis = 1.0f;
  for (int i = 0; i < OBS_IRAD_STEPS; i++) {
    const float s = (float)(2 << i);
    if (!(s < len - 2.0f)) break;
    const float u = s / len;
    if (!(u < ue)) break;
    const float zs = ortho ? pz + u * (ez - pz) : 1.0f / ((1.0f - u) / pz + u / ez);
    const int l = i > 0 ? (i - 1 < OBS_IRAD_LEVELS - 1 ? i - 1 : OBS_IRAD_LEVELS - 1) : 0;
    const int wl = (pc->width + (1 << l) - 1) >> l, hl = (pc->height + (1 << l) - 1) >> l;
    const float sx = ax + u * dx, sy = ay + u * dy;
    int tx = (int)sx >> l, ty = (int)sy >> l;
    tx = tx < 0 ? 0 : tx < wl - 1 ? tx : wl - 1;
    ty = ty < 0 ? 0 : ty < hl - 1 ? ty : hl - 1;
    const float m = j->l->pyramid[(size_t)ty * (size_t)j->l->pyr_w +
                                  (size_t)(obs_irad_pyramid_offset(pc->width, l) + tx)];
    vis *= 1.0f - occlusion(pc, zs, zs - m);
  }
  if (ue < 1.0f || tc < 1.0f) {
    /* The 3D parameter (along P -> r) where the segment leaves the view. */
    float te = ue;
    if (!ortho && ue < 1.0f) te = ue * pz / ((1.0f - ue) * ez + ue * pz);
    const float t0 = (ue < 1.0f ? te : 1.0f) * tc;
    for (int k = 1; k <= OBS_IRAD_CUBE_SAMPLES; k++) {
      const float t = t0 + (1.0f - t0) * ((float)k / (float)(OBS_IRAD_CUBE_SAMPLES + 1));
      const float vx = px + t * (r[0] - px) - pc->cube_x, vy = py + t * (r[1] - py) - pc->cube_y,
                  vz = pz + t * (r[2] - pz) - pc->cube_z;
      const float d = sqrtf(vx * vx + vy * vy + vz * vz);
      if (!(d > 0.0f)) continue;
      /* Behind an off-screen surface as seen from the cube's centre: hidden however far behind
       * (the thickness is the depth buffer's assumption). */
      vis *= 1.0f - smooth01(pc->bias * d, 2.0f * pc->bias * d, d - cube_at(j, vx, vy, vz));
    }
  }
  return vis;
}

static void gather_pixel(const irad_job *j, int x, int y, float *res) {
  const obs_gbuffer *g = j->g;
  const obs_irad_gather_push *pc = &j->gp;
  const size_t i = (size_t)y * (size_t)pc->width + (size_t)x;
  const float zp = g->depth[i];
  res[0] = res[1] = res[2] = 0.0f;
  res[3] = 1.0f;
  if (!(zp > 0.0f) || pc->classes < 1) return;
  const int ortho = (pc->flags & OBS_IRAD_ORTHO) != 0;
  const float fx = (float)x + 0.5f, fy = (float)y + 0.5f;
  const float ndx = 2.0f * fx / (float)pc->width - 1.0f, ndy = 1.0f - 2.0f * fy / (float)pc->height;
  const float px = ortho ? ndx * pc->half_w : ndx * pc->half_w * zp;
  const float py = ortho ? ndy * pc->half_h : ndy * pc->half_h * zp;
  const float *n = g->normal + 3 * i;
  const int cls = ((y & 3) * 4 + (x & 3)) % pc->classes;
  float er = 0.0f, eg = 0.0f, eb = 0.0f, all = 0.0f, kept = 0.0f;
  for (int k = pc->start[cls]; k < pc->start[cls + 1]; k++) {
    const float *r = j->l->vpls.rec + (size_t)k * 4 * OBS_IRAD_VPL_VEC4;
    float vx = r[0] - px, vy = r[1] - py, vz = r[2] - zp;
    float d2 = vx * vx + vy * vy + vz * vz;
    float nv = n[0] * vx + n[1] * vy + n[2] * vz;
    float mv = -(r[4] * vx + r[5] * vy + r[6] * vz);
    if (r[7] > 0.5f) mv = fabsf(mv);
    if (!(nv > 0.0f) || !(mv >= 0.0f)) continue;
    float n2 = mv * mv, f;
    if (n2 < pc->nc2) {
      float dl2 = d2 - n2 + pc->nc2;
      f = nv / sqrtf(d2) * sqrtf(pc->nc2 / dl2) / dl2;
    } else {
      f = (nv / d2) * (mv / d2);
    }
    float cr = r[8] * f, cg = r[9] * f, cb = r[10] * f;
    float lum = 0.2126f * cr + 0.7152f * cg + 0.0722f * cb;
    all += lum;
    if (j->exact && !visible(j, px, py, zp, n, k)) continue;
    if (pc->flags & OBS_IRAD_APPROX) {
      float v = approx_vis(j, px, py, zp, r);
      cr *= v;
      cg *= v;
      cb *= v;
      lum *= v;
    }
    er += cr;
    eg += cg;
    eb += cb;
    kept += lum;
  }
  res[0] = er;
  res[1] = eg;
  res[2] = eb;
  res[3] = all > 0.0f ? kept / all : 1.0f;
}

/* The view-space position of pixel (x, y) at depth z (the gather's reconstruction). */
static void view_pos(const obs_irad_filter_push *pc, int x, int y, float z, float *o) {
  const int ortho = (pc->flags & OBS_IRAD_ORTHO) != 0;
  const float fx = (float)x + 0.5f, fy = (float)y + 0.5f;
  const float ndx = 2.0f * fx / (float)pc->width - 1.0f, ndy = 1.0f - 2.0f * fy / (float)pc->height;
  o[0] = ortho ? ndx * pc->half_w : ndx * pc->half_w * z;
  o[1] = ortho ? ndy * pc->half_h : ndy * pc->half_h * z;
  o[2] = z;
}

/* Whether pixel (x, y) may join the filter of the centre at view-space position pc_ (depth
 * pc_[2]), normal nc: near the centre's tangent plane and facing the same way. */
static int filter_ok(const irad_job *j, int x, int y, const float *pc_, const float *nc) {
  const obs_irad_filter_push *pc = &j->fp;
  if (x < 0 || y < 0 || x >= pc->width || y >= pc->height) return 0;
  const size_t q = (size_t)y * (size_t)pc->width + (size_t)x;
  const float zq = j->g->depth[q], *nq = j->g->normal + 3 * q;
  if (!(zq > 0.0f)) return 0;
  float pq[3];
  view_pos(pc, x, y, zq, pq);
  float dp = fabsf(nc[0] * (pq[0] - pc_[0]) + nc[1] * (pq[1] - pc_[1]) + nc[2] * (pq[2] - pc_[2]));
  float dn = nq[0] * nc[0] + nq[1] * nc[1] + nq[2] * nc[2];
  return dp <= pc->depth_tol * pc_[2] && dn >= pc->normal_min;
}

static int alt(int o) { return o < 0 ? o + 4 : o - 4; }

static void filter_pixel(const irad_job *j, int x, int y, float *res) {
  const obs_irad_filter_push *pc = &j->fp;
  const size_t i = (size_t)y * (size_t)pc->width + (size_t)x;
  const float zc = j->g->depth[i], *nc = j->g->normal + 3 * i;
  if (!(zc > 0.0f)) {
    res[0] = res[1] = res[2] = 0.0f;
    res[3] = 1.0f;
    return;
  }
  float pc_[3], s[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  view_pos(pc, x, y, zc, pc_);
  int cnt = 0;
  for (int dy = OBS_IRAD_FILTER_LO; dy < OBS_IRAD_FILTER_LO + 4; dy++)
    for (int dx = OBS_IRAD_FILTER_LO; dx < OBS_IRAD_FILTER_LO + 4; dx++) {
      const int cand[4][2] = {{dx, dy}, {alt(dx), dy}, {dx, alt(dy)}, {alt(dx), alt(dy)}};
      for (int c = 0; c < 4; c++) {
        int qx = x + cand[c][0], qy = y + cand[c][1];
        if (!filter_ok(j, qx, qy, pc_, nc)) continue;
        const float *v = j->raw + 4 * ((size_t)qy * (size_t)pc->width + (size_t)qx);
        for (int k = 0; k < 4; k++) s[k] += v[k];
        cnt++;
        break;
      }
    }
  /* cnt >= 1: the centre always passes. */
  for (int k = 0; k < 4; k++) res[k] = s[k] * pc->inv_count[cnt];
}

static int gather_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  irad_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      gather_pixel(j, x, y, j->out + 4 * ((size_t)y * (size_t)j->g->width + (size_t)x));
  return 0;
}

static int filter_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  irad_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      filter_pixel(j, x, y, j->out + 4 * ((size_t)y * (size_t)j->g->width + (size_t)x));
  return 0;
}

static int irad_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_irad_light *l,
                       const obs_instant_radiosity_params *p, float *raw, float *out,
                       double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_IRAD_CPU_STAGES; k++) stage_ms[k] = 0.0;
  if (!g || !l || !p || !raw || (p->filter && !out) || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: missing G-buffer, light or output");
  irad_job j = {.g = g, .l = l, .raw = raw, .out = raw};
  j.exact = p->visibility == OBS_IRAD_VIS_EXACT && l->vpls.n > 0;
  if (j.exact && !l->rt)
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: exact visibility needs the BVH");
  if (j.exact) {
    const double *ax[3] = {l->rig.right, l->rig.up, l->rig.forward};
    for (int k = 0; k < 3; k++) {
      j.eye[k] = (float)(l->rig.origin[k] - l->rt->geo.origin[k]);
      for (int i = 0; i < 3; i++) j.axes[k][i] = (float)ax[k][i];
    }
  }
  obs_irad_gather_push_make(p, l, g->width, g->height, g->ortho, g->half_w, g->half_h, &j.gp);
  if (p->visibility == OBS_IRAD_VIS_APPROX && !l->pyramid)
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: approximate visibility needs its "
                                        "pyramid and cube (obs_irad_approx_make)");
  obs_irad_filter_push_make(p, g->width, g->height, g->ortho, g->half_w, g->half_h, &j.fp);
  r->passes = p->filter ? 2 : 1;
  double t0 = obs_now_ms();
  int rc = obs_screen_cpu_tiles(r, g->width, g->height, gather_tile, &j);
  double t1 = obs_now_ms();
  if (!rc && p->filter) {
    j.out = out;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, filter_tile, &j);
  }
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = p->filter ? obs_now_ms() - t1 : 0.0;
  }
  if (rc && rc != OBS_ECANCELED)
    return obs_err_set(err, rc, "instant_radiosity: CPU passes failed");
  return rc;
}

int obs_irad_cpu_apply(const obs_gbuffer *g, const obs_irad_light *l,
                       const obs_instant_radiosity_params *p, int threads, float *raw, float *out,
                       double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return irad_passes(&r, g, l, p, raw, out, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, float *extra, obs_err *err) {
  const obs_instant_radiosity_params *p = params;
  size_t n = (size_t)g->width * (size_t)g->height;
  float *buf = malloc(2 * 4 * n * sizeof *buf);
  if (!buf)
    return obs_err_set(err, OBS_ENOMEM, "instant_radiosity: %dx%d: out of memory", g->width,
                       g->height);
  float *raw = buf, *res = buf + 4 * n;
  double st[OBS_IRAD_CPU_STAGES];
  obs_irad_light l;
  int rc = obs_irad_light_render(r->ctx, p, &l, err);
  if (!rc && p->visibility == OBS_IRAD_VIS_APPROX) rc = obs_irad_approx_render(r->ctx, g, &l, err);
  if (!rc) rc = irad_passes(r, g, &l, p, raw, res, st, err);
  if (!rc) {
    obs_screen_cpu_stage(r, "gather", st[0]);
    if (p->filter) obs_screen_cpu_stage(r, "filter", st[1]);
    obs_irad_export(g, l.emission, raw, p->filter ? res : raw, ao, ao_raw, extra);
  }
  obs_irad_light_free(&l);
  free(buf);
  return rc;
}

static const obs_screen_extra irad_extra = {OBS_IRAD_EXTRA, obs_irad_extra_names};

int obs_instant_radiosity_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run_ex(ctx, passes, &irad_extra, ctx->bound, out, err);
}
