/* ss_radiosity on the CPU: the gather and blur passes, the twins of ss_radiosity*.comp.glsl
 * operation for operation (float32, the shader's order, nothing contracted: the build has
 * -ffp-contract=off and the shaders mark the same expressions `precise`), and the run on the
 * CPU screen-space driver. The model is docs/techniques/ss_radiosity.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"
#include "simd.h"
#include "ss_radiosity.h"
#include "techniques.h"

typedef struct srad_job {
  const obs_gbuffer *g;
  const float *direct;
  const float *probes; /* pc.nprobes of them: view-space centre, area */
  const obs_ss_radiosity_tables *t;
  obs_srad_gather_push pc;
  float threshold;
  const float *raw; /* blur input */
  float *out;
} srad_job;

/* floor(v) clamped to [0, n-1], NaN to 0: the texel a sample lands on, clamp-to-edge; the clamp
 * comes before the conversion, as in the shader. */
OBS_HOT_INLINE int texel(float v, int n) {
  float f = floorf(v);
  if (!(f >= 0.0f)) f = 0.0f;
  if (f > (float)(n - 1)) f = (float)(n - 1);
  return (int)f;
}

/* The AO probes at view-space point (px, py, pz) of normal n: Occ = A saturate(n . v^) / (v . v)
 * per probe, v from the point to the probe's centre, combined as the article's listing
 * (AO *= saturate(1 - Occ)) or additively (saturate(1 - sum Occ)). */
OBS_HOT_INLINE float probe_ao(const srad_job *j, float px, float py, float pz, const float *n) {
  const obs_srad_gather_push *pc = &j->pc;
  float prod = 1.0f, sum = 0.0f;
  for (int i = 0; i < pc->nprobes; i++) {
    const float *c = j->probes + 4 * i;
    float vx = c[0] - px, vy = c[1] - py, vz = c[2] - pz;
    float nv = n[0] * vx + n[1] * vy + n[2] * vz;
    if (!(nv > 0.0f)) continue;
    float vv = vx * vx + vy * vy + vz * vz;
    float cs = nv / sqrtf(vv);
    cs = cs > 1.0f ? 1.0f : cs;
    float occ = c[3] * cs / vv;
    if (pc->flags & OBS_SRAD_PROBES_ADD) {
      sum += occ;
    } else {
      float f = 1.0f - occ;
      prod *= f < 0.0f ? 0.0f : f;
    }
  }
  if (pc->flags & OBS_SRAD_PROBES_ADD) {
    float f = 1.0f - sum;
    return f < 0.0f ? 0.0f : f;
  }
  return prod;
}

OBS_HOT_INLINE void gather_pixel(const srad_job *j, int x, int y, float *res) {
  const obs_gbuffer *g = j->g;
  const obs_srad_gather_push *pc = &j->pc;
  const int w = pc->width, h = pc->height;
  const size_t i = (size_t)y * (size_t)w + (size_t)x;
  const float zp = g->depth[i];
  if (!(zp > 0.0f)) {
    res[0] = res[1] = res[2] = 0.0f;
    res[3] = 1.0f;
    return;
  }
  const int ortho = (pc->flags & OBS_SRAD_ORTHO) != 0;
  const float fw = (float)w, fh = (float)h;
  const float fx = (float)x + 0.5f, fy = (float)y + 0.5f;
  const float ndx = 2.0f * fx / fw - 1.0f, ndy = 1.0f - 2.0f * fy / fh;
  const float px = ortho ? ndx * pc->half_w : ndx * pc->half_w * zp;
  const float py = ortho ? ndy * pc->half_h : ndy * pc->half_h * zp;
  const float *n = g->normal + 3 * i;
  const float *rot = j->t->rotation[(y & 3) * 4 + (x & 3)];
  const float rad = pc->kernel_size / (1.0f + pc->attenuation * zp);
  const float self = j->direct[4 * i + 3];
  float occ = 0.0f, br = 0.0f, bg = 0.0f, bb = 0.0f;
  for (int k = 0; k < pc->samples; k++) {
    const float *v = j->t->offsets[k];
    float d = rot[0] * v[0] + rot[1] * v[1] + rot[2] * v[2];
    float tt = 2.0f * d;
    float ux = v[0] - tt * rot[0], uy = v[1] - tt * rot[1], uz = v[2] - tt * rot[2];
    float dn = ux * n[0] + uy * n[1] + uz * n[2];
    if (dn < 0.0f) {
      ux = -ux;
      uy = -uy;
      uz = -uz;
    }
    float ox = pc->directivity * n[0] + pc->spread * ux;
    float oy = pc->directivity * n[1] + pc->spread * uy;
    float oz = pc->directivity * n[2] + pc->spread * uz;
    float sx = px + rad * ox, sy = py + rad * oy, sz = zp + rad * oz;
    if (!(sz > 0.0f)) continue;
    float qx, qy;
    if (ortho) {
      qx = (sx / pc->half_w + 1.0f) * 0.5f * fw;
      qy = (1.0f - sy / pc->half_h) * 0.5f * fh;
    } else {
      qx = (sx / (sz * pc->half_w) + 1.0f) * 0.5f * fw;
      qy = (1.0f - sy / (sz * pc->half_h)) * 0.5f * fh;
    }
    const size_t q = (size_t)texel(qy, h) * (size_t)w + (size_t)texel(qx, w);
    float zs = g->depth[q];
    if (!(zs > 0.0f)) continue;
    float dz = zp - zs;
    if (!(dz > 0.0f)) continue;
    float wb = 1.0f - dz * pc->inv_bias;
    if (!(wb > 0.0f)) continue;
    if ((pc->flags & OBS_SRAD_EXCLUDE_SELF) && j->direct[4 * q + 3] == self) continue;
    const float *ns = g->normal + 3 * q;
    float dd = n[0] * ns[0] + n[1] * ns[1] + n[2] * ns[2];
    float gf = dd > OBS_SRAD_COPLANAR ? 0.0f : (1.0f - dd) * 0.5f;
    float c = wb * gf;
    occ += c;
    br += c * j->direct[4 * q];
    bg += c * j->direct[4 * q + 1];
    bb += c * j->direct[4 * q + 2];
  }
  const float *a = g->albedo + 3 * i;
  res[0] = br * pc->scale * a[0];
  res[1] = bg * pc->scale * a[1];
  res[2] = bb * pc->scale * a[2];
  float ao = 1.0f - occ * pc->inv_samples;
  ao = ao < 0.0f ? 0.0f : ao > 1.0f ? 1.0f : ao;
  res[3] = pc->nprobes ? ao * probe_ao(j, px, py, zp, n) : ao;
}

OBS_HOT_INLINE void blur_pixel(const srad_job *j, int x, int y, float *res) {
  const obs_gbuffer *g = j->g;
  const int w = g->width, h = g->height;
  const float zc = g->depth[(size_t)y * (size_t)w + (size_t)x];
  if (!(zc > 0.0f)) {
    res[0] = res[1] = res[2] = 0.0f;
    res[3] = 1.0f;
    return;
  }
  const float lim = j->threshold * zc;
  float s[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  int cnt = 0;
  for (int dy = OBS_SRAD_BLUR_LO; dy <= OBS_SRAD_BLUR_HI; dy++)
    for (int dx = OBS_SRAD_BLUR_LO; dx <= OBS_SRAD_BLUR_HI; dx++) {
      int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      size_t k = (size_t)yy * (size_t)w + (size_t)xx;
      float zn = g->depth[k];
      if (zn > 0.0f && fabsf(zn - zc) <= lim) {
        for (int c = 0; c < 4; c++) s[c] += j->raw[4 * k + (size_t)c];
        cnt++;
      }
    }
  /* cnt >= 1: the centre always passes. */
  for (int c = 0; c < 4; c++) res[c] = s[c] * j->t->inv_count[cnt];
  res[3] = res[3] > 1.0f ? 1.0f : res[3];
}

/* The tile loops twice (simd.h): baseline and x86-64-v3, the same scalar operations either way
 * (no contraction), so the same bits at every level. */
OBS_HOT_INLINE int gather_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  srad_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      gather_pixel(j, x, y, j->out + 4 * ((size_t)y * (size_t)j->g->width + (size_t)x));
  return 0;
}

OBS_TILE_KERNELS(gather_tile)

OBS_HOT_INLINE int blur_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  srad_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      blur_pixel(j, x, y, j->out + 4 * ((size_t)y * (size_t)j->g->width + (size_t)x));
  return 0;
}
OBS_TILE_KERNELS(blur_tile)

static int srad_passes(obs_screen_cpu *r, const obs_gbuffer *g, const float *direct,
                       const float *probes, int nprobes, const obs_ss_radiosity_params *p,
                       float *raw, float *out, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SRAD_CPU_STAGES; k++) stage_ms[k] = 0.0;
  if (!g || !direct || !p || !raw || (p->blur && !out) || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: missing G-buffer, parameters or output");
  if (nprobes < 0 || nprobes > OBS_SRAD_MAX_PROBES || (nprobes && !probes))
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: %d probes (at most %d)", nprobes,
                       OBS_SRAD_MAX_PROBES);
  if (p->samples < 1 || p->samples > OBS_SRAD_MAX_SAMPLES)
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: samples must be 1..%d (got %d)",
                       OBS_SRAD_MAX_SAMPLES, p->samples);
  obs_ss_radiosity_tables t;
  obs_ss_radiosity_tables_make(p, &t);
  srad_job j = {.g = g,
                .direct = direct,
                .probes = probes,
                .t = &t,
                .threshold = p->blur_depth_threshold,
                .raw = raw,
                .out = raw};
  obs_ss_radiosity_push_make(p, g->width, g->height, g->ortho, g->half_w, g->half_h, &j.pc);
  j.pc.nprobes = nprobes;
  r->passes = p->blur ? 2 : 1;
  const int isa = obs_simd_isa();
  double t0 = obs_now_ms();
  int rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(gather_tile, isa), &j);
  double t1 = obs_now_ms();
  if (!rc && p->blur) {
    j.out = out;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(blur_tile, isa), &j);
  }
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = p->blur ? obs_now_ms() - t1 : 0.0;
  }
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ss_radiosity: CPU passes failed");
  return rc;
}

int obs_ss_radiosity_cpu_apply(const obs_gbuffer *g, const float *direct, const float *probes,
                               int nprobes, const obs_ss_radiosity_params *p, int threads,
                               float *raw, float *out, double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return srad_passes(&r, g, direct, probes, nprobes, p, raw, out, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, float *extra, obs_err *err) {
  const obs_ss_radiosity_params *p = params;
  const obs_scene *sc = r->ctx->scene;
  size_t n = (size_t)g->width * (size_t)g->height;
  float *buf = malloc((3 * 4 * n + 4 * OBS_SRAD_MAX_PROBES) * sizeof *buf);
  if (!buf)
    return obs_err_set(err, OBS_ENOMEM, "ss_radiosity: %dx%d: out of memory", g->width, g->height);
  float *direct = buf, *raw = buf + 4 * n, *res = buf + 8 * n, *probes = buf + 12 * n;
  double dms[2], st[OBS_SRAD_CPU_STAGES];
  int rc = obs_ss_radiosity_direct(sc, p, r->threads, r->cancel, direct, dms, err);
  if (!rc) {
    obs_screen_cpu_stage(r, "bvh", dms[0]);
    obs_screen_cpu_stage(r, "direct", dms[1]);
    rc = srad_passes(r, g, direct, probes, obs_ss_radiosity_probes_make(sc, probes), p, raw, res,
                     st, err);
  }
  if (!rc) {
    obs_screen_cpu_stage(r, "gather", st[0]);
    if (p->blur) obs_screen_cpu_stage(r, "blur", st[1]);
    obs_ss_radiosity_export(g, direct, raw, p->blur ? res : raw, ao, ao_raw, extra);
  }
  free(buf);
  return rc;
}

static const obs_screen_extra srad_extra = {OBS_SRAD_EXTRA, obs_ss_radiosity_extra_names};

int obs_ss_radiosity_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run_ex(ctx, passes, &srad_extra, ctx->bound, out, err);
}
