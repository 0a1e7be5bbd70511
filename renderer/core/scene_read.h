/* Reading a scene document in core, with the technique block left to the caller: core parses
 * and validates the camera, image, objects, lights and environment; the registry, which knows
 * the techniques and backends, reads `technique` (name, backend, params) and holds the scene
 * against the technique's needs through `tech`. The public obs_scene_load_* and
 * obs_scene_validate_json (renderer/registry/scene_technique.c) pass the registry's. */
#ifndef OBS_SCENE_READ_H
#define OBS_SCENE_READ_H

#include <jansson.h>

#include "json_util.h"
#include "obscura/scene.h"

/* Reads doc's "technique" into sc (technique, backend, params) and adds the technique's
 * problems to p, after every other part of the document was read (they may be partial). */
typedef void (*obs_scene_technique_fn)(obs_jpath *p, const json_t *doc, obs_scene *sc);

/* obs_scene_load_json, _string, _file and obs_scene_validate_json with the technique block
 * read by `tech`. */
int obs_scene_read_json(obs_scene *sc, json_t *doc, const char *name, const char *base_dir,
                        const obs_override *ov, size_t nov, obs_scene_technique_fn tech,
                        obs_err *err);
int obs_scene_read_string(obs_scene *sc, const char *text, const char *name,
                          const char *base_dir, const obs_override *ov, size_t nov,
                          obs_scene_technique_fn tech, obs_err *err);
int obs_scene_read_file(obs_scene *sc, const char *path, const obs_override *ov, size_t nov,
                        obs_scene_technique_fn tech, obs_err *err);
int obs_scene_check_json(const json_t *doc, const char *name, const char *base_dir,
                         obs_scene_technique_fn tech, obs_err *err);

#endif
