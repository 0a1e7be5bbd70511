/* Which backend and lane a job runs on: the renderer's choice within this daemon's lanes, learned
 * "auto" from stored timed runs of this machine, and the lane of a job a previous process left
 * queued. Below submission and admission, which both ask it; it reads only the store. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurad.h"

int srv_pick_backend(const obs_technique *t, obs_backend requested, int vulkan_lane,
                     obs_backend *out, obs_err *err) {
  /* Without a Vulkan lane "auto" is the CPU wherever the technique has one, decided here rather
   * than by the registry's rule, whose probe of the Vulkan device would load its driver into a
   * daemon that promised to load none (--no-vulkan). */
  if (!vulkan_lane && requested == OBS_BACKEND_AUTO &&
      obs_technique_has_backend(t, OBS_BACKEND_CPU)) {
    *out = OBS_BACKEND_CPU;
    return 0;
  }
  if (!vulkan_lane && requested == OBS_BACKEND_VULKAN && t->run[OBS_BACKEND_VULKAN])
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "this server runs no Vulkan lane (started with --no-vulkan); use \"cpu\"");
  int rc = obs_technique_pick_backend(t, requested, out, err);
  if (rc || *out != OBS_BACKEND_VULKAN || vulkan_lane) return rc;
  if (requested == OBS_BACKEND_AUTO && obs_technique_has_backend(t, OBS_BACKEND_CPU)) {
    *out = OBS_BACKEND_CPU;
    return 0;
  }
  return obs_err_set(err, OBS_EUNSUPPORTED,
                     "this server runs no Vulkan lane (started with --no-vulkan); use \"cpu\"");
}

int srv_pick_lane_recovered(void *user, const char *technique, const char *backend_requested,
                            srv_lane stored, srv_lane *lane, obs_err *err) {
  const srv_app *app = user;
  const obs_technique *t = obs_technique_find(technique);
  if (!t)
    return obs_err_set(err, OBS_ENOTFOUND, "technique \"%s\" no longer exists",
                       technique ? technique : "?");
  obs_backend want = OBS_BACKEND_AUTO, be = OBS_BACKEND_CPU;
  if (backend_requested && obs_backend_parse(backend_requested, &want)) want = OBS_BACKEND_CPU;
  int rc = srv_pick_backend(t, want, app->vulkan_lane, &be, err);
  if (rc) return rc;
  /* An "auto" job keeps the lane chosen at submission (possibly from measured timings) as long
   * as that lane still runs here. */
  if (want == OBS_BACKEND_AUTO &&
      (stored == SRV_LANE_VULKAN
           ? app->vulkan_lane && obs_technique_has_backend(t, OBS_BACKEND_VULKAN)
           : obs_technique_has_backend(t, OBS_BACKEND_CPU))) {
    *lane = stored;
    return 0;
  }
  *lane = be == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU;
  return 0;
}

int srv_pick_backend_learned(srv_app *app, const obs_technique *t, obs_backend requested,
                             double work, obs_backend *out, char *reason, size_t n, obs_err *err) {
  int rc = srv_pick_backend(t, requested, app->vulkan_lane, out, err);
  if (rc) return rc;
  if (requested != OBS_BACKEND_AUTO) {
    snprintf(reason, n, "requested");
    return 0;
  }
  if (!t->run[OBS_BACKEND_CPU] || !t->run[OBS_BACKEND_VULKAN]) {
    snprintf(reason, n, "static rule: %s is the only backend of %s", obs_backend_name(*out),
             t->name);
    return 0;
  }
  /* Medians of the stored timed runs of this technique at similar work, per backend. */
  json_t *rows = NULL;
  obs_err qerr = OBS_ERR_INIT;
  /* Runs count only on hosts of this one's kind (CPU model and threads: on a shared store other
   * nodes' hosts differ), and Vulkan runs only on a device of this lane's kind: a software
   * rasteriser's time never predicts a GPU's, nor the reverse. */
  srv_arg args[4] = {{SRV_ARG_TEXT, 0, 0, t->name},
                     {SRV_ARG_REAL, 0, work, NULL},
                     {SRV_ARG_TEXT, 0, 0, app->vulkan_kind},
                     {SRV_ARG_INT, app->machine_id, 0, NULL}};
  size_t count[2] = {0, 0};
  double med[2] = {NAN, NAN};
  if (work > 0 && !srv_db_query(app->db, SRV_Q_AUTO_RUNS, args, 4, &rows, &qerr)) {
    size_t nrows = json_array_size(rows);
    double *v[2] = {malloc((nrows + 1) * sizeof(double)), malloc((nrows + 1) * sizeof(double))};
    for (size_t i = 0; v[0] && v[1] && i < nrows; i++) {
      json_t *row = json_array_get(rows, i);
      obs_backend be = OBS_BACKEND_AUTO;
      double ms = json_number_value(json_object_get(row, "total_ms"));
      int known = !obs_backend_parse(json_string_value(json_object_get(row, "backend")), &be);
      int b = be == OBS_BACKEND_VULKAN;
      if (known && isfinite(ms) && ms >= 0) v[b][count[b]++] = ms;
    }
    for (int b = 0; b < 2; b++) {
      if (v[b]) med[b] = srv_median(v[b], count[b]);
      free(v[b]);
    }
    json_decref(rows);
  } else if (work > 0) {
    srv_log("learned auto: %s (using the static rule)", obs_err_message(&qerr));
  }
  obs_err_free(&qerr);
  if (!count[0] || !count[1]) {
    snprintf(reason, n,
             "static rule (no stored runs of %s on both backends at similar work): "
             "%s",
             t->name,
             *out == OBS_BACKEND_VULKAN ? "G-buffer techniques run on Vulkan "
                                          "when a device exists"
             : app->vulkan_lane         ? "the CPU"
                                        : "the CPU (no Vulkan lane)");
    return 0;
  }
  obs_backend faster = med[1] < med[0] ? OBS_BACKEND_VULKAN : OBS_BACKEND_CPU;
  char measured[200];
  snprintf(measured, sizeof measured,
           "median cpu %.3g ms (%zu runs) vs vulkan %.3g ms (%zu "
           "runs) for %s at work within 2x of %.3g",
           med[0], count[0], med[1], count[1], t->name, work);
  if (faster == OBS_BACKEND_VULKAN && !app->vulkan_lane) {
    *out = OBS_BACKEND_CPU;
    snprintf(reason, n, "measured: vulkan is faster (%s), but this server runs no Vulkan lane",
             measured);
  } else {
    *out = faster;
    snprintf(reason, n, "measured: %s is faster (%s)", obs_backend_name(faster), measured);
  }
  return 0;
}
