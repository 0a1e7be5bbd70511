/* Test helper for the metrics cross-check (tests/tools/metrics_crosscheck.py): writes deterministic
 * candidate/reference image pairs as single-channel EXR and PNG files, and prints obscura's metrics
 * for a pair read back from those files, so OpenImageIO's idiff/oiiotool and a numpy SSIM can be
 * run on exactly the same pixels.
 *
 *   metrics_tool gen DIR
 *     writes DIR/<case>_cand.*, <case>_ref.* (and <case>_mask.exr) and prints one line per case:
 *     "<case> <ext> <mask 0|1>"
 *   metrics_tool compare CAND REF [MASK] [--channel CH]
 *     prints key=value lines: obs_metrics_compare of channel CH (default "Y") over the pixels
 *     where MASK > 0
 *   metrics_tool diff CAND.exr REF.exr CHANNEL...
 *     per channel present in both (all pixels): "<channel> rmse=R max_abs=M differ=F", F the
 *     fraction of pixels whose values differ by more than 1e-3 (the data-parallel render's check
 *     against the image-parallel one, tests/cli/mpi.sh)
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/image.h"
#include "obscura/metrics.h"

static int die(obs_err *err, const char *what) {
  fprintf(stderr, "metrics_tool: %s: %s\n", what, obs_err_message(err));
  obs_err_free(err);
  return 1;
}

/* Deterministic uniform [0,1) numbers (LCG, top 24 bits). */
static double lcg(uint32_t *s) {
  *s = *s * 1664525u + 1013904223u;
  return (double)(*s >> 8) / 16777216.0;
}

static float clamp01(double v) { return (float)(v < 0 ? 0 : v > 1 ? 1 : v); }

typedef struct {
  const char *name;
  int w, h;
  int png;  /* 8-bit PNG files instead of float EXR */
  int mask; /* also write <name>_mask.exr */
} gen_case;

static const gen_case k_cases[] = {
    {"noisy", 64, 48, 0, 0},     /* smooth field + uniform noise + positive bias */
    {"blurred", 41, 27, 0, 0},   /* box-blurred, darkened reference: structured negative bias */
    {"large", 33, 33, 0, 0},     /* an inverted block: errors up to ~0.9 */
    {"png8", 50, 40, 1, 0},      /* the noisy pair quantised to 8 bits */
    {"identical", 16, 16, 0, 0}, /* RMSE 0: PSNR is +inf for idiff, the 100 dB cap for obscura */
    {"tiny", 5, 3, 0, 0},        /* smaller than the 8x8 SSIM window */
    {"masked", 48, 40, 0, 1},    /* off-centre disc mask, garbage-sized errors outside it */
};

static double ref_value(const gen_case *c, int x, int y) {
  if (!strcmp(c->name, "blurred") || !strcmp(c->name, "large")) {
    double dx = x - c->w * 0.4, dy = y - c->h * 0.6;
    return 0.15 + 0.8 * exp(-(dx * dx + dy * dy) / (2.0 * 9.0 * 9.0));
  }
  return 0.5 + 0.35 * sin(x * 0.21 + 0.3) * cos(y * 0.17 - 0.2) + 0.1 * (double)y / c->h;
}

static int write_pair(const gen_case *c, const char *dir, obs_err *err) {
  const char *ch[] = {"Y"};
  const char *mch[] = {"Y"};
  obs_image ref, cand, mask;
  memset(&mask, 0, sizeof mask);
  int rc = obs_image_init(&ref, c->w, c->h, 1, ch, err);
  if (!rc) rc = obs_image_init(&cand, c->w, c->h, 1, ch, err);
  if (!rc && c->mask) rc = obs_image_init(&mask, c->w, c->h, 1, mch, err);
  if (rc) return rc;
  uint32_t s = 20240501u;
  for (size_t i = 0; i < strlen(c->name); i++) s = s * 31u + (uint32_t)c->name[i];
  for (int y = 0; y < c->h; y++)
    for (int x = 0; x < c->w; x++) ref.data[y * c->w + x] = clamp01(ref_value(c, x, y));
  for (int y = 0; y < c->h; y++)
    for (int x = 0; x < c->w; x++) {
      size_t i = (size_t)y * (size_t)c->w + (size_t)x;
      double r = ref.data[i], v = r;
      if (!strcmp(c->name, "blurred")) {
        double sum = 0;
        int n = 0;
        for (int j = -1; j <= 1; j++)
          for (int k = -1; k <= 1; k++) {
            int xx = x + k, yy = y + j;
            if (xx < 0 || yy < 0 || xx >= c->w || yy >= c->h) continue;
            sum += ref.data[yy * c->w + xx];
            n++;
          }
        v = 0.92 * sum / n;
      } else if (!strcmp(c->name, "large")) {
        v = (x >= 10 && x < 20 && y >= 12 && y < 25) ? 1.0 - r : r + 0.01 * (lcg(&s) - 0.5);
      } else if (!strcmp(c->name, "identical")) {
        v = r;
      } else if (!strcmp(c->name, "masked")) {
        double dx = x - 20.5, dy = y - 14.0;
        int in = dx * dx + dy * dy < 13.0 * 13.0;
        mask.data[i] = in ? 1.0f : 0.0f;
        v = in ? r - 0.04 + 0.1 * (lcg(&s) - 0.5) : 1.0 - r; /* big errors outside only */
      } else { /* noisy, png8 and tiny: noise plus a positive bias */
        v = r + 0.03 + 0.1 * (lcg(&s) - 0.5);
      }
      cand.data[i] = clamp01(v);
    }
  char path[4096];
  const char *ext = c->png ? "png" : "exr";
  snprintf(path, sizeof path, "%s/%s_ref.%s", dir, c->name, ext);
  rc = c->png ? obs_image_write_png(&ref, ch, 1, 0, path, err)
              : obs_image_write_exr(&ref, path, err);
  if (!rc) {
    snprintf(path, sizeof path, "%s/%s_cand.%s", dir, c->name, ext);
    rc = c->png ? obs_image_write_png(&cand, ch, 1, 0, path, err)
                : obs_image_write_exr(&cand, path, err);
  }
  if (!rc && c->mask) {
    snprintf(path, sizeof path, "%s/%s_mask.exr", dir, c->name);
    rc = obs_image_write_exr(&mask, path, err);
  }
  obs_image_free(&ref);
  obs_image_free(&cand);
  obs_image_free(&mask);
  return rc;
}

static int read_any(obs_image *img, const char *path, obs_err *err) {
  size_t n = strlen(path);
  if (n > 4 && !strcmp(path + n - 4, ".png")) return obs_image_read_png(img, path, err);
  return obs_image_read_exr(img, path, err);
}

/* The diff subcommand (see the top of the file). */
static int diff_channels(int argc, char **argv, obs_err *err) {
  obs_image a, b;
  if (obs_image_read_exr(&a, argv[2], err)) return die(err, argv[2]);
  if (obs_image_read_exr(&b, argv[3], err)) return die(err, argv[3]);
  if (a.width != b.width || a.height != b.height)
    return fprintf(stderr, "metrics_tool: the images' sizes differ\n"), 1;
  size_t n = (size_t)a.width * (size_t)a.height;
  for (int i = 4; i < argc; i++) {
    const float *x = obs_image_channel(&a, argv[i]), *y = obs_image_channel(&b, argv[i]);
    if (!x || !y) return fprintf(stderr, "metrics_tool: no channel %s\n", argv[i]), 1;
    double se = 0, mx = 0;
    size_t differ = 0;
    for (size_t k = 0; k < n; k++) {
      double d = fabs((double)x[k] - (double)y[k]);
      if (!(d <= mx)) mx = d; /* NaN sticks */
      se += d * d;
      differ += !(d <= 1e-3);
    }
    printf("%s rmse=%.6g max_abs=%.6g differ=%.6g\n", argv[i], sqrt(se / (double)n), mx,
           (double)differ / (double)n);
  }
  obs_image_free(&a);
  obs_image_free(&b);
  return 0;
}

int main(int argc, char **argv) {
  obs_err err = OBS_ERR_INIT;
  if (argc >= 5 && !strcmp(argv[1], "diff")) return diff_channels(argc, argv, &err);
  if (argc == 3 && !strcmp(argv[1], "gen")) {
    for (size_t i = 0; i < sizeof k_cases / sizeof k_cases[0]; i++) {
      if (write_pair(&k_cases[i], argv[2], &err)) return die(&err, k_cases[i].name);
      printf("%s %s %d\n", k_cases[i].name, k_cases[i].png ? "png" : "exr", k_cases[i].mask);
    }
    return 0;
  }
  const char *ch = "Y";
  if (argc >= 6 && !strcmp(argv[argc - 2], "--channel")) {
    ch = argv[argc - 1];
    argc -= 2;
  }
  if ((argc == 4 || argc == 5) && !strcmp(argv[1], "compare")) {
    obs_image cand, ref, mask, refm;
    if (read_any(&cand, argv[2], &err)) return die(&err, argv[2]);
    if (read_any(&ref, argv[3], &err)) return die(&err, argv[3]);
    const obs_image *reference = &ref;
    const char *mask_name = NULL;
    memset(&refm, 0, sizeof refm);
    if (argc == 5) {
      /* The reference with the mask file's plane added as "alpha". */
      if (read_any(&mask, argv[4], &err)) return die(&err, argv[4]);
      const char *names[] = {ch, "alpha"};
      if (mask.width != ref.width || mask.height != ref.height)
        return fprintf(stderr, "metrics_tool: mask size differs\n"), 1;
      if (obs_image_init(&refm, ref.width, ref.height, 2, names, &err)) return die(&err, "mask");
      size_t n = (size_t)ref.width * (size_t)ref.height;
      const float *rv = obs_image_channel(&ref, ch);
      if (!rv) return fprintf(stderr, "metrics_tool: no channel %s\n", ch), 1;
      memcpy(obs_image_channel(&refm, ch), rv, n * sizeof(float));
      memcpy(obs_image_channel(&refm, "alpha"), mask.data, n * sizeof(float));
      obs_image_free(&mask);
      reference = &refm;
      mask_name = "alpha";
    }
    obs_compare m;
    if (obs_metrics_compare(&cand, reference, ch, mask_name, &m, &err))
      return die(&err, "compare");
    const float *r = obs_image_channel(&ref, ch);
    int w = ref.width, h = ref.height;
    printf("width=%d\nheight=%d\npixels=%lld\n", w, h, (long long)m.pixels);
    printf("rmse=%.17g\nbias=%.17g\nmax_abs=%.17g\npsnr=%.17g\nssim=%.17g\n", m.rmse, m.bias,
           m.max_abs, m.psnr, m.ssim);
    /* Corner values of the reference (row 0 is the top), to pin down other readers' orientation. */
    printf("ref_top_left=%.9g\nref_top_right=%.9g\nref_bottom_left=%.9g\n", r[0], r[w - 1],
           r[(size_t)(h - 1) * (size_t)w]);
    obs_image_free(&cand);
    obs_image_free(&ref);
    obs_image_free(&refm);
    obs_err_free(&err);
    return 0;
  }
  fprintf(stderr, "usage: metrics_tool gen DIR | metrics_tool compare CAND REF [MASK] "
                  "[--channel CH] |\n"
                  "       metrics_tool diff CAND.exr REF.exr CHANNEL...\n");
  return 2;
}
