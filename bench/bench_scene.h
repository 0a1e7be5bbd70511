/* A bundled scene as the benchmarks that render one load it: the scene's document, then its image
 * size and technique replaced (the programs that include this are built with OBS_SOURCE_DIR). */
#ifndef OBS_BENCH_SCENE_H
#define OBS_BENCH_SCENE_H

#include <jansson.h>
#include <stdlib.h>

#include "obscura/obscura.h"

/* scenes/<file>'s document (the caller's, for bench_scene_load), or NULL with *err set. */
static inline json_t *bench_scene_doc(const char *file, obs_err *err) {
  char path[512];
  snprintf(path, sizeof path, "%s/scenes/%s", OBS_SOURCE_DIR, file);
  json_error_t je;
  json_t *doc = json_load_file(path, 0, &je);
  if (!doc) obs_err_set(err, OBS_EIO, "%s: %s", file, je.text);
  return doc;
}

/* Loads `doc` (consumed) into *sc at width x height, rendered by `technique` on `backend` with
 * `params` (a JSON object's text). Returns 0 or the loader's error code. */
static inline int bench_scene_load(json_t *doc, int width, int height, const char *technique,
                                   const char *backend, const char *params, obs_scene *sc,
                                   obs_err *err) {
  json_t *img = json_object_get(doc, "image");
  json_object_set_new(img, "width", json_integer(width));
  json_object_set_new(img, "height", json_integer(height));
  json_t *t = json_pack("{s:s, s:s, s:o}", "name", technique, "backend", backend, "params",
                        json_loads(params, 0, NULL));
  json_object_set_new(doc, "technique", t);
  char *text = json_dumps(doc, JSON_COMPACT);
  json_decref(doc);
  int rc = obs_scene_load_string(sc, text, "bench.json", NULL, NULL, 0, err);
  free(text);
  return rc;
}

#endif
