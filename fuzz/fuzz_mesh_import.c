/* libFuzzer target for obscurad's contained mesh import: each input becomes a mesh file in a
 * temporary scenes directory (.ply, .obj, .off or .stl, chosen by the first byte) and goes through
 * the daemon-side importer, so assimp runs in the worker process obscura-import. Whatever assimp
 * does with it (abort, crash, loop, garbage), the calling process must get back either a valid mesh
 * (indices in range, finite coordinates) or an error naming the file, and never crash itself.
 *
 * Build standalone (from the repository root, after building obscura-import and the renderer
 * library libobscura.a in build/):
 *   clang -std=c11 -g -O1 -fsanitize=fuzzer,address,undefined -D_DEFAULT_SOURCE \
 *     -Irenderer/include -Irenderer/core -Iserver fuzz/fuzz_mesh_import.c server/meshimport.c \
 *     server/meshproto.c server/meshcache.c server/util.c build/libobscura.a \
 *     $(pkg-config --cflags --libs jansson assimp) -lm -lpthread -o build/fuzz_mesh_import
 *   build/fuzz_mesh_import -max_total_time=60 -timeout=30 tests/data/mesh
 * (the renderer library's own dependencies, e.g. Embree, are linked as for obscurad.) The worker
 * is $OBSCURA_IMPORT, else obscura-import next to the fuzzer executable; each import may take
 * $OBSCURA_FUZZ_IMPORT_SECONDS (default 0.05: inputs that loop are common, and each costs this
 * long) before the worker is killed. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "meshimport.h"

static srv_meshimport *importer;
static char root[PATH_MAX];

static void die(const char *what) {
  fprintf(stderr, "fuzz_mesh_import: %s\n", what);
  abort();
}

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc;
  (void)argv;
  /* As in obscurad: a worker's closed pipe is an error to handle, not a signal to die of. */
  signal(SIGPIPE, SIG_IGN);
  char exe[PATH_MAX];
  const char *env = getenv("OBSCURA_IMPORT");
  if (env) {
    snprintf(exe, sizeof exe, "%s", env);
  } else {
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 32);
    if (n <= 0) die("cannot read /proc/self/exe; set OBSCURA_IMPORT");
    exe[n] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash) die("no directory in /proc/self/exe");
    strcpy(slash + 1, "obscura-import");
  }
  const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
  char tmpl[PATH_MAX];
  snprintf(tmpl, sizeof tmpl, "%s/fuzz-mesh-XXXXXX", tmp);
  if (!mkdtemp(tmpl) || !realpath(tmpl, root)) die("cannot create the scenes directory");
  const char *s = getenv("OBSCURA_FUZZ_IMPORT_SECONDS");
  /* No cache: every input must reach the worker (a rewritten file could otherwise match the
   * previous one's identity within one timestamp tick). */
  srv_meshimport_opts o = {exe, s ? atof(s) : 0.05, 1LL << 30, 1 << 20, 0};
  if (!(o.seconds >= 0.01)) o.seconds = 0.01;
  obs_err err = OBS_ERR_INIT;
  if (srv_meshimport_new(&o, &importer, &err)) die(obs_err_message(&err));
  return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const char *const exts[] = {"ply", "obj", "off", "stl"};
  const char *ext = exts[size ? data[0] % 4 : 0];
  char path[PATH_MAX + 32];
  snprintf(path, sizeof path, "%s/input.%s", root, ext);
  FILE *f = fopen(path, "wb");
  if (!f) die("cannot write the input file");
  if (size > 1 && fwrite(data + 1, 1, size - 1, f) != size - 1) die("short write");
  fclose(f);
  obs_mesh m;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_meshimport_import(importer, path, root, &m, &err, "fuzz.json: /objects/0/shape/file");
  if (rc == 0) {
    if (!m.pos || !m.idx || !m.ntris || !m.nverts) die("a mesh without triangles or vertices");
    for (size_t i = 0; i < m.ntris * 3; i++)
      if (m.idx[i] >= m.nverts) die("index out of range");
    for (size_t i = 0; i < m.nverts * 3; i++)
      if (!isfinite(m.pos[i]) || (m.nrm && !isfinite(m.nrm[i]))) die("non-finite coordinate");
    obs_geometry_mesh_free(&m);
  } else {
    const char *msg = obs_err_message(&err);
    if (!strstr(msg, "fuzz.json: /objects/0/shape/file: ")) die("an error without its pointer");
    if (m.pos || m.idx || m.nrm) die("an error that left a mesh behind");
  }
  obs_err_free(&err);
  unlink(path);
  return 0;
}
