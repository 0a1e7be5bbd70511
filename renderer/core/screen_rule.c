/* The screen-space rule (obs_screen_rule in obscura/technique.h; docs/accuracy.md, "Screen-space
 * radius"): a screen-space technique's radius held against the pixel footprint and the depth
 * precision at every covered pixel of the G-buffer it ran on, one warning per limit it misses.
 * Both backends' drivers call it, so the rule and its words are the same on each. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>

#include "gbuffer.h"
#include "obscura/render.h"

/* The share of the covered pixels (0 to 1) whose reach is under 1 by `which` (0: pixels, 1:
 * depth) and the smallest such reach over them; with rule->pixel_decides the depth is judged
 * only where the pixel reach is at least 1. Runs only when some pixel may miss. */
static double short_share(const obs_screen_rule *rule, const void *bound, const obs_gbuffer *g,
                          int which, double *least) {
  size_t n = (size_t)g->width * (size_t)g->height, covered = 0, missed = 0;
  *least = INFINITY;
  for (size_t i = 0; i < n; i++) {
    if (!(g->depth[i] > 0.0f)) continue;
    obs_screen_reach r;
    rule->reach(bound, g, g->depth[i], &r);
    covered++;
    if (which && rule->pixel_decides && !(r.pixels >= 1.0)) continue;
    double v = which ? r.depth : r.pixels;
    missed += !(v >= 1.0);
    *least = fmin(*least, v);
  }
  return covered ? (double)missed / (double)covered : 0.0;
}

void obs_screen_rule_check(obs_render_ctx *ctx, obs_backend backend, const obs_gbuffer *g) {
  const obs_technique *t = ctx->scene ? ctx->scene->technique : NULL;
  const obs_screen_rule *rule = t ? t->range[backend].screen : NULL;
  if (!rule || !rule->reach || !ctx->bound || !g->depth) return;
  /* Reach never grows with depth, so the farthest covered pixel decides whether any misses. */
  size_t n = (size_t)g->width * (size_t)g->height;
  float zmax = 0.0f;
  for (size_t i = 0; i < n; i++)
    if (g->depth[i] > zmax) zmax = g->depth[i];
  if (!(zmax > 0.0f)) return;
  obs_screen_reach far;
  rule->reach(ctx->bound, g, zmax, &far);
  json_t *v = json_object_get(ctx->params, rule->param);
  double value = json_is_number(v) ? json_number_value(v) : NAN;
  static const char *const unit[2] = {"pixels across the screen",
                                      "depth steps along the view axis"};
  static const char *const one[2] = {"pixel", "depth step"};
  const char *image[2] = {rule->below_pixel, rule->below_depth};
  double at_far[2] = {far.pixels, far.depth};
  for (int k = 0; k < 2; k++) {
    if (at_far[k] >= 1.0) continue;
    double least;
    double share = short_share(rule, ctx->bound, g, k, &least);
    if (!(share > 0)) continue;
    /* Both figures grow in proportion to the radius, so value / least reaches 1 everywhere;
     * a radius that rounds to 0 in the bound params reaches nothing, and suggests nothing. */
    char need[96] = "it rounds to 0 in float";
    if (least > 0)
      snprintf(need, sizeof need, "%s >= %.3g reaches one %s everywhere", rule->param,
               value / least, one[k]);
    obs_render_ctx_warn(ctx,
                        "%s %s = %g reaches %.3g %s (under one) at %.3g%% of the covered "
                        "pixels, so there the image is likely %s; %s (docs/accuracy.md, "
                        "Screen-space radius)",
                        t->name, rule->param, value, least, unit[k], 100.0 * share, image[k],
                        need);
  }
}
