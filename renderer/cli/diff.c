/* `obscura diff A B`: every metric of the table for a candidate against a reference (two EXR
 * files or two output folders), and their error maps, as idiff and flip do; `obscura metrics`:
 * the metric table itself (JSON, Markdown, OpenAPI). The figures come from
 * obs_metrics_compare_all, the function the server's comparisons use. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "args.h"
#include "diff.h"
#include "obscura/obscura.h"

typedef struct diff_opts {
  const char *a, *b, *channel, *mask, *out_dir;
  int json, mask_none;
  double ppd;
} diff_opts;

static int diff_bad(const char *fmt, const char *what) {
  fprintf(stderr, "obscura diff: ");
  fprintf(stderr, fmt, what);
  fputc('\n', stderr);
  cli_hint("diff");
  return EXIT_BAD_INPUT;
}

static int parse(int argc, char **argv, diff_opts *o) {
  memset(o, 0, sizeof *o);
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--channel") || !strcmp(a, "--mask") || !strcmp(a, "-o") ||
        !strcmp(a, "--ppd")) {
      const char *v = cli_option_value(argc, argv, &i);
      if (!v) return EXIT_BAD_INPUT;
      if (!strcmp(a, "--channel")) {
        o->channel = v;
      } else if (!strcmp(a, "--mask")) {
        o->mask_none = !strcmp(v, "none");
        o->mask = o->mask_none ? NULL : v;
      } else if (!strcmp(a, "-o")) {
        o->out_dir = v;
      } else {
        char *end;
        o->ppd = strtod(v, &end);
        if (*end || !(o->ppd > 0 && o->ppd <= 200))
          return diff_bad("--ppd takes pixels per degree in (0, 200] (got %s)", v);
      }
    } else if (!strcmp(a, "--json")) {
      o->json = 1;
    } else if (a[0] == '-' && a[1]) {
      return diff_bad("unknown option %s (see obscura diff --help)", a);
    } else if (!o->a) {
      o->a = a;
    } else if (!o->b) {
      o->b = a;
    } else {
      return diff_bad("unexpected argument %s: diff takes two images or folders", a);
    }
  }
  if (!o->b) return diff_bad("%s", "needs a candidate and a reference: obscura diff A B");
  return 0;
}

/* Reads `path`: an EXR file, or an output folder's primary EXR (the technique its summary.json
 * names). `tech` gets the folder's technique (NULL for a file). */
static int read_input(const char *path, obs_image *img, const obs_technique **tech,
                      obs_err *err) {
  struct stat st;
  *tech = NULL;
  if (stat(path, &st)) return obs_err_set(err, OBS_ENOTFOUND, "%s: no such file or folder", path);
  if (!S_ISDIR(st.st_mode)) return obs_image_read_exr(img, path, err);
  char file[4300];
  snprintf(file, sizeof file, "%s/summary.json", path);
  json_t *sum = json_load_file(file, 0, NULL);
  const char *name = json_string_value(json_object_get(sum, "technique"));
  *tech = obs_technique_find(name);
  json_decref(sum);
  if (!*tech)
    return obs_err_set(err, OBS_EINVAL,
                       "%s: not an output folder (no summary.json naming a technique)", path);
  char exr[OBS_OUTPUT_FILE_MAX];
  obs_technique_exr_name(*tech, exr, sizeof exr);
  snprintf(file, sizeof file, "%s/%s", path, exr);
  return obs_image_read_exr(img, file, err);
}

/* The channel compared when --channel is not given: the output a comparison of the folders'
 * techniques compares, else "ao" when the reference has it. */
static const char *default_channel(const obs_technique *ta, const obs_technique *tb,
                                   const obs_image *ref, char *buf, size_t n) {
  const obs_output *o = ta && tb ? obs_technique_compared_output(ta, tb) : NULL;
  if (!o && tb) o = obs_technique_primary(tb);
  if (o) {
    snprintf(buf, n, o->kind == OBS_OUTPUT_DEPTH ? "%s.Z" : "%s", o->name);
    return buf;
  }
  return obs_image_channel(ref, "ao") ? "ao" : NULL;
}

/* error.exr/png (on the scalar channel, the luminance of an RGB output) and flip.exr/png. */
static int write_maps(const obs_image *a, const obs_image *b, const char *ch, const char *mask,
                      const obs_image *flip, const char *dir, obs_err *err) {
  obs_image la, lb, e;
  memset(&la, 0, sizeof la);
  memset(&lb, 0, sizeof lb);
  memset(&e, 0, sizeof e);
  int rc = 0;
  if (!obs_image_channel(b, ch)) { /* an RGB output: its luminance */
    rc = obs_metrics_luminance_image(a, ch, NULL, &la, err);
    if (!rc) rc = obs_metrics_luminance_image(b, ch, NULL, &lb, err);
    a = &la, b = &lb;
  }
  if (!rc) rc = obs_metrics_error_image(a, b, ch, mask, &e, err);
  if (!rc) rc = obs_metrics_write_error_files(&e, dir, err);
  if (!rc && flip->data) rc = obs_metrics_write_flip_files(flip, dir, err);
  obs_image_free(&la);
  obs_image_free(&lb);
  obs_image_free(&e);
  return rc;
}

static void print_text(const diff_opts *o, const char *ch, const char *mask,
                       const obs_metric_values *v) {
  printf("%s against %s, channel %s, %s: %lld pixels\n", o->a, o->b, ch,
         mask ? mask : "every pixel", (long long)v->pixels);
  const obs_metric *t = obs_metric_table();
  for (int i = 0; i < OBS_METRIC_COUNT; i++) {
    if (!v->has[i]) continue;
    const char *better = t[i].direction == OBS_METRIC_LOWER    ? "lower is better"
                         : t[i].direction == OBS_METRIC_HIGHER ? "higher is better"
                         : t[i].direction == OBS_METRIC_ZERO   ? "closer to 0 is better"
                                                               : "";
    printf("  %-16s %-14.*g %-4s %s\n", t[i].name, t[i].digits + 2, v->v[i], t[i].unit, better);
  }
  if (v->has[OBS_METRIC_REF_NOISE] && v->at_reference_accuracy)
    printf("  the difference is within the reference's own noise (rmse < 2 ref_noise)\n");
}

static int print_json(const diff_opts *o, const char *ch, const char *mask,
                      const obs_metric_values *v) {
  json_t *m = json_object(), *doc = json_pack("{s:s, s:s, s:s, s:s?}", "candidate", o->a,
                                              "reference", o->b, "channel", ch, "mask", mask);
  const obs_metric *t = obs_metric_table();
  for (int i = 0; i < OBS_METRIC_COUNT; i++)
    if (v->has[i])
      json_object_set_new(m, t[i].name, isfinite(v->v[i]) ? json_real(v->v[i]) : json_null());
  json_object_set_new(m, "pixels", json_integer(v->pixels));
  json_object_set_new(m, "at_reference_accuracy", json_boolean(v->at_reference_accuracy));
  json_object_set_new(doc, "metrics", m);
  char *s = json_dumps(doc, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
  json_decref(doc);
  if (!s) return EXIT_FAILURE;
  puts(s);
  free(s);
  return 0;
}

/* Two output folders whose techniques name the compared quantity differently (ss_radiosity's
 * `final` against path_trace's `radiance`): the reference's primary output, and its standard
 * error, are read under the candidate's names, as the server's comparisons read them. */
static void align_reference(const obs_technique *ta, const obs_technique *tb, obs_image *b) {
  const obs_output *o = ta && tb ? obs_technique_compared_output(ta, tb) : NULL;
  const obs_output *ro = tb ? obs_technique_primary(tb) : NULL;
  if (!o || !ro || o->kind != ro->kind || !strcmp(o->name, ro->name)) return;
  obs_image_rename_output(b, ro->name, o->name);
  const char *se = obs_technique_stderr_name(tb, ro->name);
  char cs[OBS_CHANNEL_NAME_MAX];
  snprintf(cs, sizeof cs, "%s_stderr", o->name);
  if (se) obs_image_rename_output(b, se, cs);
}

int cli_diff(int argc, char **argv) {
  diff_opts o;
  int rc = parse(argc, argv, &o);
  if (rc) return rc;
  obs_err err = OBS_ERR_INIT;
  obs_image a, b, flip;
  memset(&a, 0, sizeof a);
  memset(&b, 0, sizeof b);
  memset(&flip, 0, sizeof flip);
  const obs_technique *ta, *tb;
  char chbuf[OBS_CHANNEL_NAME_MAX + 4];
  const char *ch = NULL, *mask = NULL;
  int code = read_input(o.a, &a, &ta, &err);
  if (!code) code = read_input(o.b, &b, &tb, &err);
  if (!code) align_reference(ta, tb, &b);
  if (!code && !(ch = o.channel ? o.channel : default_channel(ta, tb, &b, chbuf, sizeof chbuf)))
    code = obs_err_set(&err, OBS_EINVAL, "%s has no \"ao\" channel: name one with --channel", o.b);
  /* The reference's coverage, as the comparisons use it, unless --mask says otherwise. */
  if (!code) mask = o.mask ? o.mask : !o.mask_none && obs_image_channel(&b, "alpha") ? "alpha" : NULL;
  obs_metric_values v;
  obs_metric_opts mo = {.channel = ch, .mask = mask, .ppd = o.ppd, .flip_map = &flip};
  if (!code) code = obs_metrics_compare_all(&a, &b, &mo, &v, &err);
  /* Unreadable, missing or mismatched inputs are bad input; only memory is trouble here. */
  int exit_code = !code ? 0 : code == OBS_ENOMEM ? EXIT_FAILURE : EXIT_BAD_INPUT;
  if (!code && o.out_dir) {
    if (v.has[OBS_METRIC_ANGLE_DEG])
      fprintf(stderr, "obscura diff: no error maps for directions; -o %s left alone\n", o.out_dir);
    else if ((code = write_maps(&a, &b, ch, mask, &flip, o.out_dir, &err)))
      exit_code = EXIT_FAILURE;
  }
  if (code)
    fprintf(stderr, "obscura diff: %s\n", obs_err_message(&err));
  else if (o.json)
    exit_code = print_json(&o, ch, mask, &v);
  else
    print_text(&o, ch, mask, &v);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&flip);
  obs_err_free(&err);
  return exit_code;
}

int cli_metrics(int argc, char **argv) {
  const char *what = argc == 3 ? argv[2] : argc == 2 ? "--json" : NULL;
  char *txt = NULL;
  if (what && !strcmp(what, "--json")) {
    json_t *t = obs_metric_table_json();
    txt = json_dumps(t, JSON_INDENT(2));
    json_decref(t);
    if (txt) puts(txt);
  } else if (what && (!strcmp(what, "--markdown") || !strcmp(what, "--openapi"))) {
    txt = what[2] == 'm' ? obs_metric_table_markdown() : obs_metric_table_openapi();
    if (txt) fputs(txt, stdout);
  } else {
    fprintf(stderr, "obscura metrics: takes one of --json, --markdown, --openapi%s%s\n",
            argc > 2 ? "; got " : "", argc > 2 ? argv[2] : "");
    cli_hint("metrics");
    return EXIT_BAD_INPUT;
  }
  if (!txt) return EXIT_FAILURE;
  free(txt);
  return 0;
}
