/* The Vulkan pass driver (plan_vk.h): a technique's plan of images, passes and downloads made,
 * run, timed, read back and freed. */
#include "plan_vk.h"

#include <stdio.h>
#include <string.h>

#include "driver.h"
#include "obscura/render.h"
#include "vk_internal.h"

static int count_passes(const obs_vk_plan *p) {
  int n = 0;
  while (n < OBS_VK_PLAN_PASSES && p->passes[n].stage) n++;
  return n;
}

static int count_bound(const obs_vk_plan_pass *ps) {
  int n = 0;
  while (n < OBS_VK_MAX_BINDINGS && ps->images[n]) n++;
  return n;
}

/* Checks handle h, referred to as `what`, and marks it used. */
static int use(obs_vk_plan_state *r, int h, const char *what, obs_err *err) {
  if (h < OBS_VK_PLAN_DEPTH || h >= OBS_VK_PLAN_IMAGES)
    return obs_err_set(err, OBS_EINVAL, "vulkan: %s: %s: image handle %d (1..%d)", r->who, what, h,
                       OBS_VK_PLAN_IMAGES - 1);
  r->used[h] = 1;
  return 0;
}

/* Marks what the enabled passes and the active downloads use, checking every reference. */
static int mark(obs_vk_plan_state *r, obs_err *err) {
  const obs_vk_plan *p = r->plan;
  char what[128];
  int rc = 0;
  for (int i = 0; i < count_passes(p) && !rc; i++) {
    const obs_vk_plan_pass *ps = &p->passes[i];
    if (ps->skip) continue;
    if (!count_bound(ps))
      return obs_err_set(err, OBS_EINVAL, "vulkan: %s: pass %d (\"%s\"): no image bound", r->who, i,
                         ps->stage);
    for (int k = 0; k < count_bound(ps) && !rc; k++) {
      snprintf(what, sizeof what, "pass %d (\"%s\"), binding %d", i, ps->stage, k);
      rc = use(r, ps->images[k], what, err);
    }
    snprintf(what, sizeof what, "pass %d (\"%s\"), grid", i, ps->stage);
    if (!rc && ps->grid) rc = use(r, ps->grid, what, err);
  }
  for (int i = 0; i < OBS_VK_PLAN_DOWNLOADS && !rc; i++)
    if (p->downloads[i].to) {
      snprintf(what, sizeof what, "download %d", i);
      rc = use(r, p->downloads[i].image, what, err);
    }
  return rc;
}

/* The G-buffer's image behind handle h (NULL when there is none). */
static obs_vk_image *gbuffer_image(const obs_vk_gbuffer *g, int h) {
  if (!g) return NULL;
  return h == OBS_VK_PLAN_DEPTH ? g->depth : h == OBS_VK_PLAN_NORMAL ? g->normal : g->albedo;
}

/* Checks every used image's description before anything is made. */
static int check_images(obs_vk_plan_state *r, const obs_vk_gbuffer *g, obs_err *err) {
  for (int h = OBS_VK_PLAN_DEPTH; h < OBS_VK_PLAN_IMAGES; h++) {
    if (!r->used[h]) continue;
    if (h < OBS_VK_PLAN_IMAGE0) {
      if (!gbuffer_image(g, h))
        return obs_err_set(err, OBS_EINVAL, "vulkan: %s: image %d: the G-buffer's %s is missing",
                           r->who, h,
                           h == OBS_VK_PLAN_DEPTH    ? "depth"
                           : h == OBS_VK_PLAN_NORMAL ? "normal"
                                                     : "albedo");
      continue;
    }
    const obs_vk_plan_image *d = &r->plan->images[h];
    if (d->use) continue;
    if (d->channels != 1 && d->channels != 4)
      return obs_err_set(err, OBS_EINVAL, "vulkan: %s: image %d: %d channels (1 or 4)", r->who, h,
                         d->channels);
    int w = d->width || d->height ? d->width : r->fw,
        ht = d->width || d->height ? d->height : r->fh;
    if (w < 1 || ht < 1)
      return obs_err_set(err, OBS_EINVAL, "vulkan: %s: image %d: %dx%d texels", r->who, h, w, ht);
  }
  return 0;
}

/* Binds the G-buffer and the callers' images, makes and uploads the technique's own. */
static int make_images(obs_vk *vk, obs_vk_plan_state *r, const obs_vk_gbuffer *g, obs_err *err) {
  for (int h = OBS_VK_PLAN_DEPTH; h < OBS_VK_PLAN_IMAGES; h++) {
    if (!r->used[h]) continue;
    const obs_vk_plan_image *d = &r->plan->images[h];
    if (h < OBS_VK_PLAN_IMAGE0 || d->use) {
      r->img[h] = h < OBS_VK_PLAN_IMAGE0 ? gbuffer_image(g, h) : d->use;
      continue;
    }
    int sized = d->width || d->height;
    int rc = obs_vk_image_create(vk, sized ? d->width : r->fw, sized ? d->height : r->fh,
                                 d->channels, &r->img[h], err);
    if (rc) return rc;
    r->owned[h] = 1;
    if (d->data && (rc = obs_vk_image_upload(vk, r->img[h], d->data, err))) return rc;
  }
  return 0;
}

static uint32_t groups(int n, int local) {
  int l = local > 0 ? local : OBS_VK_PLAN_LOCAL;
  return (uint32_t)((n + l - 1) / l);
}

/* Adds ms to `stage` in t (a new entry in first-seen order). */
static void add_stage(obs_vk_plan_times *t, const char *stage, double ms) {
  for (int i = 0; i < t->n; i++)
    if (!strcmp(t->stage[i], stage)) {
      t->ms[i] += ms;
      return;
    }
  if (t->n == OBS_VK_PLAN_PASSES + 1) return;
  t->stage[t->n] = stage;
  t->ms[t->n++] = ms;
}

/* The enabled passes, in order, through one obs_vk_run. */
static int dispatch(obs_vk_plan_state *r, obs_err *err) {
  const obs_vk_plan *p = r->plan;
  obs_vk_pass ps[OBS_VK_PLAN_PASSES];
  char names[OBS_VK_PLAN_PASSES][96];
  int from[OBS_VK_PLAN_PASSES], n = 0;
  memset(ps, 0, sizeof ps);
  for (int i = 0; i < count_passes(p); i++) {
    const obs_vk_plan_pass *s = &p->passes[i];
    if (s->skip) continue;
    const obs_vk_image *grid = s->grid ? r->img[s->grid] : NULL;
    snprintf(names[n], sizeof names[n], "%s %s", r->who, s->stage);
    ps[n] = (obs_vk_pass){.name = names[n],
                          .spirv = s->spirv,
                          .spirv_size = s->spirv_size,
                          .nimages = count_bound(s),
                          .push = s->push,
                          .push_size = s->push_size,
                          .groups_x = groups(grid ? grid->width : r->fw, s->local[0]),
                          .groups_y = groups(grid ? grid->height : r->fh, s->local[1]),
                          .ntextures = s->ntextures,
                          .data = s->data};
    for (int k = 0; k < ps[n].nimages; k++) ps[n].images[k] = r->img[s->images[k]];
    memcpy(ps[n].textures, s->textures, sizeof ps[n].textures);
    from[n++] = i;
  }
  double ms[OBS_VK_PLAN_PASSES] = {0};
  int rc = obs_vk_run(r->vk, ps, n, ms, err);
  if (rc) return rc;
  for (int i = 0; i < n; i++) add_stage(&r->times, p->passes[from[i]].stage, ms[i]);
  return 0;
}

static int download(obs_vk_plan_state *r, obs_err *err) {
  double t0 = obs_now_ms();
  for (int i = 0; i < OBS_VK_PLAN_DOWNLOADS; i++) {
    const obs_vk_plan_download *d = &r->plan->downloads[i];
    int rc = d->to ? obs_vk_image_download(r->vk, r->img[d->image], d->to, err) : 0;
    if (rc) return rc;
  }
  add_stage(&r->times, "readback", obs_now_ms() - t0);
  return 0;
}

int obs_vk_plan_open(obs_vk *vk, const obs_vk_gbuffer *g, const obs_vk_plan *plan,
                     obs_vk_plan_state *s, obs_err *err) {
  memset(s, 0, sizeof *s);
  if (!vk || !plan) return obs_err_set(err, OBS_EINVAL, "vulkan: plan: no device or plan");
  s->vk = vk;
  s->plan = plan;
  s->who = plan->technique ? plan->technique : "(unnamed plan)";
  s->fw = plan->width || plan->height ? plan->width : g ? g->width : 0;
  s->fh = plan->width || plan->height ? plan->height : g ? g->height : 0;
  s->seen = obs_vk_validation_messages(vk);
  int rc = mark(s, err);
  if (!rc) rc = check_images(s, g, err);
  if (!rc) rc = make_images(vk, s, g, err);
  return rc;
}

int obs_vk_plan_dispatch(obs_vk_plan_state *s, obs_err *err) {
  if (!s->vk) return obs_err_set(err, OBS_EINVAL, "vulkan: plan: dispatch before a good open");
  return dispatch(s, err);
}

int obs_vk_plan_close(obs_vk_plan_state *s, int rc, obs_vk_plan_times *times, obs_err *err) {
  if (!rc) rc = download(s, err);
  for (int h = 0; h < OBS_VK_PLAN_IMAGES; h++)
    if (s->owned[h]) obs_vk_image_free(s->vk, s->img[h]);
  uint32_t complaints = s->vk ? obs_vk_validation_messages(s->vk) - s->seen : 0;
  if (!rc && complaints)
    rc = obs_err_set(err, OBS_EINTERNAL,
                     "vulkan: %s: %u Vulkan validation message(s) on its passes on \"%s\" (printed "
                     "above)",
                     s->who, complaints, obs_vk_device_name(s->vk));
  if (times) *times = rc ? (obs_vk_plan_times){0} : s->times;
  memset(s, 0, sizeof *s);
  return rc;
}

int obs_vk_plan_run(obs_vk *vk, const obs_vk_gbuffer *g, const obs_vk_plan *plan,
                    obs_vk_plan_times *times, obs_err *err) {
  obs_vk_plan_state s;
  int rc = obs_vk_plan_open(vk, g, plan, &s, err);
  if (!rc) rc = obs_vk_plan_dispatch(&s, err);
  return obs_vk_plan_close(&s, rc, times, err);
}

double obs_vk_plan_ms(const obs_vk_plan_times *t, const char *stage) {
  for (int i = 0; t && i < t->n; i++)
    if (!strcmp(t->stage[i], stage)) return t->ms[i];
  return 0.0;
}

void obs_vk_plan_stage_ms(const obs_vk_plan_times *t, const char *const *names, int n,
                          double *stage_ms) {
  for (int i = 0; stage_ms && i < n; i++) stage_ms[i] = obs_vk_plan_ms(t, names[i]);
}

void obs_vk_plan_record(obs_render_ctx *ctx, const obs_vk_plan_times *t) {
  for (int i = 0; i < t->n; i++) obs_driver_stage_add(ctx, t->stage[i], t->ms[i]);
}
