/* A scene's environment as the cube map that techniques with OBS_NEED_ENV_MAP light with
 * (environment.h): a constant colour, a lat-long EXR, six face EXRs or the procedural sky, scaled
 * by the environment's intensity. */
#include <string.h>

#include "environment.h"

static void sky_params(const obs_environment *en, obs_env_sky_params *sp) {
  const obs_vec3 *v[5] = {&en->zenith, &en->horizon, &en->ground, &en->sun_direction, &en->sun};
  double *d[5] = {sp->zenith, sp->horizon, sp->ground, sp->sun_dir, sp->sun_radiance};
  for (int i = 0; i < 5; i++) {
    d[i][0] = v[i]->x;
    d[i][1] = v[i]->y;
    d[i][2] = v[i]->z;
  }
  sp->sun_radius_deg = en->sun_radius;
}

int obs_env_from_scene(const obs_scene *sc, obs_env *e, obs_err *err) {
  memset(e, 0, sizeof *e);
  const obs_environment *en = &sc->env;
  obs_err local = OBS_ERR_INIT;
  int rc = 0;
  if (en->kind == OBS_ENV_COLOR) {
    const double c[3] = {sc->environment.x, sc->environment.y, sc->environment.z};
    rc = obs_env_constant(e, c, &local);
  } else if (en->kind == OBS_ENV_LATLONG) {
    rc = obs_env_from_latlong_file(e, en->files[0], en->resolution, &local);
  } else if (en->kind == OBS_ENV_FACES) {
    const char *const files[6] = {en->files[0], en->files[1], en->files[2],
                                  en->files[3], en->files[4], en->files[5]};
    rc = obs_env_from_face_files(e, files, &local);
  } else {
    obs_env_sky_params sp;
    sky_params(en, &sp);
    rc = obs_env_sky(e, &sp, en->resolution, &local);
  }
  if (rc) {
    obs_err_set(err, rc, "%s: /environment: %s", sc->name, obs_err_message(&local));
    obs_err_free(&local);
    return rc;
  }
  if (en->kind != OBS_ENV_COLOR && en->intensity != 1) {
    size_t n = (size_t)6 * (size_t)e->res * (size_t)e->res * 3;
    for (size_t i = 0; i < n; i++) e->data[i] = (float)(e->data[i] * en->intensity);
    for (int k = 0; k < 3; k++) e->mean[k] *= en->intensity;
  }
  return 0;
}
