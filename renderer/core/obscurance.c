/* The scene-wide terms of the obscurance model: average reflectivity and the closed-environment
 * ambient intensity (obscurance.h). */
#include "obscurance.h"

#include <string.h>

const char *const obs_falloff_names[4] = {"binary", "sqrt", "exp", NULL};

static double quad_area(const obs_light *l) {
  double a = 0;
  for (int k = 1; k < 3; k++) { /* triangles (v0, v1, v2) and (v0, v2, v3) */
    const obs_vec3 *p = &l->v[0], *q = &l->v[k], *r = &l->v[k + 1];
    double e1[3] = {q->x - p->x, q->y - p->y, q->z - p->z};
    double e2[3] = {r->x - p->x, r->y - p->y, r->z - p->z};
    double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
           cz = e1[0] * e2[1] - e1[1] * e2[0];
    a += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
  }
  return a;
}

static void add_object(obs_obscurance_env *env, double sum_e[3], const obs_object *o, double a) {
  const double r[3] = {o->reflectivity.x, o->reflectivity.y, o->reflectivity.z};
  const double e[3] = {o->emission.x, o->emission.y, o->emission.z};
  env->area += a;
  for (int c = 0; c < 3; c++) {
    if (o->has_material) env->r_ave[c] += a * r[c];
    sum_e[c] += a * e[c];
  }
}

int obs_obscurance_env_compute(const obs_scene *scene, const obs_geometry *geo,
                               obs_obscurance_env *env, obs_err *err) {
  memset(env, 0, sizeof *env);
  double sum_e[3] = {0, 0, 0};
  for (size_t m = 0; m < geo->nmeshes; m++) {
    const obs_mesh *me = &geo->meshes[m];
    double a = 0;
    for (size_t t = 0; t < me->ntris; t++) a += obs_geometry_mesh_tri_area(me, t);
    add_object(env, sum_e, &scene->objects[me->object], a);
  }
  for (size_t s = 0; s < geo->nspheres; s++) {
    const obs_sphere *sp = &geo->spheres[s];
    add_object(env, sum_e, &scene->objects[sp->object], 4.0 * M_PI * sp->radius * sp->radius);
  }
  for (size_t i = 0; i < scene->nlights; i++) {
    const obs_light *l = &scene->lights[i];
    double a = quad_area(l);
    sum_e[0] += a * l->emission.x, sum_e[1] += a * l->emission.y, sum_e[2] += a * l->emission.z;
  }
  if (!(env->area > 0) || !isfinite(env->area))
    return obs_err_set(err, OBS_EINVAL,
                       "%s: /objects: the obscurance model needs surfaces of finite, non-zero "
                       "area (got %g)",
                       scene->name, env->area);
  for (int c = 0; c < 3; c++) {
    env->r_ave[c] /= env->area;
    env->emitted[c] = sum_e[c] / env->area;
    if (!(env->r_ave[c] < 1.0))
      return obs_err_set(err, OBS_EINVAL,
                         "%s: /objects: the area-weighted average reflectivity reaches 1 in "
                         "channel %d (the closed-environment ambient term 1 / (1 - R_ave) "
                         "diverges); lower a material's reflectivity",
                         scene->name, c);
  }
  return 0;
}

void obs_obscurance_ambient(const obs_obscurance_env *env, int color_bleeding, double ia[3]) {
  for (int c = 0; c < 3; c++) {
    double k = 1.0 / (1.0 - env->r_ave[c]);
    ia[c] = (color_bleeding ? k : env->r_ave[c] * k) * env->emitted[c];
  }
}
