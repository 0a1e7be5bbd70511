/* `obscura submit`: a scene validated locally and sent to obscurad, then with --wait the job
 * followed to its end and its outputs downloaded. */
#include <curl/curl.h>
#include <errno.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "args.h"
#include "client.h"
#include "http.h"
#include "obscura/obscura.h"

#define POLL_MS 200          /* --wait polls the job this often */

typedef struct submit_opts {
  cli_scene_opts s;
  const char *server, *label, *out_dir;
  int priority; /* -1: not given (the server's default) */
  int wait;
} submit_opts;

static int parse_submit(int argc, char **argv, submit_opts *o) {
  memset(o, 0, sizeof *o);
  o->priority = -1;
  for (int i = 2; i < argc; i++) {
    int taken = cli_scene_option(&o->s, argc, argv, &i);
    if (taken < 0) return -1;
    if (taken) continue;
    const char *a = argv[i];
    if (!strcmp(a, "--server") || !strcmp(a, "--priority") || !strcmp(a, "--label") ||
        !strcmp(a, "-o")) {
      const char *val = cli_option_value(argc, argv, &i);
      if (!val) return -1;
      if (!strcmp(a, "--server")) {
        o->server = val;
      } else if (!strcmp(a, "--label")) {
        o->label = val;
      } else if (!strcmp(a, "-o")) {
        if (!*val) {
          fprintf(stderr, "obscura: -o needs a directory name\n");
          return -1;
        }
        o->out_dir = val;
        o->wait = 1;
      } else {
        char *end;
        long n = strtol(val, &end, 10);
        if (!*val || *end || n < 0 || n > 100) {
          fprintf(stderr, "obscura: --priority must be an integer from 0 to 100 (got %s)\n", val);
          return -1;
        }
        o->priority = (int)n;
      }
    } else if (!strcmp(a, "--wait")) {
      o->wait = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (!o->s.scene) {
      o->s.scene = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!o->s.scene) {
    fprintf(stderr, "obscura: missing SCENE.json\n");
    return -1;
  }
  o->server = cli_server(o->server);
  return 0;
}

/* The request body: the validated document (overrides and --technique/--backend applied) with
 * the wrapper keys. Meshes are named as in the document; the server reads them from its own
 * --scenes-dir, so say so. */
static char *submit_body(const obs_scene *sc, const submit_opts *o) {
  json_t *objs = json_object_get(sc->doc, "objects");
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (sc->objects[i].shape.type != OBS_SHAPE_MESH) continue;
    const char *file = json_string_value(
        json_object_get(json_object_get(json_array_get(objs, i), "shape"), "file"));
    fprintf(stderr, "obscura: note: mesh file \"%s\" is read by the server from its --scenes-dir\n",
            file ? file : "?");
  }
  json_t *doc = json_deep_copy(sc->doc);
  if (!doc) return NULL;
  if (o->priority >= 0) json_object_set_new(doc, "priority", json_integer(o->priority));
  /* The server names the job's scene after the file (an inline document has no name). */
  const char *base = strrchr(o->s.scene, '/');
  json_t *name = json_string(base ? base + 1 : o->s.scene);
  if (name && json_string_length(name) > 0 && json_string_length(name) <= 256)
    json_object_set_new(doc, "scene_name", name);
  else
    json_decref(name);
  if (o->label) {
    json_t *l = json_string(o->label);
    if (!l) {
      fprintf(stderr, "obscura: --label must be UTF-8 text\n");
      json_decref(doc);
      return NULL;
    }
    json_object_set_new(doc, "label", l);
  }
  char *text = json_dumps(doc, JSON_COMPACT);
  json_decref(doc);
  return text;
}

/* Polls the job until it is succeeded, failed or cancelled. Returns 0 with *job set to its last
 * state (new reference), or an exit status after printing why. */
/* The progress shown while a job is followed; reset when the server is lost (a restarted render
 * starts again from 0). */
typedef struct wait_state {
  cli_progress pr;
  int bar, last_tenth;
} wait_state;

static void wait_lost(void *user) {
  wait_state *w = user;
  if (w->bar) fputc('\n', stderr);
  w->bar = 0;
  w->pr.last = -1;
  w->last_tenth = 0;
}

static int wait_job(cli_client *c, long long id, const char *url, json_t **job) {
  *job = NULL;
  wait_state w = {.pr = {.tty = isatty(2), .last = -1}};
  char state[16] = "";
  double lost_since = -1;
  for (;;) {
    json_t *j;
    int rc = cli_poll_json(c, url, POLL_MS, &lost_since, wait_lost, &w, &j);
    if (rc == CLI_POLL_AGAIN) continue;
    if (rc) return rc;
    const char *st = json_string_value(json_object_get(j, "state"));
    double progress = json_number_value(json_object_get(j, "progress"));
    if (!st) {
      if (w.bar) fputc('\n', stderr);
      fprintf(stderr, "obscura: GET %s: the answer is not a job\n", url);
      json_decref(j);
      return EXIT_FAILURE;
    }
    int done = !strcmp(st, "succeeded") || !strcmp(st, "failed") || !strcmp(st, "cancelled");
    if (strcmp(st, state)) {
      if (w.bar) {
        if (!strcmp(st, "succeeded")) cli_progress_draw(&w.pr, 1.0);
        fputc('\n', stderr);
        w.bar = 0;
      }
      w.pr.last = -1;
      w.last_tenth = 0;
      fprintf(stderr, "job %lld: ", id);
      cli_put_clean(stderr, st);
      fputc('\n', stderr);
      snprintf(state, sizeof state, "%s", st);
    }
    if (done) {
      *job = j;
      return 0;
    }
    if (!strcmp(st, "running")) {
      if (w.pr.tty) {
        cli_progress_draw(&w.pr, progress);
        w.bar = 1;
      } else if ((int)(progress * 10.0) > w.last_tenth && progress < 1.0) {
        w.last_tenth = (int)(progress * 10.0);
        fprintf(stderr, "job %lld: running %d%%\n", id, w.last_tenth * 10);
      }
    }
    json_decref(j);
    cli_sleep_ms(POLL_MS);
  }
}

/* Output file names come from the server: plain names only. */
static int safe_name(const char *s) {
  if (!s || !*s || s[0] == '.' || strlen(s) > 128) return 0;
  for (; *s; s++)
    if (!((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z') || (*s >= '0' && *s <= '9') ||
          *s == '.' || *s == '_' || *s == '-'))
      return 0;
  return 1;
}

typedef struct sink {
  CURL *curl;
  FILE *f;
  long status; /* 0 until the first body bytes */
  curl_off_t bytes;
  int write_failed;
  cli_buf errbody; /* the body of a non-200 answer */
} sink;

static size_t sink_write(char *data, size_t size, size_t n, void *user) {
  sink *s = user;
  size_t k = size * n;
  if (!s->status) curl_easy_getinfo(s->curl, CURLINFO_RESPONSE_CODE, &s->status);
  if (s->status != 200) return cli_buf_write(data, size, n, &s->errbody);
  if (fwrite(data, 1, k, s->f) != k) {
    s->write_failed = errno ? errno : EIO;
    return 0;
  }
  s->bytes += (curl_off_t)k;
  return k;
}

/* Downloads one output into DIR/name through a temporary file and rename, checking its size. */
static int download(cli_client *c, const char *dir, const char *name, const char *ref,
                    long long size) {
  char *url = cli_client_url(c, ref);
  if (!url) return EXIT_FAILURE;
  char tmp[4096], final[4096];
  if (snprintf(final, sizeof final, "%s/%s", dir, name) >= (int)sizeof final ||
      snprintf(tmp, sizeof tmp, "%s/.%s.XXXXXX", dir, name) >= (int)sizeof tmp) {
    fprintf(stderr, "obscura: %s: path too long\n", dir);
    free(url);
    return EXIT_BAD_INPUT;
  }
  int fd = mkstemp(tmp);
  FILE *f = fd < 0 ? NULL : fdopen(fd, "wb");
  if (!f) {
    fprintf(stderr, "obscura: cannot create %s: %s\n", tmp, strerror(errno));
    if (fd >= 0) {
      close(fd);
      unlink(tmp);
    }
    free(url);
    return EXIT_FAILURE;
  }
  mode_t mask = umask(0);
  umask(mask);
  fchmod(fd, 0666 & ~mask);

  sink s = {.curl = c->curl, .f = f};
  cli_client_prepare(c, url, 0);
  curl_easy_setopt(c->curl, CURLOPT_WRITEFUNCTION, sink_write);
  curl_easy_setopt(c->curl, CURLOPT_WRITEDATA, &s);
  CURLcode cc = curl_easy_perform(c->curl);
  if (cc == CURLE_OK) curl_easy_getinfo(c->curl, CURLINFO_RESPONSE_CODE, &s.status);
  int rc = 0;
  if (s.write_failed) {
    fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(s.write_failed));
    rc = EXIT_FAILURE;
  } else if (cc) {
    rc = cli_transport_error(c, url, cc, s.errbody.overflow);
  } else if (s.status != 200) {
    cli_response r = {.status = s.status, .body = s.errbody};
    rc = cli_http_error(c, "GET", url, &r);
  }
  if (fflush(f) || fsync(fd)) {
    if (!rc) fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(errno));
    rc = rc ? rc : EXIT_FAILURE;
  }
  if (fclose(f) && !rc) {
    fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(errno));
    rc = EXIT_FAILURE;
  }
  if (!rc && s.bytes != (curl_off_t)size) {
    fprintf(stderr, "obscura: %s: downloaded %lld bytes but the job lists %lld\n", url,
            (long long)s.bytes, size);
    rc = EXIT_FAILURE;
  }
  if (!rc && rename(tmp, final)) {
    fprintf(stderr, "obscura: cannot rename %s to %s: %s\n", tmp, final, strerror(errno));
    rc = EXIT_FAILURE;
  }
  if (rc) unlink(tmp);
  free(s.errbody.p);
  free(url);
  return rc;
}

int cli_download_outputs(cli_client *c, json_t *job, const char *dir) {
  json_t *links = json_object_get(json_object_get(job, "links"), "outputs");
  json_t *list = json_object_get(job, "outputs");
  if (!json_is_object(links) || !json_object_size(links)) {
    fprintf(stderr, "obscura: the job lists no outputs to download\n");
    return EXIT_FAILURE;
  }
  obs_err derr = OBS_ERR_INIT;
  if (obs_path_make_dirs(dir, &derr)) {
    fprintf(stderr, "obscura: %s\n", obs_err_message(&derr));
    obs_err_free(&derr);
    return EXIT_FAILURE;
  }
  const char *name;
  json_t *ref;
  json_object_foreach(links, name, ref) {
    if (!safe_name(name)) {
      fprintf(stderr, "obscura: the server listed an output with an unusable name (");
      cli_put_clean(stderr, name);
      fprintf(stderr, ")\n");
      return EXIT_FAILURE;
    }
    json_t *size = NULL;
    size_t i;
    json_t *o;
    json_array_foreach(list, i, o) {
      if (json_is_string(json_object_get(o, "name")) &&
          !strcmp(json_string_value(json_object_get(o, "name")), name))
        size = json_object_get(o, "size");
    }
    if (!json_is_integer(size) || json_integer_value(size) < 0) {
      fprintf(stderr, "obscura: the job lists no size for output %s\n", name);
      return EXIT_FAILURE;
    }
    int rc = download(c, dir, name, json_string_value(ref), (long long)json_integer_value(size));
    if (rc) return rc;
    printf("%s/%s (%lld bytes)\n", dir, name, (long long)json_integer_value(size));
  }
  return 0;
}

static void print_finished(long long id, json_t *job) {
  json_t *be = json_object_get(job, "backend");
  const char *actual = json_string_value(json_object_get(be, "actual"));
  json_t *img = json_object_get(job, "image");
  json_t *t = json_object_get(job, "timings_ms");
  json_t *stats = json_object_get(job, "stats"), *ao = json_object_get(stats, "ao");
  /* A technique without ao: the first channel of its primary output. */
  const char *prim = json_string_value(json_object_get(stats, "primary_output"));
  const char *what = "AO";
  if (!ao && prim) {
    json_t *chs = json_object_get(json_object_get(json_object_get(stats, "outputs"), prim),
                                  "channels");
    ao = json_object_iter_value(json_object_iter(chs));
    what = prim;
  }
  printf("job %lld succeeded: ", id);
  cli_put_clean(stdout, json_string_value(json_object_get(job, "technique")));
  putchar('/');
  cli_put_clean(stdout, actual ? actual : "?");
  printf(" %lldx%lld, %.1f ms render (%.1f total), ",
         (long long)json_integer_value(json_object_get(img, "width")),
         (long long)json_integer_value(json_object_get(img, "height")),
         json_number_value(json_object_get(t, "render")),
         json_number_value(json_object_get(t, "total")));
  cli_put_clean(stdout, what);
  printf(" mean %.4f\n", json_number_value(json_object_get(ao, "mean")));
}

int cli_submit(int argc, char **argv) {
  submit_opts o;
  if (parse_submit(argc, argv, &o)) {
    cli_hint("submit");
    cli_scene_opts_free(&o.s);
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  if (rc) {
    cli_client_close(&c);
    cli_scene_opts_free(&o.s);
    return rc;
  }
  /* Everything the renderer would refuse is refused here, before anything is sent. */
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  int lrc = cli_scene_load(&o.s, &sc, &err);
  if (lrc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_err_free(&err);
    cli_client_close(&c);
    cli_scene_opts_free(&o.s);
    return cli_load_exit_code(lrc);
  }
  obs_err_free(&err);
  /* An unusable -o DIR is found now, not after the render. */
  if (o.out_dir && obs_path_make_dirs(o.out_dir, &err)) {
    fprintf(stderr, "obscura: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    obs_scene_free(&sc);
    cli_client_close(&c);
    cli_scene_opts_free(&o.s);
    return EXIT_BAD_INPUT;
  }
  char *body = submit_body(&sc, &o);
  obs_scene_free(&sc);
  char *url = body ? cli_client_url(&c, "/api/v1/jobs") : NULL;
  json_t *answer = NULL, *job = NULL;
  char *self = NULL;
  long long id = 0;
  if (!url) {
    rc = body ? EXIT_FAILURE : EXIT_BAD_INPUT;
    goto done;
  }
  cli_response r;
  CURLcode cc = cli_client_json(&c, "POST", url, body, &r);
  if (cc) {
    rc = cli_transport_error(&c, url, cc, r.body.overflow);
    cli_response_free(&r);
    goto done;
  }
  if (r.status != 201) {
    rc = cli_http_error(&c, "POST", url, &r);
    cli_response_free(&r);
    goto done;
  }
  answer = json_loads(r.body.p ? r.body.p : "", 0, NULL);
  cli_response_free(&r);
  json_t *jid = json_object_get(answer, "id");
  const char *ref = json_string_value(json_object_get(json_object_get(answer, "links"), "self"));
  if (!json_is_integer(jid) || !ref) {
    fprintf(stderr, "obscura: POST %s: the answer has no job id and link\n", url);
    rc = EXIT_FAILURE;
    goto done;
  }
  id = (long long)json_integer_value(jid);
  self = cli_client_url(&c, ref);
  if (!self) {
    rc = EXIT_FAILURE;
    goto done;
  }
  char route[64];
  snprintf(route, sizeof route, "jobs/%lld", id);
  char *page = cli_dashboard_url(&c, route);
  if (!page) {
    rc = EXIT_FAILURE;
    goto done;
  }
  printf("job %lld queued: %s\n", id, page);
  free(page);
  fflush(stdout);
  if (!o.wait) goto done;
  rc = wait_job(&c, id, self, &job);
  if (rc) goto done;
  const char *st = json_string_value(json_object_get(job, "state"));
  if (strcmp(st, "succeeded")) {
    const char *why = json_string_value(json_object_get(job, "error"));
    fprintf(stderr, "obscura: job %lld %s: ", id, st);
    cli_put_clean(stderr, why ? why : "(no error message)");
    fputc('\n', stderr);
    rc = EXIT_FAILURE;
    goto done;
  }
  print_finished(id, job);
  if (o.out_dir) rc = cli_download_outputs(&c, job, o.out_dir);
done:
  json_decref(job);
  json_decref(answer);
  free(self);
  free(url);
  free(body);
  cli_client_close(&c);
  cli_scene_opts_free(&o.s);
  return rc;
}
