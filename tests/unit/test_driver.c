/* The shared drivers: the per-pixel driver's region, rays, progress, cancellation and thread
 * independence on a synthetic shade function (a pixel and a block at a time), then the same
 * properties through obs_render for rt_ao and proximity_ao (per-pixel driver, BVH built by the
 * framework; proximity_ao shades blocks) and ssao/hbao (CPU screen-space driver); the tile watch
 * (obs_tile_watch) told of every tile once, with its pixels final, and of the end once. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "testutil.h"

#define W 70
#define H 45

static const char *scene_json(const char *technique, const char *params) {
  static char buf[1024];
  snprintf(buf, sizeof buf,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0.3,0],"
           "\"up\":[0,1,0],\"fov_y\":45},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{\"name\":\"ground\",\"shape\":{\"type\":\"quad\",\"vertices\":"
           "[[-20,0,-20],[-20,0,20],[20,0,20],[20,0,-20]]}},{\"name\":\"ball\",\"shape\":"
           "{\"type\":\"sphere\",\"center\":[0,1,0],\"radius\":0.5}}],"
           "\"technique\":{\"name\":\"%s\",\"backend\":\"cpu\",\"params\":%s}}",
           W, H, technique, params);
  return buf;
}

/* A pixel's values depend on (x, y) only; each pixel "traces" x % 3 + 1 rays. */
typedef struct synth {
  atomic_int *cancel_at_first; /* raised by the first pixel shaded, when set */
} synth;

static uint64_t synth_shade(const void *job, int thread, int x, int y, float *v) {
  const synth *s = job;
  (void)thread;
  if (s->cancel_at_first) atomic_store(s->cancel_at_first, 1);
  v[0] = sinf((float)x * 0.37f) + (float)y;
  v[1] = (float)(x * 1000 + y);
  v[2] = 1.0f;
  return (uint64_t)(x % 3 + 1);
}

/* The same pixels a block at a time: a block never leaves its cell of the block grid. */
static uint64_t synth_block(const void *job, int thread, int x0, int y0, int x1, int y1, float *v) {
  const int B = OBS_PIXEL_BLOCK;
  assert_true(x0 < x1 && y0 < y1);
  assert_int_equal(x0 / B, (x1 - 1) / B);
  assert_int_equal(y0 / B, (y1 - 1) / B);
  const int n = (x1 - x0) * (y1 - y0);
  uint64_t rays = 0;
  for (int y = y0, i = 0; y < y1; y++)
    for (int x = x0; x < x1; x++, i++) {
      float p[3];
      rays += synth_shade(job, thread, x, y, p);
      for (int c = 0; c < 3; c++) v[c * n + i] = p[c];
    }
  return rays;
}

static const char *const synth_names[3] = {"a", "b", "alpha"};
static const obs_pixel_ops synth_ops = {3, synth_names, .shade = synth_shade};
static const obs_pixel_ops synth_block_ops = {3, synth_names, .block = synth_block};
/* Both ways of shading: every property of the driver holds for each. */
static const obs_pixel_ops *const synth_ways[2] = {&synth_ops, &synth_block_ops};

typedef struct progress_log {
  int calls;
  double last, min_step;
} progress_log;

static void log_progress(void *user, double f) {
  progress_log *p = user;
  if (p->calls && f - p->last < p->min_step) p->min_step = f - p->last;
  p->last = f;
  p->calls++;
}

static void ctx_init(obs_render_ctx *ctx, const obs_scene *sc, int threads) {
  memset(ctx, 0, sizeof *ctx);
  ctx->scene = sc;
  ctx->params = sc->params;
  ctx->threads = threads;
}

static void check_pixels_region(const obs_pixel_ops *ops) {
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  obs_render_ctx ctx;
  ctx_init(&ctx, &sc, 2);
  progress_log pl = {0, 0, 1};
  ctx.progress = log_progress;
  ctx.progress_user = &pl;
  ctx.region = (obs_region){5, 3, 67, 41};
  synth s = {NULL};
  obs_image img;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_driver_pixels(&ctx, ops, &s, &img, &err), 0);
  assert_int_equal(img.width, W);
  assert_int_equal(img.height, H);
  assert_int_equal(img.nchannels, 3);
  assert_string_equal(img.names[1], "b");
  uint64_t rays = 0;
  size_t plane = (size_t)W * H;
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      size_t i = (size_t)y * W + (size_t)x;
      int in = x >= 5 && x < 67 && y >= 3 && y < 41;
      float v[3];
      if (in) rays += synth_shade(&s, 0, x, y, v);
      for (int c = 0; c < 3; c++)
        if (in)
          assert_true(img.data[c * plane + i] == v[c]);
        else
          assert_true(img.data[c * plane + i] == 0.0f);
    }
  assert_int_equal(ctx.rays, rays);
  /* 62x38 pixels are 2x2 tiles: four reports, the last one 1, never going back. */
  assert_int_equal(pl.calls, 4);
  assert_true(pl.last == 1.0);
  assert_true(pl.min_step > 0);
  obs_image_free(&img);
  /* A region outside the image, or empty, is refused. */
  ctx.region = (obs_region){0, 0, W + 1, H};
  assert_int_equal(obs_driver_pixels(&ctx, ops, &s, &img, &err), OBS_EINVAL);
  assert_null(img.data);
  ctx.region = (obs_region){10, 10, 10, 20};
  assert_int_equal(obs_driver_pixels(&ctx, ops, &s, &img, &err), OBS_EINVAL);
  obs_err_free(&err);
  obs_scene_free(&sc);
}

static void test_pixels_region(void **state) {
  (void)state;
  for (int k = 0; k < 2; k++) check_pixels_region(synth_ways[k]);
}

static void test_pixels_threads(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  obs_image img[6];
  uint64_t rays[6];
  const int threads[3] = {1, 2, 5};
  synth s = {NULL};
  obs_err err = OBS_ERR_INIT;
  for (int k = 0; k < 6; k++) {
    obs_render_ctx ctx;
    ctx_init(&ctx, &sc, threads[k % 3]);
    assert_int_equal(obs_driver_pixels(&ctx, synth_ways[k / 3], &s, &img[k], &err), 0);
    rays[k] = ctx.rays;
  }
  for (int k = 1; k < 6; k++) {
    assert_memory_equal(img[0].data, img[k].data, sizeof(float) * 3 * W * H);
    assert_int_equal(rays[0], rays[k]);
  }
  for (int k = 0; k < 6; k++) obs_image_free(&img[k]);
  obs_err_free(&err);
  obs_scene_free(&sc);
}

static void test_pixels_cancel(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  atomic_int cancel;
  atomic_init(&cancel, 0);
  obs_render_ctx ctx;
  ctx_init(&ctx, &sc, 1);
  ctx.cancel = &cancel;
  progress_log pl = {0, 0, 1};
  ctx.progress = log_progress;
  ctx.progress_user = &pl;
  synth s = {&cancel};
  obs_image img;
  obs_err err = OBS_ERR_INIT;
  /* Raised while the first tile runs: it finishes, the next never starts, nothing is returned
   * (and nothing stays allocated: the ASan build checks). */
  assert_int_equal(obs_driver_pixels(&ctx, &synth_ops, &s, &img, &err), OBS_ECANCELED);
  assert_null(img.data);
  assert_int_equal(pl.calls, 1);
  assert_non_null(strstr(obs_err_message(&err), "cancelled"));
  obs_err_free(&err);
  obs_scene_free(&sc);
}

/* What a tile watch saw: each pixel's tile count, its values when told, the end calls. */
typedef struct watch_log {
  pthread_mutex_t mu;
  int seen[W * H];
  float at_tile[W * H];
  int ends, tiles;
  const obs_image *img;
} watch_log;

static void watch_tile(void *user, const obs_image *img, const obs_region *t) {
  watch_log *w = user;
  pthread_mutex_lock(&w->mu);
  w->img = img;
  w->tiles++;
  for (int y = t->y0; y < t->y1; y++)
    for (int x = t->x0; x < t->x1; x++) {
      w->seen[y * W + x]++;
      w->at_tile[y * W + x] = img->data[y * W + x];
    }
  pthread_mutex_unlock(&w->mu);
}

static void watch_end(void *user, const obs_image *img) {
  watch_log *w = user;
  assert_ptr_equal(img, w->img);
  w->ends++;
}

static void test_pixels_watch(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  for (int way = 0; way < 2; way++) {
    watch_log *w = calloc(1, sizeof *w);
    pthread_mutex_init(&w->mu, NULL);
    obs_tile_watch watch = {watch_tile, watch_end, w};
    obs_render_ctx ctx;
    ctx_init(&ctx, &sc, 3);
    ctx.region = (obs_region){5, 3, 67, 41};
    ctx.watch = &watch;
    synth s = {NULL};
    obs_image img;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_driver_pixels(&ctx, synth_ways[way], &s, &img, &err), 0);
    /* Every pixel of the region in exactly one tile, none outside; the value seen when its tile
     * was reported is the final one; one end, after the last tile, with the image returned. */
    int inside = 0;
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++) {
        int in = x >= 5 && x < 67 && y >= 3 && y < 41;
        assert_int_equal(w->seen[y * W + x], in);
        if (in) assert_true(w->at_tile[y * W + x] == img.data[y * W + x]);
        inside += in;
      }
    assert_int_equal(inside, 62 * 38);
    assert_int_equal(w->tiles, 2 * 2); /* 62 x 38 in 32 x 32 tiles */
    assert_int_equal(w->ends, 1);
    assert_ptr_equal(w->img, &img);
    obs_image_free(&img);
    obs_err_free(&err);
    pthread_mutex_destroy(&w->mu);
    free(w);
  }
  obs_scene_free(&sc);
}

static int has_stage(const obs_result *r, const char *name) {
  for (int i = 0; i < r->nstages; i++)
    if (!strcmp(r->stage_names[i], name)) return 1;
  return 0;
}

/* A technique rendered whole and on a region: the region's pixels are the whole render's. */
static void check_region(const char *technique, const char *params, const char *stage) {
  obs_scene sc;
  obs_test_load(scene_json(technique, params), "d.json", &sc);
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  obs_result full, part, one;
  assert_int_equal(obs_render(&sc, &o, &full, &err), 0);
  assert_true(has_stage(&full, stage));
  assert_true(full.timings.build_ms >= 0 && full.timings.render_ms >= 0);
  assert_true(full.timings.build_ms + full.timings.render_ms <= full.timings.total_ms);
  obs_region r = {17, 9, 53, 40};
  o.region = r;
  assert_int_equal(obs_render(&sc, &o, &part, &err), 0);
  obs_test_assert_region(&full.image, &part.image, r);
  obs_render_opts o1 = {.threads = 1};
  assert_int_equal(obs_render(&sc, &o1, &one, &err), 0);
  assert_memory_equal(full.image.data, one.image.data,
                      sizeof(float) * (size_t)full.image.nchannels * W * H);
  obs_result_free(&full);
  obs_result_free(&part);
  obs_result_free(&one);
  obs_err_free(&err);
  obs_scene_free(&sc);
}

static void test_rt_ao_region(void **state) {
  (void)state;
  check_region("rt_ao", "{\"samples\":16}", "bvh");
}

static void test_proximity_ao_region(void **state) {
  (void)state;
  check_region("proximity_ao", "{\"volume_res\":32}", "corners");
}

static void test_ssao_region(void **state) {
  (void)state;
  check_region("ssao", "{\"samples\":8}", "gbuffer");
}

static void test_hbao_region(void **state) {
  (void)state;
  check_region("hbao", "{\"directions\":4,\"steps\":4,\"radius\":1,\"half_res\":true}",
               "upsample");
}

typedef struct cancel_on {
  atomic_int *flag;
  int at, calls;
  double last;
} cancel_on;

static void cancel_progress(void *user, double f) {
  cancel_on *c = user;
  assert_true(f >= c->last && f <= 1.0);
  c->last = f;
  if (++c->calls == c->at) atomic_store(c->flag, 1);
}

/* A screen-space render reports progress up to 1 and stops mid-passes when cancelled. */
static void check_progress_cancel(const char *technique, const char *params) {
  obs_scene sc;
  obs_test_load(scene_json(technique, params), "d.json", &sc);
  obs_err err = OBS_ERR_INIT;
  atomic_int cancel;
  atomic_init(&cancel, 0);
  cancel_on c = {&cancel, -1, 0, 0};
  obs_render_opts o = {.threads = 2, .cancel = &cancel, .progress = cancel_progress,
                       .progress_user = &c};
  obs_result r;
  assert_int_equal(obs_render(&sc, &o, &r, &err), 0);
  assert_true(c.last == 1.0);
  assert_true(c.calls > 2);
  obs_result_free(&r);
  c = (cancel_on){&cancel, 1, 0, 0};
  assert_int_equal(obs_render(&sc, &o, &r, &err), OBS_ECANCELED);
  assert_null(r.image.data);
  assert_true(c.last < 1.0);
  assert_non_null(strstr(obs_err_message(&err), "cancelled"));
  obs_err_free(&err);
  obs_scene_free(&sc);
}

static void test_hbao_progress_cancel(void **state) {
  (void)state;
  check_progress_cancel("hbao", "{\"directions\":4,\"steps\":4,\"radius\":1,\"blur_radius\":2}");
}

static void test_ssao_progress_cancel(void **state) {
  (void)state;
  check_progress_cancel("ssao", "{\"samples\":8,\"blur\":true}");
}

/* A tile source over a list of tiles, as a caller splitting a render hands them out: any size,
 * any order, only some of the region. Serialised by its own lock, as sources must be. */
typedef struct list_source {
  pthread_mutex_t lock;
  const obs_region *tiles;
  int ntiles, next, done;
  uint64_t rays;
  int fail_next; /* the code `next` returns once the list is half taken (0: none) */
  int fail_done; /* the code `done` returns (0: none) */
} list_source;

static int list_next(void *user, obs_region *tile) {
  list_source *s = user;
  pthread_mutex_lock(&s->lock);
  int rc = 0;
  if (s->fail_next && s->next >= s->ntiles / 2)
    rc = s->fail_next;
  else if (s->next < s->ntiles)
    *tile = s->tiles[s->next++], rc = 1;
  pthread_mutex_unlock(&s->lock);
  return rc;
}

static int list_done(void *user, const obs_image *img, const obs_region *tile, uint64_t rays) {
  list_source *s = user;
  /* The tile's pixels are there when done is called. */
  size_t i = (size_t)tile->y0 * (size_t)img->width + (size_t)tile->x0;
  assert_true(img->data[(size_t)2 * img->width * img->height + i] == 1.0f);
  pthread_mutex_lock(&s->lock);
  s->done++;
  s->rays += rays;
  pthread_mutex_unlock(&s->lock);
  return s->fail_done;
}

static void list_init(list_source *s, const obs_region *tiles, int n) {
  memset(s, 0, sizeof *s);
  pthread_mutex_init(&s->lock, NULL);
  s->tiles = tiles;
  s->ntiles = n;
}

/* The tiles of the region [5,67)x[3,41) in a scrambled order and odd sizes, leaving some out. */
static const obs_region source_tiles[] = {{40, 20, 67, 41}, {5, 3, 6, 4},    {20, 3, 40, 20},
                                          {6, 3, 20, 11},   {5, 30, 17, 41}, {40, 3, 67, 20},
                                          {5, 11, 20, 20}};

static void test_pixels_source(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  const obs_region region = {5, 3, 67, 41};
  const int n = (int)(sizeof source_tiles / sizeof source_tiles[0]);
  synth s = {NULL};
  obs_err err = OBS_ERR_INIT;
  obs_render_ctx ctx;
  ctx_init(&ctx, &sc, 1);
  ctx.region = region;
  obs_image whole;
  assert_int_equal(obs_driver_pixels(&ctx, &synth_ops, &s, &whole, &err), 0);
  assert_int_equal(ctx.tiled, 0);
  for (int way = 0; way < 4; way++) {
    const int threads = way % 2 ? 3 : 1;
    list_source src;
    list_init(&src, source_tiles, n);
    obs_tile_source ts = {list_next, list_done, &src};
    progress_log pl = {0, 0, 1};
    ctx_init(&ctx, &sc, threads);
    ctx.region = region;
    ctx.tiles = &ts;
    ctx.progress = log_progress;
    ctx.progress_user = &pl;
    obs_image img;
    assert_int_equal(obs_driver_pixels(&ctx, synth_ways[way / 2], &s, &img, &err), 0);
    assert_int_equal(ctx.tiled, 1);
    assert_int_equal(src.done, n);
    assert_int_equal(src.rays, ctx.rays);
    assert_int_equal(pl.calls, 0); /* the source sees the tiles; the driver reports nothing */
    /* Each tile holds the whole render's bits; the rest of the image stays 0. */
    size_t plane = (size_t)W * H;
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++) {
        int in = 0;
        for (int t = 0; t < n; t++)
          in |= x >= source_tiles[t].x0 && x < source_tiles[t].x1 && y >= source_tiles[t].y0 &&
                y < source_tiles[t].y1;
        for (int c = 0; c < 3; c++) {
          size_t i = (size_t)c * plane + (size_t)y * W + (size_t)x;
          if (in)
            assert_memory_equal(&whole.data[i], &img.data[i], sizeof(float));
          else
            assert_true(img.data[i] == 0.0f);
        }
      }
    obs_image_free(&img);
    pthread_mutex_destroy(&src.lock);
  }
  obs_image_free(&whole);
  obs_err_free(&err);
  obs_scene_free(&sc);
}

/* A source's failure stops the render with its code; a tile outside the region is refused. */
static void test_pixels_source_errors(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(scene_json("rt_ao", "{}"), "d.json", &sc);
  const int n = (int)(sizeof source_tiles / sizeof source_tiles[0]);
  synth s = {NULL};
  obs_err err = OBS_ERR_INIT;
  obs_render_ctx ctx;
  obs_image img;
  list_source src;
  obs_tile_source ts = {list_next, list_done, &src};
  for (int k = 0; k < 3; k++) {
    list_init(&src, source_tiles, n);
    if (k == 0) src.fail_next = OBS_EIO;
    if (k == 1) src.fail_done = OBS_ENOMEM;
    ctx_init(&ctx, &sc, 2);
    ctx.region = (obs_region){5, 3, 67, 41};
    if (k == 2) ctx.region = (obs_region){5, 3, 60, 41}; /* the first tile reaches x 67 */
    ctx.tiles = &ts;
    obs_err_clear(&err);
    int rc = obs_driver_pixels(&ctx, &synth_ops, &s, &img, &err);
    assert_int_equal(rc, k == 0 ? OBS_EIO : k == 1 ? OBS_ENOMEM : OBS_EINVAL);
    assert_null(img.data);
    if (k == 2)
      assert_non_null(strstr(obs_err_message(&err), "tile [40,67)x[20,41)"));
    else
      assert_non_null(strstr(obs_err_message(&err), "tile source"));
    pthread_mutex_destroy(&src.lock);
  }
  obs_err_free(&err);
  obs_scene_free(&sc);
}

/* Through obs_render: rt_ao and proximity_ao (which shades blocks of pixels) split between two
 * sources (as two processes would) add up to the whole render's bits and rays, and say `tiled`;
 * ssao, which does not render per pixel, ignores the source and renders the whole image. */
static void test_render_tile_source(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  const char *techniques[3][2] = {{"ssao", "{\"samples\":8}"},
                                  {"rt_ao", "{\"samples\":8}"},
                                  {"proximity_ao", "{\"volume_res\":32}"}};
  for (int k = 0; k < 3; k++) {
    obs_scene sc;
    obs_test_load(scene_json(techniques[k][0], techniques[k][1]), "d.json", &sc);
    obs_render_opts o = {.threads = 2};
    obs_result whole, part[2];
    assert_int_equal(obs_render(&sc, &o, &whole, &err), 0);
    assert_int_equal(whole.tiled, 0);
    /* Alternate 16x16 tiles to the two halves. */
    obs_region tiles[2][16];
    int n[2] = {0, 0}, i = 0;
    for (int y = 0; y < H; y += 16)
      for (int x = 0; x < W; x += 16, i++)
        tiles[i % 2][n[i % 2]++] =
            (obs_region){x, y, x + 16 < W ? x + 16 : W, y + 16 < H ? y + 16 : H};
    uint64_t rays = 0;
    for (int h = 0; h < 2; h++) {
      list_source src;
      list_init(&src, tiles[h], n[h]);
      obs_tile_source ts = {list_next, NULL, &src};
      o.tiles = &ts;
      assert_int_equal(obs_render(&sc, &o, &part[h], &err), 0);
      assert_int_equal(part[h].tiled, k > 0);
      rays += part[h].rays;
      pthread_mutex_destroy(&src.lock);
    }
    size_t count = (size_t)whole.image.nchannels * W * H;
    if (k > 0) {
      /* Pasted, not added: -0.0 + 0.0 would not keep the bits. */
      for (int c = 0; c < whole.image.nchannels; c++)
        for (int t = 0; t < n[1]; t++)
          for (int y = tiles[1][t].y0; y < tiles[1][t].y1; y++)
            for (int x = tiles[1][t].x0; x < tiles[1][t].x1; x++) {
              size_t j = (size_t)c * W * H + (size_t)y * W + (size_t)x;
              part[0].image.data[j] = part[1].image.data[j];
            }
      assert_int_equal(rays, whole.rays);
    }
    for (int h = 0; h < (k > 0 ? 1 : 2); h++)
      assert_memory_equal(whole.image.data, part[h].image.data, count * sizeof(float));
    obs_result_free(&whole);
    for (int h = 0; h < 2; h++) obs_result_free(&part[h]);
    obs_scene_free(&sc);
  }
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_pixels_region),       cmocka_unit_test(test_pixels_threads),
      cmocka_unit_test(test_pixels_cancel),       cmocka_unit_test(test_pixels_watch),
      cmocka_unit_test(test_rt_ao_region),
      cmocka_unit_test(test_ssao_region),         cmocka_unit_test(test_hbao_region),
      cmocka_unit_test(test_hbao_progress_cancel), cmocka_unit_test(test_ssao_progress_cancel),
      cmocka_unit_test(test_pixels_source),       cmocka_unit_test(test_pixels_source_errors),
      cmocka_unit_test(test_render_tile_source), cmocka_unit_test(test_proximity_ao_region),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
