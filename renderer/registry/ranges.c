/* The guaranteed ranges of the technique descriptors, as JSON (the registry, the server's
 * techniques endpoint) and as the Markdown table of docs/accuracy.md. */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "strbuf.h"
#include "registry.h"

static json_t *pair(double a, double b) { return json_pack("[ff]", a, b); }

json_t *obs_range_json(const obs_range *r) {
  json_t *o = json_object();
  json_object_set_new(o, "size", pair(r->size_min, r->size_max));
  json_object_set_new(o, "translation_max", json_real(r->translation_max));
  json_object_set_new(o, "fov_y", pair(r->fov_min, r->fov_max));
  json_object_set_new(o, "orthographic", json_boolean(r->orthographic));
  json_t *ps = json_object();
  for (const obs_param_range *p = r->params; p->name; p++)
    json_object_set_new(ps, p->name,
                        json_pack("{sfsfss}", "min", p->min, "max", p->max, "unit",
                                  obs_param_range_unit(p)));
  json_object_set_new(o, "params", ps);
  if (r->screen) json_object_set_new(o, "screen_radius", json_string(r->screen->param));
  json_object_set_new(o, "tolerance",
                      json_pack("{sfsfsfsfsf}", "ao_mean", r->tol.ao_mean, "ao_pixel",
                                r->tol.ao_pixel, "share", r->tol.share, "normal", r->tol.normal,
                                "depth_rel", r->tol.depth_rel));
  return o;
}

/* Appends printf-style text to a growing string; keeps going (and drops text) when out of
 * memory, returning NULL at the end instead. */

char *obs_technique_ranges_markdown(void) {
  obs_strbuf b = {0};
  obs_strbuf_put(&b, "| Technique | Backend | Size | Translation | fov_y (degrees) | Orthographic | "
          "Parameters | ao: mean, per pixel (all but share) | normal | depth (relative) |\n");
  obs_strbuf_put(&b, "|---|---|---|---|---|---|---|---|---|---|\n");
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    for (int be = OBS_BACKEND_CPU; be < OBS_BACKEND_COUNT; be++) {
      if (!t->run[be]) continue;
      const obs_range *r = &t->range[be];
      obs_strbuf_put(&b, "| `%s` | %s | ", t->name, obs_backend_name((obs_backend)be));
      if (!(r->size_max > 0)) {
        obs_strbuf_put(&b, "none declared | | | | | | | |\n");
        continue;
      }
      obs_strbuf_put(&b, "%g to %g | up to %g sizes | %g to %g | %s | ", r->size_min, r->size_max,
          r->translation_max, r->fov_min, r->fov_max, r->orthographic ? "yes" : "no");
      if (!r->params[0].name && !r->screen) obs_strbuf_put(&b, "as the schema");
      for (const obs_param_range *p = r->params; p->name; p++)
        obs_strbuf_put(&b, "%s`%s` %g to %g %s", p == r->params ? "" : "; ", p->name, p->min, p->max,
            obs_param_range_unit(p));
      if (r->screen)
        obs_strbuf_put(&b, "%s`%s` reaching 1 pixel and 1 depth step at every covered pixel "
                       "(screen-space rule)", r->params[0].name ? "; " : "", r->screen->param);
      obs_strbuf_put(&b, " | %g, %g (%g) | %g | %g |\n", r->tol.ao_mean, r->tol.ao_pixel, r->tol.share,
          r->tol.normal, r->tol.depth_rel);
    }
  }
  return obs_strbuf_finish(&b);
}
