/* The obscura command-line tool: render, validate, list techniques, and the job server's client
 * commands (client.h). */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "args.h"
#include "client.h"
#include "diff.h"
#include "mpi_render.h"
#include "obscura/obscura.h"

/* Where render writes when -o is not given. */
#define DEFAULT_OUT "out"

typedef struct cli {
  cli_scene_opts s;
  const char *out_dir; /* -o, else DEFAULT_OUT */
  int out_given;       /* -o was given: the folder was named, so whatever is there is replaced */
  int threads, quiet;
  int data, no_ghost; /* --distribute data, --no-ghost */
  const char *progress_file;
} cli;

static int parse_args(int argc, char **argv, int first, cli *c) {
  memset(c, 0, sizeof *c);
  c->out_dir = DEFAULT_OUT;
  for (int i = first; i < argc; i++) {
    int taken = cli_scene_option(&c->s, argc, argv, &i);
    if (taken < 0) return -1;
    if (taken) continue;
    const char *a = argv[i];
    if (!strcmp(a, "-o") || !strcmp(a, "--threads") || !strcmp(a, "--distribute") ||
        !strcmp(a, "--progress-file")) {
      const char *val = cli_option_value(argc, argv, &i);
      if (!val) return -1;
      if (!strcmp(a, "-o")) {
        c->out_dir = val;
        c->out_given = 1;
      } else if (!strcmp(a, "--progress-file")) {
        c->progress_file = val;
      } else if (!strcmp(a, "--distribute")) {
        if (strcmp(val, "image") && strcmp(val, "data")) {
          fprintf(stderr, "obscura: --distribute takes image or data (got %s)\n", val);
          return -1;
        }
        c->data = !strcmp(val, "data");
      } else {
        char *end;
        long n = strtol(val, &end, 10);
        if (*end || n < 1 || n > 1024) {
          fprintf(stderr, "obscura: --threads must be an integer from 1 to 1024 (got %s)\n", val);
          return -1;
        }
        c->threads = (int)n;
      }
    } else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) {
      c->quiet = 1;
    } else if (!strcmp(a, "--no-ghost")) {
      c->no_ghost = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (!c->s.scene) {
      c->s.scene = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!c->s.scene) {
    fprintf(stderr, "obscura: missing SCENE.json\n");
    return -1;
  }
  if (c->no_ghost && !c->data) {
    fprintf(stderr, "obscura: --no-ghost goes with --distribute data\n");
    return -1;
  }
  return 0;
}

/* --distribute data splits the scene's volumes, on the CPU backend (obs_brick): what cannot is
 * said before any rank renders, as bad input. */
static int check_distribute(const cli *c, const obs_scene *sc, obs_err *err) {
  return c->data && obs_render_brick_check(sc, err) ? OBS_EINVAL : 0;
}

/* Without -o a render writes DEFAULT_OUT, the same folder for every scene, so running a second
 * scene would silently replace the first one's outputs. The folder's summary.json names the scene
 * it was rendered from (its file name): a render of another scene is refused, bad input, before
 * anything renders; naming the folder with -o says to replace it. */
static int check_default_out(const cli *c, const obs_scene *sc, obs_err *err) {
  if (c->out_given) return 0;
  json_t *sum = json_load_file(DEFAULT_OUT "/summary.json", 0, NULL);
  const char *was = json_string_value(json_object_get(sum, "scene"));
  int rc = 0;
  if (was && strcmp(was, sc->name))
    rc = obs_err_set(err, OBS_EINVAL,
                     "obscura: " DEFAULT_OUT "/ holds the outputs of %s (" DEFAULT_OUT
                     "/summary.json), not of %s: give -o DIR for this scene's, or -o " DEFAULT_OUT
                     " to replace them",
                     was, sc->name);
  json_decref(sum);
  return rc;
}

static void free_args(cli *c) { cli_scene_opts_free(&c->s); }

/* Prints what a finished render wrote: the mean of the primary output (its channel, or the
 * luminance of an RGB one), the times and the rays. */
static void print_render(const obs_result *res, const obs_scene *sc, const char *out_dir) {
  const obs_output *prim = obs_technique_primary(res->technique);
  char exr[OBS_OUTPUT_FILE_MAX], what[OBS_OUTPUT_NAME_MAX + 16];
  obs_technique_exr_name(res->technique, exr, sizeof exr);
  double mean = 0;
  obs_stats st;
  if (prim->kind == OBS_OUTPUT_RGB) {
    obs_metrics_luminance_mean(&res->image, prim->name, NULL, &mean, NULL);
    snprintf(what, sizeof what, "%s luminance", prim->name);
  } else if (obs_metrics_stats(&res->image, prim->name, NULL, &st, NULL) == 0) {
    mean = st.mean;
    snprintf(what, sizeof what, "%s", strcmp(prim->name, "ao") ? prim->name : "AO");
  } else {
    snprintf(what, sizeof what, "%s", prim->name);
  }
  char rays[48] = "", ranks[24] = "";
  if (res->rays && res->timings.render_ms > 0)
    snprintf(rays, sizeof rays, ", %.3g Mrays/s", (double)res->rays / res->timings.render_ms / 1e3);
  if (res->ranks > 1) snprintf(ranks, sizeof ranks, " on %d ranks", res->ranks);
  printf("%s: %s/%s %dx%d%s, %.1f ms render (%.1f build)%s, %s mean %.4f -> %s/%s\n", sc->name,
         res->technique->name, obs_backend_name(res->backend), res->image.width, res->image.height,
         ranks, res->timings.render_ms, res->timings.build_ms, rays, what, mean, out_dir, exr);
}

/* Under mpirun (more than one rank) the render is split across the ranks (mpi_render.h); rank 0
 * alone speaks and writes, as a one-process run would. */
static int cmd_render(int argc, char **argv) {
  cli c;
  int worker = cli_mpi_env_size() > 1 && cli_mpi_env_rank() > 0;
  if (parse_args(argc, argv, 2, &c)) {
    if (!worker) cli_hint("render");
    free_args(&c);
    return EXIT_BAD_INPUT;
  }
  obs_err err = OBS_ERR_INIT;
  cli_mpi *mpi = NULL;
  int rc = cli_mpi_env_size() > 1 ? cli_mpi_init(&mpi, &err) : 0;
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_err_free(&err);
    free_args(&c);
    return EXIT_FAILURE;
  }
  obs_scene sc;
  double t0 = obs_now_ms();
  rc = cli_scene_load(&c.s, &sc, &err);
  if (!rc && (rc = check_distribute(&c, &sc, &err))) obs_scene_free(&sc);
  if (!rc && !worker && (rc = check_default_out(&c, &sc, &err))) obs_scene_free(&sc);
  int code = rc ? cli_load_exit_code(rc) : 0;
  if (mpi)
    code = cli_mpi_loaded(mpi, code, &err);
  else if (rc)
    fprintf(stderr, "%s\n", obs_err_message(&err));
  if (code) {
    if (!rc) obs_scene_free(&sc);
    obs_err_free(&err);
    free_args(&c);
    cli_mpi_finish(mpi);
    return code;
  }
  double load_ms = obs_now_ms() - t0;
  int tty = mpi ? cli_mpi_tty() : isatty(2);
  cli_progress pr = {.tty = !c.quiet && !worker && tty, .last = -1};
  /* Without it the render goes on: progress is for whoever watches, the outputs are the job. */
  if (c.progress_file && !worker) cli_progress_file(&pr, c.progress_file);
  obs_render_opts opts = {.threads = c.threads, .progress = cli_progress_draw, .progress_user = &pr};
  /* One process renders the one brick there is; under mpirun each rank its own. */
  if (c.data) opts.brick = (obs_brick){0, 1, c.no_ghost};
  if (mpi && !opts.threads) opts.threads = cli_mpi_threads();
  obs_result res;
  rc = mpi ? cli_mpi_render(mpi, &sc, &opts, &pr, &res, &err) : obs_render(&sc, &opts, &res, &err);
  if (pr.tty) fputc('\n', stderr);
  if (rc || worker) {
    if (rc && !worker) fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_result_free(&res);
    obs_scene_free(&sc);
    obs_err_free(&err);
    free_args(&c);
    cli_mpi_finish(mpi);
    return rc == 0 ? 0 : rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE;
  }
  res.timings.load_ms = load_ms;
  res.timings.total_ms += load_ms;
  for (int i = 0; i < res.nwarnings; i++) fprintf(stderr, "obscura: warning: %s\n", res.warnings[i]);
  rc = obs_result_write(&res, &sc, c.out_dir, &err);
  if (rc)
    fprintf(stderr, "%s\n", obs_err_message(&err));
  else if (!c.quiet)
    print_render(&res, &sc, c.out_dir);
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free_args(&c);
  cli_mpi_finish(mpi);
  return rc == 0 ? 0 : rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

static int cmd_validate(int argc, char **argv) {
  cli c;
  if (parse_args(argc, argv, 2, &c)) {
    cli_hint("validate");
    free_args(&c);
    return EXIT_BAD_INPUT;
  }
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  int rc = cli_scene_load(&c.s, &sc, &err);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
  } else {
    printf("%s: valid (%s, %zu objects)\n", sc.name, sc.technique->name, sc.nobjects);
    obs_scene_free(&sc);
  }
  obs_err_free(&err);
  free_args(&c);
  return rc == 0 ? 0 : rc == OBS_EINVAL || rc == OBS_EIO ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

static int cmd_techniques(int argc, char **argv) {
  if (argc == 3 && !strcmp(argv[2], "--markdown")) {
    char *md = obs_technique_ranges_markdown();
    if (!md) return EXIT_FAILURE;
    fputs(md, stdout);
    free(md);
    return 0;
  }
  if (argc >= 3 && (!strcmp(argv[2], "--schema") || !strcmp(argv[2], "--openapi") ||
                    !strcmp(argv[2], "--docs"))) {
    int docs = !strcmp(argv[2], "--docs");
    if (argc != (docs ? 4 : 3)) {
      fprintf(stderr, "obscura: %s %s\n", argv[2],
              docs ? "takes one technique name" : "takes no argument");
      cli_hint("techniques");
      return EXIT_BAD_INPUT;
    }
    char *txt = docs ? obs_registry_params_markdown(argv[3])
                : argv[2][2] == 's' ? obs_registry_scene_schema()
                                    : obs_registry_openapi();
    if (!txt) {
      fprintf(stderr, "obscura: %s\n", docs ? "no such technique" : "out of memory");
      return docs ? EXIT_BAD_INPUT : EXIT_FAILURE;
    }
    fputs(txt, stdout);
    free(txt);
    return 0;
  }
  if (argc > 2) {
    fprintf(stderr, "obscura: unknown option %s\n", argv[2]);
    cli_hint("techniques");
    return EXIT_BAD_INPUT;
  }
  json_t *reg = obs_technique_registry_json();
  char *s = json_dumps(reg, JSON_INDENT(2));
  puts(s ? s : "[]");
  free(s);
  json_decref(reg);
  return 0;
}

/* `obscura help [CMD]`: the usage of CMD, or of every command. */
static int cmd_help(int argc, char **argv) {
  if (argc > 3) {
    fprintf(stderr, "obscura: help takes at most one command\n");
    return EXIT_BAD_INPUT;
  }
  if (!cli_usage(stdout, argc == 3 ? argv[2] : NULL)) return 0;
  fprintf(stderr, "obscura: no command %s\n", argv[2]);
  cli_hint(NULL);
  return EXIT_BAD_INPUT;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    cli_usage(stderr, NULL);
    return EXIT_BAD_INPUT;
  }
  if (argv[1][0] != '-' && cli_wants_help(argc, argv) && !cli_usage(stdout, argv[1])) return 0;
  if (!strcmp(argv[1], "help")) return cmd_help(argc, argv);
  if (!strcmp(argv[1], "render")) return cmd_render(argc, argv);
  if (!strcmp(argv[1], "validate")) return cmd_validate(argc, argv);
  if (!strcmp(argv[1], "techniques")) return cmd_techniques(argc, argv);
  if (!strcmp(argv[1], "submit")) return cli_submit(argc, argv);
  if (!strcmp(argv[1], "jobs")) return cli_jobs(argc, argv);
  if (!strcmp(argv[1], "job")) return cli_job(argc, argv);
  if (!strcmp(argv[1], "cancel")) return cli_cancel(argc, argv);
  if (!strcmp(argv[1], "fetch")) return cli_fetch(argc, argv);
  if (!strcmp(argv[1], "comparisons")) return cli_comparisons(argc, argv);
  if (!strcmp(argv[1], "compare")) return cli_compare(argc, argv);
  if (!strcmp(argv[1], "diff")) return cli_diff(argc, argv);
  if (!strcmp(argv[1], "metrics")) return cli_metrics(argc, argv);
  if (!strcmp(argv[1], "--version")) {
    puts("obscura " OBSCURA_VERSION);
    return 0;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    cli_usage(stdout, NULL);
    return 0;
  }
  fprintf(stderr, "obscura: unknown command %s\n", argv[1]);
  cli_hint(NULL);
  return EXIT_BAD_INPUT;
}
