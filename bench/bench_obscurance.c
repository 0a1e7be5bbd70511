/* The article's Cornell box as numbers: obscurance's final image without and with colour bleeding
 * against the path_trace reference (RMSE and SSIM of luminance, per-channel RMSE), the reference's
 * own noise (two seeds), a time-against-error row per `samples`, and optionally the PNGs of the
 * three images for docs/img. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "obscura/obscura.h"

typedef struct options {
  int threads, size, ref_samples, samples, light_samples;
  double d_max; /* obscurance's d_max */
  const char *png_dir;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_obscurance [--threads N] [--size W] [--ref-samples S] [--samples S]\n"
          "                        [--light-samples S] [--d-max D] [--png-dir DIR]\n"
          "  Renders scenes/cornell_box.json at W x W (default 128) with path_trace (S paths per\n"
          "  pixel, default 4096, twice with two seeds) and obscurance's final image without and\n"
          "  with colour bleeding (defaults: samples 256, light_samples 256, d_max 300, about\n"
          "  half the box's width), and prints RMSE and SSIM of both against the reference, then time and\n"
          "  error per samples 4..256. --png-dir writes the three images as tone-mapped PNGs.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(), .size = 128, .ref_samples = 4096, .samples = 256,
                 .light_samples = 256, .d_max = 300};
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--size", 8, 4096, &o->size),
      BENCH_OPT_INT("--ref-samples", 1, 65536, &o->ref_samples),
      BENCH_OPT_INT("--samples", 1, 65536, &o->samples),
      BENCH_OPT_INT("--light-samples", 1, 4096, &o->light_samples),
      BENCH_OPT_REAL("--d-max", 0, HUGE_VAL, BENCH_OPEN_LO, &o->d_max),
      BENCH_OPT_STR("--png-dir", &o->png_dir),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* Renders the Cornell box at size x size with `technique` and `params`; render time in *ms. */
static int render(const options *o, const char *technique, const char *params, obs_result *res,
                  double *ms) {
  char size[16], name[48];
  snprintf(size, sizeof size, "%d", o->size);
  snprintf(name, sizeof name, "\"%s\"", technique);
  const obs_override ov[] = {{"/image/width", size},
                             {"/image/height", size},
                             {"/image/spp", "1"},
                             {"/technique/name", name},
                             {"/technique/params", params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, OBS_SOURCE_DIR "/scenes/cornell_box.json", ov, 5, &err);
  obs_render_opts opts = {.threads = o->threads};
  if (!rc) {
    rc = obs_render(&sc, &opts, res, &err);
    obs_scene_free(&sc);
  }
  if (rc) fprintf(stderr, "bench_obscurance: %s: %s\n", technique, obs_err_message(&err));
  else *ms = res->timings.render_ms;
  obs_err_free(&err);
  return rc;
}

/* The RGB output `out` of `img` as an image of channels radiance.R/G/B (and alpha), so that any
 * two RGB outputs go through the one comparison. */
static int as_radiance(const obs_image *img, const char *out, obs_image *dst) {
  static const char *const names[4] = {"radiance.R", "radiance.G", "radiance.B", "alpha"};
  static const char *const rgb[3] = {"R", "G", "B"};
  obs_err err = OBS_ERR_INIT;
  int rc = obs_image_init(dst, img->width, img->height, 4, names, &err);
  size_t n = (size_t)img->width * (size_t)img->height;
  for (int k = 0; !rc && k < 4; k++) {
    char ch[64];
    if (k < 3) snprintf(ch, sizeof ch, "%s.%s", out, rgb[k]);
    else snprintf(ch, sizeof ch, "alpha");
    const float *v = obs_image_channel(img, ch);
    if (!v) rc = obs_err_set(&err, OBS_ENOTFOUND, "no channel %s", ch);
    else memcpy(dst->data + (size_t)k * n, v, n * sizeof *v);
  }
  if (rc) fprintf(stderr, "bench_obscurance: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

static int compare(const obs_image *cand, const obs_image *ref, obs_compare_rgb *c) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_metrics_compare_rgb(cand, ref, "radiance", "alpha", c, &err);
  if (rc) fprintf(stderr, "bench_obscurance: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

/* Mean of each channel of radiance.R/G/B over the image. */
static void means(const obs_image *img, double m[3]) {
  static const char *const rgb[3] = {"radiance.R", "radiance.G", "radiance.B"};
  size_t n = (size_t)img->width * (size_t)img->height;
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(img, rgb[k]);
    double s = 0;
    for (size_t i = 0; i < n; i++) s += v[i];
    m[k] = s / (double)n;
  }
}

static void print_row(const char *what, const obs_image *img, const obs_compare_rgb *c) {
  double m[3];
  means(img, m);
  printf("  %-34s RMSE lum %.5f  SSIM lum %.4f  RMSE R G B %.5f %.5f %.5f  mean R G B %.4f "
         "%.4f %.4f\n",
         what, c->rmse_luminance, c->ssim_luminance, c->rmse[0], c->rmse[1], c->rmse[2], m[0],
         m[1], m[2]);
}

static int write_png(const obs_image *img, const char *dir, const char *file) {
  static const char *const rgb[3] = {"radiance.R", "radiance.G", "radiance.B"};
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", dir, file);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_image_write_png(img, rgb, 3, 1, path, &err);
  if (rc) fprintf(stderr, "bench_obscurance: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

/* obscurance's params: samples and light samples, colour bleeding, d_max. */
static const char *ob_params(const options *o, int samples, int light, int bleed, int seed) {
  static char buf[256];
  char dm[48];
  snprintf(dm, sizeof dm, ",\"d_max\":%.17g", o->d_max);
  snprintf(buf, sizeof buf,
           "{\"samples\":%d,\"light_samples\":%d,\"color_bleeding\":%s,\"seed\":%d%s}", samples,
           light, bleed ? "true" : "false", seed, dm);
  return buf;
}

static double lum(const double m[3]) { return 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2]; }

/* Where the error comes from: the reference's indirect light (path_trace minus path_trace with
 * one bounce) against the model's, in mean, and the comparison again with the model's indirect
 * term scaled to the reference's mean luminance (final = direct + indirect, so this is the model
 * with I_A times that factor: the level of I_A taken out of the error, its distribution over the
 * image and its colour left). */
static int explain(const options *o, const obs_image *ref, obs_result ob[2]) {
  obs_result d;
  double ms, mref[3], mdir[3];
  char params[96];
  snprintf(params, sizeof params, "{\"samples\":%d,\"max_bounces\":1,\"seed\":5}",
           o->ref_samples);
  obs_image dimg;
  if (render(o, "path_trace", params, &d, &ms) || as_radiance(&d.image, "radiance", &dimg))
    return 1;
  means(ref, mref);
  means(&dimg, mdir);
  double ind_ref[3];
  for (int k = 0; k < 3; k++) ind_ref[k] = mref[k] - mdir[k];
  printf("indirect light (image mean R G B): reference %.4f %.4f %.4f (path_trace minus "
         "path_trace with max_bounces 1)\n",
         ind_ref[0], ind_ref[1], ind_ref[2]);
  int rc = 0;
  for (int b = 0; b < 2 && !rc; b++) {
    obs_image ind, dir;
    double m[3];
    rc = as_radiance(&ob[b].image, "indirect", &ind) || as_radiance(&ob[b].image, "direct", &dir);
    if (rc) break;
    means(&ind, m);
    double fit = lum(ind_ref) / lum(m);
    size_t n = (size_t)ind.width * (size_t)ind.height;
    for (size_t i = 0; i < 3 * n; i++) dir.data[i] += (float)(fit * ind.data[i]);
    obs_compare_rgb c;
    rc = compare(&dir, ref, &c);
    if (!rc) {
      printf("  %s: model %.4f %.4f %.4f; I_A x %.3f matches the reference's mean luminance:\n",
             b ? "with colour bleeding" : "without colour bleeding", m[0], m[1], m[2], fit);
      print_row(b ? "  with colour bleeding, I_A fitted" : "  without bleeding, I_A fitted", &dir,
                &c);
    }
    obs_image_free(&ind);
    obs_image_free(&dir);
  }
  obs_image_free(&dimg);
  obs_result_free(&d);
  return rc;
}

/* Time against error per samples (light_samples equal to it): error against a converged
 * obscurance (same model, 1024 of each, another seed) and against the reference. */
static int sweep(const options *o, const obs_image *ref) {
  obs_result conv;
  double ms;
  if (render(o, "obscurance", ob_params(o, 1024, 1024, 1, 99), &conv, &ms)) return 1;
  obs_image conv_img;
  if (as_radiance(&conv.image, "final", &conv_img)) return 1;
  printf("time against error, colour bleeding, light_samples = samples (converged: 1024, %.0f ms)\n",
         ms);
  printf("  %7s %10s %12s %14s %14s\n", "samples", "render ms", "us/pixel", "RMSE vs conv.",
         "RMSE vs ref.");
  int rc = 0;
  for (int s = 4; s <= 256 && !rc; s *= 4) {
    obs_result r;
    obs_image img;
    obs_compare_rgb a, b;
    rc = render(o, "obscurance", ob_params(o, s, s, 1, 1), &r, &ms);
    if (rc) break;
    rc = as_radiance(&r.image, "final", &img);
    if (!rc) rc = compare(&img, &conv_img, &a) || compare(&img, ref, &b);
    if (!rc)
      printf("  %7d %10.1f %12.2f %14.5f %14.5f\n", s, ms, ms * 1e3 / ((double)o->size * o->size),
             a.rmse_luminance, b.rmse_luminance);
    obs_image_free(&img);
    obs_result_free(&r);
  }
  obs_image_free(&conv_img);
  obs_result_free(&conv);
  return rc;
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  bench_print_machine();
  obs_result pt[2], ob[2];
  obs_image ref[2], cand[2];
  double ms_pt = 0, ms_ob[2] = {0, 0}, ms;
  char params[96];
  for (int i = 0; i < 2; i++) {
    snprintf(params, sizeof params, "{\"samples\":%d,\"seed\":%d}", o.ref_samples, 11 + i);
    if (render(&o, "path_trace", params, &pt[i], &ms) || as_radiance(&pt[i].image, "radiance",
                                                                       &ref[i]))
      return 1;
    ms_pt += ms;
  }
  for (int b = 0; b < 2; b++)
    if (render(&o, "obscurance", ob_params(&o, o.samples, o.light_samples, b, 1), &ob[b],
               &ms_ob[b]) ||
        as_radiance(&ob[b].image, "final", &cand[b]))
      return 1;
  char dm[32];
  snprintf(dm, sizeof dm, "%g", o.d_max);
  printf("cornell_box %dx%d, %d threads; path_trace %d paths per pixel (%.0f ms each);\n"
         "obscurance samples %d, light_samples %d, d_max %s, sqrt falloff, halton (%.0f ms without "
         "bleeding, %.0f ms with)\n",
         o.size, o.size, o.threads, o.ref_samples, ms_pt / 2, o.samples, o.light_samples,
         dm, ms_ob[0], ms_ob[1]);
  obs_compare_rgb c[3];
  if (compare(&cand[0], &ref[0], &c[0]) || compare(&cand[1], &ref[0], &c[1]) ||
      compare(&ref[1], &ref[0], &c[2]))
    return 1;
  printf("final image against the path_trace reference\n");
  print_row("without colour bleeding", &cand[0], &c[0]);
  print_row("with colour bleeding", &cand[1], &c[1]);
  print_row("reference noise (its other seed)", &ref[1], &c[2]);
  int rc = 0;
  if (o.png_dir)
    rc = write_png(&cand[0], o.png_dir, "obscurance_cornell_plain.png") ||
         write_png(&cand[1], o.png_dir, "obscurance_cornell_bleeding.png") ||
         write_png(&ref[0], o.png_dir, "obscurance_cornell_reference.png");
  if (!rc) rc = explain(&o, &ref[0], ob);
  if (!rc) rc = sweep(&o, &ref[0]);
  for (int i = 0; i < 2; i++) {
    obs_image_free(&ref[i]);
    obs_image_free(&cand[i]);
    obs_result_free(&pt[i]);
    obs_result_free(&ob[i]);
  }
  return rc ? 1 : 0;
}
